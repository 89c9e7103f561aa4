"""Sessions: the event-driven contact detector, force models run on unbounded streams, session scores."""

import dataclasses
import pathlib
import re
import subprocess
import sys

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from neurotac_cli import metrics
from neurotac_cli import model as models
from neurotac_cli import schema as sch
from neurotac_cli import tables
from neurotac_cli.errors import ModelError
from neurotac_cli.model import data as shaping
from neurotac_cli.model import evaluate, session
from neurotac_cli.ops import contact

ROOT = pathlib.Path(__file__).resolve().parents[2]
SIZE = 9
WINDOW_US = 10_000


def tiny_session(grasps=4, seed=0, trial="s0", rest=(40, 80), background=0.05, bright=()):
    """A session of grasp-like contacts between rests: OFF events while the force rises, ON while it
    falls, a little activity while held, background everywhere; the grasps numbered in `bright` the
    other way round (a bright object: ON as it presses, OFF as it lets go). Returns (frames table,
    true onsets)."""
    rng = np.random.default_rng(seed)
    force, phase, grasp, onsets, swapped = [], [], [], [], []
    for g in range(grasps):
        gap = int(rng.integers(*rest))
        force += [0.0] * gap
        phase += ["none"] * gap
        grasp += [-1] * gap
        peak = rng.uniform(1, 3)
        hold = int(rng.integers(5, 30))
        onsets.append(len(force))
        shape = np.concatenate([np.linspace(peak / 4, peak, 4), np.full(hold, peak), np.linspace(peak * 0.6, 0, 3)])
        swapped += list(range(len(force), len(force) + len(shape))) if g in bright else []
        force += shape.tolist()
        phase += ["grasping"] * 4 + ["holding"] * hold + ["releasing"] * 2 + ["none"]
        grasp += [g] * (len(shape) - 1) + [-1]
    force += [0.0] * int(rng.integers(*rest))
    phase += ["none"] * (len(force) - len(phase))
    grasp += [-1] * (len(force) - len(grasp))
    force = np.asarray(force)
    change = np.diff(force, prepend=0.0)
    # a press and a release make their events where the object is (the middle 5x5 cells), as many in
    # all as 3 per cell and newton over the frame; the background is everywhere
    patch = np.zeros((SIZE, SIZE))
    patch[2:7, 2:7] = SIZE * SIZE / 25
    off = rng.poisson(background + 3 * np.clip(change, 0, None)[:, None, None] * patch, (len(force), SIZE, SIZE))
    on = rng.poisson(background + 3 * np.clip(-change, 0, None)[:, None, None] * patch, (len(force), SIZE, SIZE))
    counts = np.stack([off, on], axis=1)
    counts[swapped] = counts[swapped, ::-1]
    return frames_table(trial, counts, force, phase, np.asarray(grasp)), onsets


def frames_table(trial, counts, force, phase, grasp):
    n = len(counts)
    schema = sch.frames_schema(SIZE, SIZE, window_us=WINDOW_US, extra=[("grasp", pa.int32())])
    columns = [pa.array([trial] * n), pa.array(np.arange(n, dtype=np.int32)), pa.array(np.arange(n, dtype=np.int64) * WINDOW_US),
               sch.counts_array(counts.astype(np.uint16)), pa.array(force, pa.float32()), pa.array(phase, pa.string()),
               pa.array(grasp, pa.int32(), mask=grasp < 0)]
    return pa.Table.from_arrays(columns, schema=schema)


@pytest.fixture(scope="module")
def sessions():
    return pa.concat_tables([tiny_session(6, seed=s, trial=f"s{s}")[0] for s in range(3)])


@pytest.fixture(scope="module")
def trained(sessions):
    return session.train(sessions, models.make_spec("deform-gru", epochs=3, hidden=8), seed=0)


# ---------------------------------------------------------------- the detector


def test_detector_finds_every_contact_within_two_frames_and_ends_it_at_the_release():
    table, onsets = tiny_session(grasps=8, seed=3)
    off, on = contact.frame_sums(sch.counts_numpy(table.column("counts")))
    phases, found, _, _ = contact.detect(contact.ContactConfig(), off, on)
    assert np.flatnonzero(found).tolist() == onsets
    truth = np.asarray(table.column("phase").to_pylist()) != "none"
    true_runs, found_runs = metrics.runs(truth), metrics.runs(phases != contact.NONE)
    assert len(found_runs) == len(true_runs)
    for (a, b), (c, d) in zip(true_runs, found_runs):
        assert abs(c - a) <= 2 and abs(d - b) <= 2
    assert {"grasping", "holding"} <= set(phases[truth])


def test_a_gap_in_the_camera_s_events_teaches_the_detector_no_background():
    """Two hours without an event (a recording paused, a dropped transfer) at 10 ms frames decayed the
    background to zero, from which it climbed back by 3σ a frame: the stream's next contact ended early
    and split, its background ON events read as release bursts."""
    table, onsets = tiny_session(grasps=4, seed=3, background=0.2)  # 16 events of each polarity a frame at rest
    off, on = contact.frame_sums(sch.counts_numpy(table.column("counts")))
    start = onsets[0] - 40  # rest: the warm-up done, the background learnt
    gap = np.zeros(720_000)
    phases, _, _, _ = contact.detect(contact.ContactConfig(), off, on)
    gapped, _, _, _ = contact.detect(contact.ContactConfig(), np.r_[off[:start], gap, off[start:]], np.r_[on[:start], gap, on[start:]])
    assert (gapped[start + len(gap):] == phases[start:]).all() and (gapped[start:start + len(gap)] == contact.NONE).all()


def test_detector_phases_through_a_grasp():
    """Rest; an OFF burst (grasping) that settles (holding), a hold's ripple, an ON-dominated run that
    grows to a full release (releasing, then rest), and the membrane's ON tail after it (still rest)."""
    off = [3] * 50 + [1000, 2000, 300, 20, 60, 10, 10, 10, 12, 3, 2, 3, 3]
    on = [8] * 50 + [10, 10, 30, 25, 70, 10, 10, 60, 50, 3000, 300, 60, 10]
    phases, onsets, _, _ = contact.detect(contact.ContactConfig(), np.array(off), np.array(on))
    assert phases[:50].tolist() == ["none"] * 50 and np.flatnonzero(onsets).tolist() == [50]
    assert phases[50:].tolist() == ["grasping", "grasping", "holding", "holding", "holding", "holding", "holding",
                                    "releasing", "releasing", "none", "none", "none", "none"]


def test_given_the_force_a_contact_ends_when_it_stays_low_after_a_release_not_at_the_release_share():
    """`detect(force=...)` ends contacts as the streaming model does: after the release burst, once
    the force has stayed under release_force_n for low_frames frames; a force that stays up keeps the
    contact (a partial release), though its ON events alone would have ended it."""
    config = contact.ContactConfig()
    off = np.array([3.0] * 50 + [1000, 2000, 300] + [3.0] * 20 + [3.0] * 60)
    on = np.array([8.0] * 50 + [10, 10, 30] + [8.0] * 20 + [300.0] + [8.0] * 59)  # a release dimmer than a full one
    released = 73
    alone, _, _, _ = contact.detect(config, off, on)
    assert metrics.runs(alone != contact.NONE) == [(50, released)]  # the ON events of the release end it at once
    falling = np.where(np.arange(len(off)) < released, 2.0, 0.0)
    phases, _, _, _ = contact.detect(config, off, on, force=falling)
    assert metrics.runs(phases != contact.NONE) == [(50, released + config.low_frames - 1)]
    held, _, _, _ = contact.detect(config, off, on, force=np.full(len(off), 2.0))
    assert metrics.runs(held != contact.NONE) == [(50, len(off))]


def test_detector_learns_a_background_far_from_its_start_and_passes_over_a_blink():
    """A camera with ten times the starting background, and an LED blink in its first frames: no
    contact until the grasp, which is found and ends at its release (a background learnt only at
    rest would start a contact at the blink and read every later frame as a burst)."""
    rng = np.random.default_rng(0)
    off, on = rng.poisson(50, 120).astype(float), rng.poisson(150, 120).astype(float)
    on[2], off[4] = 5000, 5000  # the LED on, then off
    off[40:42] += [2000, 3000]
    on[80:82] += [2500, 1500]
    phases, onsets, _, _ = contact.detect(contact.ContactConfig(), off, on)
    assert np.flatnonzero(onsets).tolist() == [40]
    assert metrics.runs(phases != contact.NONE) == [(40, 80)]
    phases, onsets, _, _ = contact.detect(contact.ContactConfig(warmup_frames=0), off, on)  # the starting background kept
    assert onsets[4] and onsets.sum() >= 3  # the blink's OFF events start a contact, and a background too low others


def test_a_release_that_darkens_the_rim_starts_no_contact():
    """A release's ON burst can carry OFF events above the background (the rim darkens as the face lets
    go); the contact ends at the release and those OFF events start no new one."""
    rng = np.random.default_rng(1)
    off, on = rng.poisson(50, 120).astype(float), rng.poisson(150, 120).astype(float)
    off[40:42] += [2000, 3000]
    on[80:82] += [2500, 1500]
    off[81] += 150  # well above the background, far below the ON burst beside it
    phases, onsets, _, _ = contact.detect(contact.ContactConfig(), off, on)
    assert np.flatnonzero(onsets).tolist() == [40]
    assert metrics.runs(phases != contact.NONE) == [(40, 80)]


def test_a_faint_press_over_a_busy_background_settles_into_a_hold():
    """Hot pixels can fire more OFF events per frame than a quarter of a faint press's peak: the
    hold is told by the OFF count above the background, so the press still settles."""
    rng = np.random.default_rng(2)
    off, on = rng.poisson(180, 200).astype(float), rng.poisson(210, 200).astype(float)
    off[40:43] += [150, 300, 250]
    phases, onsets, _, _ = contact.detect(contact.ContactConfig(), off, on)
    assert np.flatnonzero(onsets).tolist() == [40]
    assert (phases[50:] == contact.HOLDING).all()


def test_detector_in_pieces_equals_one_pass():
    table, _ = tiny_session(grasps=5, seed=4)
    off, on = contact.frame_sums(sch.counts_numpy(table.column("counts")))
    config = contact.ContactConfig()
    whole, _, _, _ = contact.detect(config, off, on)
    state, parts = None, []
    for start in range(0, len(off), 7):
        part, _, _, state = contact.detect(config, off[start:start + 7], on[start:start + 7], state)
        parts.append(part)
    assert np.concatenate(parts).tolist() == whole.tolist()


def held_contact(config, release_on):
    """A detector state through an onset, a settled hold and an ON-dominated burst of `release_on` events:
    a flicker while the object settles, or a release."""
    state = contact.ContactState.start(config)
    for off, on in [(3, 8)] * 50 + [(1000, 10), (2000, 10), (300, 30)] + [(3, 8)] * 10 + [(3, release_on)]:
        contact.step(config, state, off, on, by_force=True)
    assert state.released
    return state


@pytest.mark.parametrize("release_on, estimate, ends", [(200, 2.0, False), (200, 0.5, True), (3000, 2.0, True)])
def test_a_quiet_hold_stays_a_contact_unless_the_estimate_or_the_release_says_otherwise(release_on, estimate, ends):
    """After an ON flicker a steady hold makes no more events than rest: the estimate tells them apart,
    and a release as bright as the press was dark ends the contact even where the estimate stays up."""
    config = contact.ContactConfig()
    state = held_contact(config, release_on)
    state.peak_force = 2.2
    ended = False
    for _ in range(4 * config.quiet_frames):
        if contact.step(config, state, 3, 8, by_force=True) == contact.NONE:
            break
        ended = contact.end_by_force(config, state, estimate)
        if ended:
            break
    assert ended == ends


def test_a_slip_that_begins_as_a_press_of_a_settled_hold_is_flagged():
    """A fast slip darkens the membrane first (the detector sees a press), then both polarities burst."""
    config, slip = contact.ContactConfig(), contact.SlipConfig()
    off = [3] * 50 + [1000, 2000, 300] + [3] * 20 + [600, 700, 650, 700, 3, 3]
    on = [8] * 50 + [10, 10, 30] + [8] * 20 + [10, 300, 320, 310, 8, 8]
    phases, _, slips, _ = contact.detect(config, np.array(off), np.array(on), separation=np.full(len(off), 2.0), slip=slip)
    assert phases[73] == contact.GRASPING and not slips[73]
    assert slips[74:77].all()
    assert not slips[:73].any()


def test_no_slip_starts_in_a_release():
    """A release on some membranes makes both polarities at once (the patch lets go, its rim relaxes):
    in a frame the detector reads as releasing no slip starts; one under way goes on."""
    slip = contact.SlipConfig(min_events=50.0)

    def flag(phase, slipping=False):
        state = contact.ContactState(mean_off=5.0, mean_on=5.0, phase=phase, held=20, held_before=20, slipping=slipping)
        return contact.slip_step(slip, state, 5 + 80, 5 + 120, 2.0)

    assert flag(contact.HOLDING) and not flag(contact.RELEASING) and flag(contact.RELEASING, slipping=True)


def test_an_either_contact_whose_estimate_lags_its_press_is_not_ended_by_it():
    """press_polarity "either" ends a contact whose estimate stays low, burst or not, but only once it
    has risen: a slow model lags a press that is still rising."""
    off = [5.0] * 30 + [150.0, 120.0, 100.0] + [30.0] * 40 + [5.0] * 40
    on = [5.0] * 113
    config = contact.ContactConfig(release_force_n=0.3, press_polarity="either")
    lagging = np.asarray([0.0] * 60 + [2.0] * 20 + [0.0] * 33)  # up at last, then down with no release burst
    phases = contact.detect(config, np.asarray(off), np.asarray(on), force=lagging)[0]
    runs = metrics.runs(phases != contact.NONE)
    assert runs == [(30, 80 + config.low_frames - 1)]


def test_a_slip_goes_on_through_frames_that_pass_half_its_bar_and_no_weaker_one_starts():
    """Hysteresis: a slip whose events come unevenly is one slip, not several; the same weak frames
    in a quiet hold start none."""
    slip = contact.SlipConfig(min_events=50.0, hold_frames=1)

    def flags(off_on):
        state = contact.ContactState(mean_off=5.0, mean_on=5.0, phase=contact.HOLDING, held=20, held_before=20)
        return [contact.slip_step(slip, state, 5 + a, 5 + b, 2.0) for a, b in off_on]

    uneven = [(60, 60), (30, 30), (25, 40), (40, 10), (60, 60), (0, 0), (0, 0)]  # (40, 10) and (0, 0) pass as pairs
    assert flags(uneven) == [True, True, True, True, True, True, False]
    assert not any(flags(uneven[1:4]))
    assert flags([(60, 60), (10, 10), (10, 10)]) == [True, True, False]  # neither the frame nor the pair: it ends


def test_a_hold_that_keeps_trembling_is_no_slip_and_a_slip_rises_above_it():
    """Both polarities 60 events above the background in every frame of a hold (a trembling object):
    over the bars of 50, but steady, so once the hold's own level is learnt nothing is flagged; a
    slip that doubles it is."""
    slip = contact.SlipConfig(min_events=50.0, noise_sigma=0.0)
    state = contact.ContactState(mean_off=5.0, mean_on=5.0, phase=contact.HOLDING, held=20, held_before=20)
    trembling = [contact.slip_step(slip, state, 65.0, 65.0, 2.0) for _ in range(10 * slip.level_frames)]
    assert not any(trembling[-slip.level_frames:])
    assert contact.slip_step(slip, state, 5 + 120.0, 5 + 120.0, 2.0)


def test_a_press_peak_is_taken_above_the_streams_own_background():
    off = np.array([40.0] * 10 + [40, 300, 900, 500, 60] + [40] * 20 + [40, 200, 100] + [40] * 10)
    assert contact.press_peaks(off, [(10, 15), (35, 38)]) == [860.0, 160.0]


@pytest.mark.parametrize("press, bar", [(1500.0, 75.0), (400.0, 20.0), (60.0, contact.SLIP_FLOOR_EVENTS)])
def test_the_slip_bar_follows_the_rigs_presses_down_to_a_floor(press, bar):
    assert contact.slip_for(press).min_events == pytest.approx(bar)


@pytest.mark.parametrize("release, on_bar", [(None, None), (3000.0, 50.0), (500.0, 25.0), (50.0, contact.SLIP_FLOOR_EVENTS)])
def test_the_on_bar_follows_the_releases_brightness(release, on_bar):
    """A camera whose releases make a third of the presses' events flags a slip's trailing edge at a
    third of the OFF bar; one whose releases are brighter keeps the OFF bar for both."""
    slip = contact.slip_for(1000.0, release)
    assert slip.min_events == pytest.approx(50.0)
    assert slip.min_events_on == (None if on_bar is None else pytest.approx(on_bar))
    state = contact.ContactState(mean_off=5.0, mean_on=5.0, phase=contact.HOLDING, held=20, held_before=20)
    assert contact.slip_step(slip, state, 5 + 60, 5 + 30, 2.0) is (on_bar is not None and on_bar <= 30)


def test_a_release_peak_is_taken_about_the_contacts_end():
    on = np.array([40.0] * 10 + [40] * 10 + [400, 900, 100] + [40] * 20)
    assert contact.release_peaks(on, [(10, 21)]) == [860.0]


@pytest.mark.parametrize("press", [None, float("nan"), 0.0, -3.0])
def test_without_a_press_the_slip_bar_is_the_default(press):
    assert contact.slip_for(press) == contact.SlipConfig()


def test_a_bright_backgrounds_noise_is_not_a_slip_however_low_the_bar():
    """Both polarities 30 events above a background of 200 a frame (σ 14): noise there, a slip at a background of 5."""
    slip = contact.SlipConfig(min_events=10.0)
    for background, flagged in ((200.0, False), (5.0, True)):
        state = contact.ContactState(mean_off=background, mean_on=background, phase=contact.HOLDING, held=20, held_before=20)
        assert contact.slip_step(slip, state, background + 30, background + 30, 2.0) is flagged


def test_a_slip_drowned_in_the_frames_background_stands_out_of_the_contacts_footprint():
    """ON background 1 event per cell and frame over 20x20 cells (400 a frame, σ 20); a slip makes 40
    ON and 60 OFF events at the edge of a 4x4 press: under the frame's noise floor (4σ: 80), over the
    footprint's (6x6 cells, 36 a frame, 4σ: 24)."""
    rng = np.random.default_rng(0)
    frames = np.stack([rng.poisson(0.1, (80, 20, 20)), rng.poisson(1.0, (80, 20, 20))], axis=1).astype(np.float64)
    frames[20:23, 0, 8:12, 8:12] += 40.0  # the press
    frames[60:64, 0, 8:12, 11] += 15.0  # the slip's leading edge darkens ...
    frames[60:64, 1, 8:12, 8] += 10.0  # ... and its trailing edge brightens
    off, on, separation = contact.frame_stats(frames)
    config, slip = contact.ContactConfig(), contact.SlipConfig(min_events=20.0, min_events_on=20.0)
    phases, _, totals, _ = contact.detect(config, off, on, separation=separation, slip=slip)
    _, _, local, state = contact.detect(config, off, on, separation=separation, slip=slip, counts=frames)
    assert (phases[25:70] != contact.NONE).all()
    assert not totals.any()
    assert local[60:64].all() and not local[:60].any() and not local[70:].any()
    assert state.footprint.cells.sum() == 36


def inverted(table: pa.Table) -> pa.Table:
    """The same frames with their channels swapped: a sensor whose presses brighten the membrane."""
    counts = sch.counts_numpy(table.column("counts"))[:, ::-1]
    index = table.schema.get_field_index("counts")
    return table.set_column(index, table.schema.field(index), sch.counts_array(np.ascontiguousarray(counts)))


def test_the_detector_reads_a_sensor_whose_presses_brighten_with_its_polarities_swapped(sessions):
    frames = sch.counts_numpy(sessions.column("counts"))
    off, on = contact.frame_sums(frames)
    config = contact.ContactConfig(release_force_n=0.3)
    force = sessions.column("force").to_numpy()
    darkening = contact.detect(config, off, on, force=force, counts=frames)[0]
    swapped = contact.detect(dataclasses.replace(config, press_polarity="on"), on, off, force=force, counts=frames[:, ::-1])[0]
    unswapped = contact.detect(config, on, off, force=force, counts=frames[:, ::-1])[0]
    assert (darkening != contact.NONE).sum() > 100
    assert (swapped == darkening).all() and (unswapped != darkening).any()


def test_a_flash_over_the_whole_view_begins_no_contact():
    """An LED blink after the warm-up lights every cell (a press lights the object's); read as a
    press, it began a contact that ran on to the first grasp's release."""
    table, onsets = tiny_session(3, seed=4)
    frames = sch.counts_numpy(table.column("counts")).copy()
    frames[20, 0] += 3  # OFF events in every cell: the LED switched off
    off, on = contact.frame_sums(frames)
    config = contact.ContactConfig()
    with_frames = metrics.runs(contact.detect(config, off, on, counts=frames)[0] != contact.NONE)
    sums_only = metrics.runs(contact.detect(config, off, on)[0] != contact.NONE)
    assert [begin for begin, _ in with_frames] == onsets
    assert sums_only[0][0] == 20  # the frame sums alone cannot tell a flash from a press
    table, onsets = tiny_session(4, seed=2)
    frames = sch.counts_numpy(table.column("counts"))
    off, on = contact.frame_sums(frames)
    nine = frames.reshape(len(frames), 2, 3, 3, 3, 3).sum(axis=(3, 5))  # pooled 3x3 cells of 3x3
    for pooled in (frames.sum(axis=(2, 3), keepdims=True), nine):  # `crop --pool all`, a few cells
        found = contact.detect(config, off, on, counts=pooled)[1]
        assert list(np.flatnonzero(found)) == onsets  # a press covers them all: no flash rule there


def test_a_sensor_that_sees_dark_and_bright_objects_reads_each_contact_by_its_own_press():
    """Dark objects press OFF and let go ON, bright ones the reverse: with press_polarity "either" each
    contact is read by the polarity of its own onset, and the burst of a release that ended a contact
    begins no contact of its polarity; one polarity for every contact misses or merges the others."""
    table, onsets = tiny_session(grasps=8, seed=5, bright=(1, 2, 5))
    frames = sch.counts_numpy(table.column("counts"))
    off, on = contact.frame_sums(frames)
    force = table.column("force").to_numpy()
    truth = metrics.runs(force > 0)
    config = contact.ContactConfig(release_force_n=0.3)
    assert contact.press_polarity([(off, on, truth)]) == "either"
    both = on + 0.8 * off, off + 0.8 * on  # presses that make both polarities in like numbers: one kind of contact
    assert contact.press_polarity([(*both, truth)]) == "on" and contact.press_polarity([(*both[::-1], truth)]) == "off"
    assert contact.contact_polarities(contact.press_shares([(off, on, truth)])) == [["on" if g in (1, 2, 5) else "off" for g in range(8)]]
    either = dataclasses.replace(config, press_polarity="either")
    for given in (force, None):  # ended by the force, and by the release burst alone (which then goes on for two frames)
        phases, found, _, state = contact.detect(either, off, on, force=given, counts=frames)
        assert list(np.flatnonzero(found)) == onsets
        runs = metrics.runs(phases != contact.NONE)
        assert [begin for begin, _ in runs] == onsets and all(end - begin >= 5 for begin, end in runs)
        assert state.phase == contact.NONE and state.polarity == "off"  # read as OFF-presses again between contacts
    darkening = contact.detect(config, off, on, force=force, counts=frames)[1]
    assert not darkening[[onsets[g] for g in (1, 2, 5)]].any()  # read by one polarity, a bright press begins nothing
    flash = frames.copy()
    flash[onsets[0] - 10, 1] += 2  # a lamp brightening every cell: refused as a press, and no contact read the other way after it
    found = contact.detect(either, *contact.frame_sums(flash), force=force, counts=flash)[1]
    assert list(np.flatnonzero(found)) == onsets


def test_a_bright_press_that_begins_with_its_rims_off_events_is_read_as_pressing_on():
    """A bright face through a membrane whose rim darkens about it: the press's first frames are OFF,
    then ON overtakes them. Read as OFF to the end, its ON burst was a release and its OFF release a
    press again; turned over, the release is one."""
    off = [5.0] * 30 + [60.0, 80.0, 20.0, 20.0, 15.0] + [5.0] * 40 + [150.0, 150.0] + [5.0] * 40
    on = [5.0] * 30 + [10.0, 40.0, 300.0, 250.0, 100.0] + [5.0] * 40 + [10.0, 10.0] + [5.0] * 40
    force = [0.0] * 30 + [0.5, 1.0, 2.0, 3.0, 3.0] + [3.0] * 40 + [1.0, 0.0] + [0.0] * 40
    config = contact.ContactConfig(release_force_n=0.3, press_polarity="either")
    turned, first = (contact.detect(dataclasses.replace(config, press_frames=frames), np.asarray(off), np.asarray(on),
                                    force=np.asarray(force))[0] for frames in (10, 1))  # 1: read by its onset frame alone
    assert metrics.runs(turned != contact.NONE)[0][0] == 30 and 76 <= metrics.runs(turned != contact.NONE)[0][1] <= 100
    assert list(turned[32:35]) == [contact.GRASPING] * 3 and list(turned[75:77]) == [contact.RELEASING] * 2
    assert first[32] == contact.RELEASING and first[75] == contact.GRASPING


def test_an_either_contact_ended_at_a_partial_release_takes_its_final_release_as_its_tail():
    """The quiet rule ends a dark contact at a partial release (the object still held at 1.2 N); its
    final release, 40 frames later, is an ON burst as a bright object's press is: within
    `await_frames` of such an end it begins no contact. A bright press after the wait, and one 40
    frames after a whole release, begin theirs."""
    def stream(release):
        off = [5.0] * 30 + [150.0, 120.0, 100.0] + [5.0] * 267 + [5.0, 5.0, 5.0] + [5.0] * 57 + [100.0, 80.0] + [5.0] * 60
        on = [5.0] * 100 + release + [5.0] * 58 + [120.0, 80.0] + [5.0] * 138 + [150.0, 120.0, 100.0] + [5.0] * 119
        force = [0.0] * 30 + [3.0] * 70 + [1.2] * 60 + [0.0] * 140 + [3.0] * 60 + [0.0] * 62  # a bright press at 300
        return np.asarray(off), np.asarray(on), np.asarray(force)

    config = contact.ContactConfig(press_polarity="either")
    partial = stream([60.0, 40.0])  # 90 ON events above the background against the press's 355 OFF
    found = contact.detect(config, partial[0], partial[1], force=partial[2])[1]
    assert list(np.flatnonzero(found)) == [30, 300]
    unbounded = contact.detect(dataclasses.replace(config, await_frames=0), partial[0], partial[1], force=partial[2])[1]
    assert list(np.flatnonzero(unbounded)) == [30, 160]  # the final release read as a bright press, run on through the next
    whole = stream([200.0, 150.0])  # a whole release: the burst 40 frames after its end is the next object's press
    assert contact.detect(config, whole[0], whole[1], force=whole[2])[1][160]


def test_a_contact_turned_over_measures_its_press_for_the_slip_bars_in_its_own_polarity():
    off = [5.0] * 30 + [165.0, 20.0, 20.0, 10.0] + [5.0] * 40 + [100.0, 100.0] + [5.0] * 40
    on = [5.0] * 30 + [20.0, 100.0, 100.0, 60.0] + [5.0] * 40 + [10.0, 10.0] + [5.0] * 40
    force = [0.0] * 30 + [1.0, 2.0, 3.0, 3.0] + [3.0] * 40 + [1.0, 0.0] + [0.0] * 40
    config = contact.ContactConfig(release_force_n=0.3, press_polarity="either")
    _, _, _, state = contact.detect(config, np.asarray(off), np.asarray(on), force=np.asarray(force), separation=np.zeros(len(off)),
                                    slip=contact.SlipConfig())
    assert list(state.gain.presses) == [95.0]  # the rim's OFF frame (160 above the background) was no part of it


def test_training_on_a_sensor_of_dark_and_bright_objects_reads_each_contact_by_its_own_press():
    mixed = pa.concat_tables([tiny_session(6, seed=s, trial=f"s{s}", bright=(1, 4, s))[0] for s in range(3)])
    model = session.train(mixed, models.make_spec("deform-gru", epochs=1, hidden=4), seed=0)
    config = session.contact_config(model)
    assert config.press_polarity == "either" and model.training["contacts"]["presses_on"] == [8, 18]
    assert model.training["contacts"]["detection"]["f1"] >= 0.9
    frames = mixed.filter(pc.equal(mixed.column("trial"), "s2"))
    counts = sch.counts_numpy(frames.column("counts"))
    off, on = contact.frame_sums(counts)
    streamed = session.Stream(model).step(counts, frames.column("t").to_numpy())[1]
    estimates = session.predict_table(model, frames).column("force_pred").to_numpy()
    found = contact.detect(config, off, on, force=estimates, counts=counts)[0]
    assert (streamed == found).all() and len(metrics.runs(found != contact.NONE)) == 6


def mixed_release_stream(grasps=4, ratio=1.5):
    """OFF and ON per frame and the true force of grasps whose releases make `ratio` times as many ON
    as OFF events (a membrane that partly darkens as it lets go); presses make OFF, with a few ON."""
    off, on, force = [5.0] * 30, [5.0] * 30, [0.0] * 30
    for _ in range(grasps):
        off += [150.0, 120.0, 40.0] + [5.0] * 30 + [60.0, 60.0] + [5.0] * 40
        on += [15.0, 12.0, 5.0] + [5.0] * 30 + [60.0 * ratio, 60.0 * ratio] + [5.0] * 40
        force += [1.0, 2.0, 2.0] + [2.0] * 30 + [0.5, 0.0] + [0.0] * 40
    return np.asarray(off), np.asarray(on), np.asarray(force)


def test_a_sensor_whose_releases_also_darken_gets_a_release_bar_between_its_presses_and_releases():
    off, on, force = mixed_release_stream()
    touching = metrics.runs(force > 0)
    config = contact.ContactConfig(release_force_n=0.2)
    bar = contact.dominance_for(config, [(off, on, touching)])
    assert contact.DOMINANCE_FLOOR <= bar < 1.5
    found = {dominance: metrics.runs(contact.detect(dataclasses.replace(config, dominance=dominance), off, on, force=force)[0] != contact.NONE)
             for dominance in (config.dominance, bar)}
    assert len(found[bar]) == 4 and len(found[config.dominance]) < 4  # at the fixed bar, a release's OFF began a contact
    clear_off, clear_on, _ = mixed_release_stream(ratio=20.0)
    assert contact.dominance_for(config, [(clear_off, clear_on, touching)]) == config.dominance


def test_training_on_a_sensor_whose_releases_also_darken_keeps_its_release_bar_in_the_model():
    off, on, force = mixed_release_stream(grasps=6)
    counts = np.zeros((len(off), 2, SIZE, SIZE))
    counts[:, 0, 4, 4], counts[:, 1, 4, 4] = off, on
    phase = np.where(force > 0, "holding", "none")
    table = frames_table("s0", counts, force, phase, np.full(len(off), -1))
    model = session.train(table, models.make_spec("deform-gru", epochs=1, hidden=4), seed=0)
    bar = session.contact_config(model).dominance
    assert contact.DOMINANCE_FLOOR <= bar < contact.ContactConfig().dominance and model.training["contacts"]["dominance"] == bar


def test_training_measures_which_polarity_a_press_makes_and_checks_the_detector_on_its_sessions(sessions, trained):
    flipped = session.train(inverted(sessions), models.make_spec("deform-gru", epochs=1, hidden=4), seed=0)
    assert session.contact_config(trained).press_polarity == "off" and session.contact_config(flipped).press_polarity == "on"
    mine, theirs = trained.training["contacts"], flipped.training["contacts"]
    assert (theirs["press_off"], theirs["release_on"]) == (mine["press_off"], mine["release_on"])  # each on the polarity that presses
    assert theirs["detection"] == mine["detection"] and mine["detection"]["f1"] >= 0.9 and mine["detection"]["true"] == 18
    assert theirs["dominance"] == mine["dominance"] == session.contact_config(trained).dominance
    assert session.detection_note(mine) is None
    poor = {"detection": {"f1": 0.76, "true": 24.0, "found": 19.0, "hits": 16.0, "slip_f1": 0.2, "slip_true": 2.0,
                          "slip_found": 18.0, "slip_hits": 2.0}}
    note = session.detection_note(poor)
    assert "finds 16 of their 24 contacts, 19 in all (F1 0.76" in note and "flags 18 slips for their 2 (2 of them found" in note
    assert "(a press of OFF events, a release of ON); and it flags 18 slips" in note and "holds do not show slips" in note
    assert "(each contact's press of one polarity and its release of the other)" in session.detection_note({**poor, "press_polarity": "either"})
    slips_only = session.detection_note({"detection": {**poor["detection"], "f1": 1.0}})
    assert "presses and releases" not in slips_only and "holds do not show slips" in slips_only
    stream = session.Stream(flipped)  # the material model reads the frames' sums as framed, not as the detector does
    frames = inverted(sessions).filter(pc.equal(sessions.column("trial"), "s0"))
    counts = sch.counts_numpy(frames.column("counts"))
    stream.step(counts, frames.column("t").to_numpy())
    off, on = contact.frame_sums(counts)
    assert stream.sums and all(tuple(pair) in set(zip(off.tolist(), on.tolist())) for pair in stream.sums)
    with pytest.raises(ModelError, match="press_polarity='up' is not one of off, on"):
        flipped.input_spec[session.CONTACT_KEY]["press_polarity"] = "up"
        session.contact_config(flipped)


def test_training_without_phases_warns_where_the_contacts_it_found_release_more_than_they_press():
    """Frames without phases: the presses are taken to make OFF events. On a sensor whose presses
    brighten, the contacts then run from each release to the next press, and their "releases" (the
    presses, sharper than the releases) dwarf their "presses": said, where the same sensor's frames
    read the right way round say nothing."""
    pressing, releasing = [5.0] * 30, [5.0] * 30  # each grasp: the press's polarity, the release's
    for _ in range(6):
        pressing += [400.0, 300.0, 100.0] + [5.0] * 30 + [5.0, 5.0] + [5.0] * 40
        releasing += [15.0, 12.0, 5.0] + [5.0] * 30 + [40.0, 40.0] + [5.0] * 40
    notes = {}
    for name, (off, on) in (("dark", (pressing, releasing)), ("bright", (releasing, pressing))):
        counts = np.zeros((len(off), 2, SIZE, SIZE))
        counts[:, 0, 4, 4], counts[:, 1, 4, 4] = off, on
        table = frames_table("s0", counts, np.zeros(len(off)), np.full(len(off), "none"), np.full(len(off), -1))
        _, summary, _ = session.contacts_table(table, contact.ContactConfig(release_force_n=0.3))
        assert summary["from"] == "detector" and summary["press_polarity"] == "off"
        notes[name] = session.polarity_note(summary)
    assert notes["dark"] is None
    assert "the frames have no phases, so the presses were taken to make OFF events, not measured" in notes["bright"]


def test_scoring_names_frames_without_slip_truth(sessions, trained):
    slip = [False] * sessions.num_rows
    with_nulls = sessions.append_column("slip", pa.array([None if i % 50 == 0 else flag for i, flag in enumerate(slip)], pa.bool_()))
    notes = session.scoring_input_notes(trained.input_spec, trained.training, "force", with_nulls)
    said = [note for note in notes if "have no slip truth" in note]
    assert len(said) == 1 and f"{(sessions.num_rows + 49) // 50} frames of {sessions.num_rows:,} have no slip truth" in said[0]
    whole = sessions.append_column("slip", pa.array(slip, pa.bool_()))
    assert not [note for note in session.scoring_input_notes(trained.input_spec, trained.training, "force", whole) if "slip" in note]


def test_a_validation_session_that_holds_every_contact_is_refused_in_contacts():
    table, _ = tiny_session(6, seed=0, trial="s0")
    with pytest.raises(ModelError, match=r"every contact would be in validation, leaving none to train on \(--val-trials names a "
                                         r"session for all of its contacts\)"):
        session.train(table, models.make_spec("deform-gru", epochs=1, hidden=4), val_trials=["s0"], seed=0)


def test_training_says_where_contacts_close_together_train_as_one():
    off, on, force = [5.0] * 30, [5.0] * 30, [0.0] * 30
    for rest in (10, 60, 60):  # the first two grasps 10 frames apart: inside the first one's margin after its release
        off += [150.0, 120.0, 40.0] + [5.0] * 30 + [5.0, 5.0] + [5.0] * rest
        on += [15.0, 12.0, 5.0] + [5.0] * 30 + [90.0, 90.0] + [5.0] * rest
        force += [1.0, 2.0, 2.0] + [2.0] * 30 + [0.5, 0.0] + [0.0] * rest
    counts = np.zeros((len(off), 2, SIZE, SIZE))
    counts[:, 0, 4, 4], counts[:, 1, 4, 4] = off, on
    table = frames_table("s0", counts, np.asarray(force), np.where(np.asarray(force) > 0, "holding", "none"), np.full(len(off), -1))
    said = []
    model = session.train(table, models.make_spec("deform-gru", epochs=1, hidden=4), val_fraction=0, seed=0, progress=said.append)
    summary = model.training["contacts"]
    assert (summary["found"], summary["contacts"]) == (3, 2)
    assert any(line.startswith("contacts: 2 (of 3 found: a contact ending within 32 frames of the next trains with it) in 1 stream")
               for line in said), said


def moving_view_stream(move_at=40, press_at=80, hold_move_at=100, release_at=125, length=170, seed=0):
    """9x9 frames of a quiet camera: the view moving (both polarities in 40 cells, 8 frames, then 2 of
    OFF alone) at rest, then a press (OFF in a 3x3 patch), the view moving again while held, and the
    release (ON)."""
    rng = np.random.default_rng(seed)
    counts = rng.poisson(0.05, (length, 2, SIZE, SIZE)).astype(np.float64)
    cells = rng.choice(SIZE * SIZE, 40, replace=False)
    for start in (move_at, hold_move_at):
        for k in range(start, start + 8):
            for polarity in (0, 1):
                counts[k, polarity, cells // SIZE, cells % SIZE] += rng.poisson(3.0, 40)
    counts[move_at + 8:move_at + 10, 0, cells // SIZE, cells % SIZE] += 3  # the move's tail: OFF alone, 2 frames
    counts[press_at:press_at + 3, 0, 3:6, 3:6] += 12
    counts[release_at:release_at + 2, 1, 3:6, 3:6] += 12
    return counts


def test_the_view_moving_at_rest_begins_no_contact_and_a_contact_under_way_goes_on():
    """A camera on a robot arm, or a gripper's motor: edges sliding by make both polarities in the
    same cells over much of the view. An independent generator's arm moves began contacts that ran on
    into the next grasp; none begins in such a frame or the 3 after it (a move's tail of one polarity
    is no press). A press makes one polarity in
    a cell at a time, and a contact under way is not judged (an arm may carry what the gripper holds)."""
    counts = moving_view_stream()
    off, on = contact.frame_sums(counts)
    force = np.zeros(len(off))
    force[80:126] = 1.0
    config = contact.ContactConfig(release_force_n=0.3)
    framed = metrics.runs(contact.detect(config, off, on, force=force, counts=counts)[0] != contact.NONE)
    assert len(framed) == 1 and framed[0][0] == 80 and framed[0][1] >= 125
    sums_only = metrics.runs(contact.detect(config, off, on, force=force)[0] != contact.NONE)
    assert sums_only[0][0] == 40  # without the frames the move is a burst like any other


def test_an_led_that_lights_part_of_the_view_and_goes_dark_frames_later_begins_no_contact():
    """A session's LED lit a third of the view 0.5 s into the recording (after the warm-up) for 20
    ms: its switch-on is ON events alone in its frame, its switch-off two frames later OFF alone,
    over too few cells for a flash, and the switch-off began a contact that ran on into the first
    grasp. Cells that fire one polarity and, within `scene_frames`, the other are the view changing."""
    rng = np.random.default_rng(1)
    counts = rng.poisson(0.3, (400, 2, 30, 30)).astype(np.float64)
    counts[50, 1, :10] += 4  # the LED on, over the top third of the cells
    counts[52, 0, :10] += 4  # ... and off
    force = np.zeros(len(counts))
    counts[150:153, 0, 14:18, 14:18] += 30  # a dark press
    counts[300:302, 1, 14:18, 14:18] += 30  # its release
    force[150:302] = 1.0
    off, on = contact.frame_sums(counts)
    config = contact.ContactConfig(release_force_n=0.3)
    found = contact.detect(config, off, on, force=force, counts=counts)[0]
    assert [run[0] for run in metrics.runs(found != contact.NONE)] == [150]
    counts[52, 0, :10] -= 4
    counts[52, 0, 10:20] += 4  # OFF in other cells than the ON before it: a burst of its own, read as a press
    found = contact.detect(config, *contact.frame_sums(counts), force=force, counts=counts)[0]
    assert metrics.runs(found != contact.NONE)[0][0] == 52


@pytest.mark.parametrize("background", [0.05, 0.5, 1.0])
def test_a_busy_background_does_not_read_as_the_view_moving(background):
    """Cells of about one event a frame at rest (pooled, busy or long frames) pass a bar of one event
    above their rest in both polarities by chance over more than 2% of a frame: every press was taken
    for the view moving (none of 4 found at one event a cell). A cell fires past one event and 3
    Poisson σ above its rest."""
    rng = np.random.default_rng(0)
    counts = rng.poisson(background, (540, 2, 20, 20)).astype(np.float64)
    force = np.zeros(len(counts))
    for start in (60, 180, 300, 420):
        counts[start:start + 3, 0, 8:12, 8:12] += 30
        counts[start + 50:start + 52, 1, 8:12, 8:12] += 30
        force[start:start + 52] = 1.0
    off, on = contact.frame_sums(counts)
    found = contact.detect(contact.ContactConfig(release_force_n=0.3), off, on, force=force, counts=counts)[0]
    assert [run[0] for run in metrics.runs(found != contact.NONE)] == [60, 180, 300, 420]


def test_a_slip_column_without_a_value_is_no_slip_truth():
    table = pa.table({"slip": pa.array([None, None, None], pa.bool_())})
    assert session.slip_truth(table) is None
    assert session.slip_truth(pa.table({"slip": pa.array([None, True, False], pa.bool_())})).tolist() == [False, True, False]


def test_info_names_the_polarities_a_contacts_model_reads_presses_and_releases_in(sessions, trained, tmp_path):
    from neurotac_cli.describe import _model_lines, describe_model

    flipped = session.train(inverted(sessions), models.make_spec("deform-gru", epochs=1, hidden=4), seed=0)
    lines = {}
    for name, model in (("off", trained), ("on", flipped)):
        models.save(model, str(tmp_path / f"{name}.model"))
        lines[name] = dict(pair for pair in _model_lines(describe_model(str(tmp_path / f"{name}.model"))) if isinstance(pair, tuple))
    assert " OFF, release " in lines["off"]["contacts"] and lines["off"]["contacts"].endswith(" ON events")
    assert " contacts, " in lines["off"]["training"] and " trials" not in lines["off"]["training"]  # what it trained on
    assert " ON, release " in lines["on"]["contacts"] and lines["on"]["contacts"].endswith(" OFF events")
    assert lines["on"]["slip bars"].endswith(" OFF events") and " ON / " in lines["on"]["slip bars"]
    mixed = pa.concat_tables([tiny_session(6, seed=s, trial=f"s{s}", bright=(1, 4, s))[0] for s in range(3)])
    models.save(session.train(mixed, models.make_spec("deform-gru", epochs=1, hidden=4), seed=0), str(tmp_path / "either.model"))
    either = dict(pair for pair in _model_lines(describe_model(str(tmp_path / "either.model"))) if isinstance(pair, tuple))
    assert re.search(r"median press [\d.]+, release [\d.]+ events \(each contact read in the polarity its press makes", either["contacts"])
    assert re.fullmatch(r"[\d.]+ / [\d.]+ events \(press / release polarity\)", either["slip bars"])


def test_training_on_contacts_sets_the_slip_bar_from_the_training_presses(sessions, trained):
    summary = trained.training["contacts"]
    assert summary["press_off"] > 0
    assert summary["release_on"] > 0
    assert session.slip_config(trained) == contact.slip_for(summary["press_off"], summary["release_on"])
    chosen = contact.SlipConfig(min_events=123.0)
    again = session.train(sessions, models.make_spec("deform-gru", epochs=1, hidden=4), slip=chosen, seed=0)
    assert session.slip_config(again) == chosen


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(0.0, 5000.0))
def test_detector_state_stays_bounded_on_long_random_streams(seed, scale):
    """Whatever the stream (bursts, silence, a contact that never ends), the state is a few bounded numbers."""
    rng = np.random.default_rng(seed)
    n = 20_000
    off = rng.poisson(scale * rng.random(n) ** 4)
    on = rng.poisson(scale * rng.random(n) ** 4)
    config = contact.ContactConfig()
    _, _, _, state = contact.detect(config, off, on)
    frames = np.zeros((n, 2, 3, 3))
    frames[:, 0, 1, 1], frames[:, 1, 1, 1] = off, on
    _, _, _, with_cells = contact.detect(config, off, on, counts=frames, separation=np.full(n, 2.0), slip=contact.SlipConfig())
    gain = with_cells.gain
    assert len(gain.presses) <= contact.SlipConfig.follow_presses
    assert all(abs(value) <= largest_count(off, on) for value in (*gain.presses, gain.press_peak))
    if with_cells.footprint.pressed is not None:
        assert with_cells.footprint.pressed.max() <= off.max() * (config.memory_frames + 1)
    largest = float(max(off.max(), on.max(), config.background_off, config.background_on)) + 1
    assert 0 <= state.mean_off <= largest and 0 <= state.mean_on <= largest
    assert 0 <= state.off_since <= largest * (config.memory_frames + 1)
    assert state.phase in (contact.NONE, contact.GRASPING, contact.HOLDING, contact.RELEASING)


def largest_count(off, on) -> float:
    return float(max(off.max(), on.max(), contact.ContactConfig.background_off, contact.ContactConfig.background_on)) + 1


@pytest.mark.parametrize("follow, flagged", [(15, True), (0, False)])
def test_the_slip_bars_follow_the_streams_own_presses(follow, flagged):
    """A model trained on a sensor whose presses make about 1400 events (bars 71 / 62) runs on a camera
    whose presses make 200: its slips make a few tens of events, under the training bars but well
    over the stream's own (a twentieth of its presses, floored at 10)."""
    slip = contact.SlipConfig(min_events=71.3, min_events_on=61.6, follow_presses=follow)
    rest, press, hold = [(5, 5)] * 40, [(120, 5), (205, 5), (60, 5)], [(5, 5)] * 40
    off_on = rest + press + hold + [(35, 35)] * 3 + hold
    off, on = (np.array(v, dtype=float) for v in zip(*off_on))
    _, _, slips, state = contact.detect(contact.ContactConfig(), off, on, separation=np.full(len(off), 2.0), slip=slip)
    start = len(rest) + len(press) + len(hold)
    assert bool(slips[start:start + 3].all()) is flagged and not slips[:start].any()
    assert list(state.gain.presses) == ([200.0] if follow else [])


# ---------------------------------------------------------------- models on streams


def test_a_model_trained_on_contacts_carries_the_detector_and_round_trips(trained, sessions, tmp_path):
    assert session.is_session_model(trained)
    assert trained.training["contacts"]["contacts"] == 18
    assert trained.config.memory_frames == session.DEFAULT_MEMORY_FRAMES
    models.save(trained, str(tmp_path / "m.model"))
    again = models.load(str(tmp_path / "m.model"))
    assert session.is_session_model(again)
    a = models.predict_table(trained, sessions).column("force_pred").to_numpy()
    b = models.predict_table(again, sessions).column("force_pred").to_numpy()
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_a_model_with_detector_settings_from_a_newer_version_is_refused_in_one_line(trained):
    newer = trained
    spec = dict(newer.input_spec)
    newer.input_spec = dict(spec, contact=dict(spec["contact"], future_setting=1.0))
    try:
        with pytest.raises(ModelError, match="future_setting.*newer version"):
            session.predict_table(newer, tiny_session(1)[0])
    finally:
        newer.input_spec = spec


@pytest.mark.parametrize("key, setting, value, said", [
    ("contact", "quiet_frames", 0, "quiet_frames=0 is outside 1.."), ("contact", "memory_frames", 0, "memory_frames=0 is outside"),
    ("contact", "lead_frames", -1, "lead_frames=-1 is not a finite number"), ("contact", "onset_sigma", None, "onset_sigma=None"),
    ("contact", "low_frames", "20", "low_frames='20'"), ("slip", "level_frames", 2.5, "level_frames=2.5 is not a whole number"),
    ("slip", "min_events", float("nan"), "min_events=nan"), ("slip", "follow_presses", 1e12, "follow_presses=1000000000000.0 is outside 0.."),
    ("slip", None, [1, 2], "are not a mapping")])
def test_detector_settings_no_training_writes_are_refused_in_one_line(trained, key, setting, value, said):
    """A hand-edited or damaged model file: a count of 0 frames divided by zero deep in a stream, a
    string or None was a traceback, a negative lead a deque's error, others ran without a word."""
    spec = dict(trained.input_spec)
    trained.input_spec = dict(spec, **{key: value if setting is None else dict(spec[key], **{setting: value})})
    try:
        with pytest.raises(ModelError, match=re.escape(said)):
            session.predict_table(trained, tiny_session(1)[0])
    finally:
        trained.input_spec = spec


def test_whole_detector_settings_written_as_floats_read_as_counts(trained):
    spec = dict(trained.input_spec)
    trained.input_spec = dict(spec, contact=dict(spec["contact"], lead_frames=2.0))
    try:
        assert type(session.contact_config(trained).lead_frames) is int
    finally:
        trained.input_spec = spec


def test_a_session_streamed_in_pieces_gives_the_forces_eval_gives(trained):
    table, _ = tiny_session(grasps=5, seed=9, trial="test")
    whole = models.predict_table(trained, table)
    schema, batches = models.stream(trained, table.schema, iter(table.to_batches(max_chunksize=5)))
    streamed = pa.Table.from_batches(list(batches), schema=schema)
    np.testing.assert_allclose(streamed.column("force_pred").to_numpy(), whole.column("force_pred").to_numpy(), atol=1e-5)
    assert streamed.column("phase_pred").to_pylist() == whole.column("phase_pred").to_pylist()
    assert streamed.column("grasp").to_pylist() == table.column("grasp").to_pylist()


def test_the_slip_bars_each_stream_followed_are_told_once_it_ends(trained):
    table, _ = tiny_session(grasps=3, seed=9, trial="test")
    notes = []
    schema, batches = models.stream(trained, table.schema, iter(table.to_batches(max_chunksize=5)), notes=notes)
    for _ in batches:
        assert notes == []  # nothing before the stream has ended
    bars = session.slip_config(trained)
    assert len(notes) == 1 and notes[0].startswith("trial test: slips flagged at ")
    assert notes[0].endswith(f"the model's bars {bars.min_events:g} / {bars.on_events:g}")
    assert "from the median of its last 3 presses" in notes[0]
    one, _ = tiny_session(grasps=1, seed=9, trial="one")
    schema, batches = models.stream(trained, one.schema, iter(one.to_batches()), notes=notes)
    list(batches)
    assert "from its one press (" in notes[1]
    del notes[1:]
    empty, _ = tiny_session(grasps=0, seed=5, rest=(3000, 3001))
    schema, batches = models.stream(trained, empty.schema, iter(empty.to_batches()), notes=notes)
    list(batches)
    assert len(notes) == 1  # no press, nothing followed


def test_a_session_with_no_grasp_reads_zero_throughout(trained):
    table, _ = tiny_session(grasps=0, seed=5, rest=(3000, 3001))
    predictions = models.predict_table(trained, table)
    assert not any(predictions.column("contact_pred").to_pylist())
    assert np.abs(predictions.column("force_pred").to_numpy()).max() < 0.01


def test_force_reads_zero_between_contacts_and_runs_inside_them(trained):
    table, _ = tiny_session(grasps=6, seed=11, trial="test")
    predictions = models.predict_table(trained, table)
    phase = np.asarray(predictions.column("phase").to_pylist())
    pred = predictions.column("force_pred").to_numpy()
    true = predictions.column("force").to_numpy()
    rest = (phase == "none") & ~predictions.column("contact_pred").to_numpy(zero_copy_only=False)
    assert np.all(pred[rest] == 0)
    inside = predictions.column("contact_pred").to_numpy(zero_copy_only=False)
    assert pred[inside].max() > 0  # the model runs there (an undershoot below zero reads as none)
    assert np.all(pred >= 0)
    assert np.abs(pred - true)[rest].max() < 0.01


class Recorder:
    """A force model that reads zero and keeps the times and the state each call was given."""

    def __init__(self, model):
        self.input_spec, self.net, self.calls = model.input_spec, None, []

    def step(self, counts, t_us, state):
        self.calls.append((t_us[0].tolist(), state))
        return np.zeros((1, counts.shape[1]), np.float32), {"call": len(self.calls)}


@pytest.mark.parametrize("piece", [1, 1000])
def test_the_force_model_starts_on_the_frames_before_the_onset(trained, piece):
    """As its training contacts begin `lead_frames` before the true onset, the model is started on the
    frames before the detected one, whether they came in the same batch or in earlier ones."""
    table, _ = tiny_session(grasps=1, seed=3)
    data = shaping.sequences(table)
    counts, t_us = data.counts[0], data.t[0]
    recorder = Recorder(trained)
    stream = session.Stream(recorder)
    phases = np.concatenate([stream.step(counts[k : k + piece], t_us[k : k + piece])[1] for k in range(0, len(counts), piece)])
    onset = int(np.flatnonzero(phases != contact.NONE)[0])
    lead = session.contact_config(trained).lead_frames
    assert recorder.calls[0] == (t_us[onset - lead : onset].tolist(), None)
    assert recorder.calls[1][0][0] == t_us[onset] and recorder.calls[1][1] == {"call": 1}


@pytest.mark.parametrize("window_us, lead, level", [(10_000, 2, 50), (5_000, 4, 100), (20_000, 1, 25)])
def test_a_model_file_without_a_later_setting_keeps_its_duration_at_the_files_window(trained, window_us, lead, level):
    """A file written before the lead (or the hold's level) was a setting reads as many frames as its
    training kept: the default's duration at its own window."""
    older = models.Model(trained.name, trained.config, trained.net, dict(trained.input_spec, window_us=window_us), None, trained.training)
    older.input_spec["contact"] = {k: v for k, v in trained.input_spec["contact"].items() if k != "lead_frames"}
    older.input_spec["slip"] = {k: v for k, v in trained.input_spec["slip"].items() if k != "level_frames"}
    assert session.contact_config(older).lead_frames == lead
    assert session.slip_config(older).level_frames == level


def test_training_contacts_begin_as_many_frames_before_the_true_onset_as_the_model_reads(sessions):
    config = contact.ContactConfig()
    found, summary, _ = session.contacts_table(sessions, config)
    first = {}
    for trial, frame in zip(found.column("trial").to_pylist(), found.column("frame").to_pylist()):
        first.setdefault(trial, frame)
    for name, frame in first.items():
        stream = name.split("@")[0]
        phases = sessions.filter(pc.equal(sessions.column("trial"), stream)).column("phase").to_pylist()
        assert phases[frame + config.lead_frames] != "none" and phases[frame + config.lead_frames - 1] == "none"


@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_model_state_stays_bounded_on_long_random_streams(trained, seed):
    """A long stream of random activity (contacts that may never end): the force model's state is
    dropped at every rest, and inside a contact deform-gru's leaky sums stay under their bound."""
    rng = np.random.default_rng(seed)
    one = session.Stream(trained)
    largest = 0.0
    for _ in range(20):
        length = 200
        level = rng.choice([0.0, 0.05, 2.0, 6.0])
        counts = rng.poisson(level * rng.random((length, 1, 1, 1)) ** 2, (length, 2, SIZE, SIZE)).astype(np.uint16)
        force, phases, _, _ = one.step(counts, np.arange(length, dtype=np.int64) * WINDOW_US)
        assert np.all(np.isfinite(force))
        largest = max(largest, float(counts.max()))
        if phases[-1] == contact.NONE:
            assert one.inner is None
        else:
            memory = trained.config.memory_frames
            assert float(one.inner["deformation"].abs().max()) <= largest * (memory + 1)
            assert float(one.inner["h"].abs().max()) <= 1.0


# ---------------------------------------------------------------- scores


def test_session_scores_rest_drift_grasps_and_contacts():
    frame = np.arange(12)
    phase = ["none"] * 3 + ["grasping", "holding", "holding", "releasing"] + ["none"] * 5
    true = np.array([0, 0, 0, 1, 2, 2, 1, 0, 0, 0, 0, 0], dtype=float)
    pred = np.array([0.1, 0, 0, 0, 2, 2, 1, 0.3, 0.2, 0.1, 0.1, 0.1])
    contact_pred = np.array([0, 0, 0, 0, 1, 1, 1, 1, 0, 0, 0, 0], dtype=bool)
    grasp = np.where(np.isin(phase, ["none"]), np.nan, 0)
    rows = metrics.session_rows(["s"] * 12, frame, frame * 60e6, phase, true, pred, grasp=grasp, contact_pred=contact_pred)
    figures = {m: v for s, m, v in rows if s == "all"}
    rest = np.array([0.1, 0, 0, 0.3, 0.2, 0.1, 0.1, 0.1])
    assert figures["rest_mean_abs"] == pytest.approx(rest.mean())
    assert figures["rest_max_abs"] == pytest.approx(0.3)
    assert figures["drift_n_per_min"] == pytest.approx(np.polyfit([0, 1, 2, 7, 8, 9, 10, 11], rest, 1)[0])
    assert figures["contact_f1"] == 1.0 and figures["contact_onset_frames_mean"] == 1.0
    assert figures["contact_frame_f1"] == pytest.approx(2 * 3 / (4 + 4))
    assert {m: v for s, m, v in rows if s == "grasp:s/0"}["rmse"] == pytest.approx(np.sqrt(1 / 4))


def test_detection_f1_counts_misses_and_false_alarms():
    truth = [np.array([0, 1, 1, 0, 0, 1, 1, 0, 0, 0], bool)]
    found = [np.array([0, 0, 1, 0, 0, 0, 0, 0, 1, 0], bool)]
    figures = metrics.detection_figures(truth, found, "slip", unit=10.0, units="ms", timing="latency", tolerance=20)
    assert figures["slip_hits"] == 1 and figures["slip_true"] == 2 and figures["slip_found"] == 2
    assert figures["slip_f1"] == 0.5
    assert figures["slip_latency_ms_mean"] == 10.0 and figures["slip_within_20"] == 1.0
    assert figures["slip_end_ms_mean"] == 0.0  # the hit ends where its slip ends
    late = metrics.detection_figures(truth, [np.array([0, 1, 1, 1, 1, 0, 1, 0, 0, 0], bool)], "contact")
    assert late["contact_end_frames_mean"] == 1.0 and late["contact_end_frames_max"] == 2.0  # the first 2 frames past its end, the second on time


def test_slip_latency_is_read_from_the_frames_times_whatever_the_metadata_says():
    """The latency in ms comes from the frames' `t`: predictions that do not record their window
    (a warning, not a refusal) read every slip as flagged at once (0 ms, all within 20 ms)."""
    frame = np.arange(10)
    slip = np.array([0, 0, 1, 1, 1, 0, 0, 0, 1, 1], bool)
    slip_pred = np.array([0, 0, 0, 0, 1, 1, 0, 0, 0, 1], bool)
    rows = metrics.session_rows(["s"] * 10, frame, frame * 10_000, ["holding"] * 10, np.ones(10), np.ones(10),
                                contact_pred=np.ones(10, bool), slip=slip, slip_pred=slip_pred)
    figures = {m: v for s, m, v in rows if s == "all"}
    assert figures["slip_latency_ms_mean"] == pytest.approx(15.0) and figures["slip_latency_ms_max"] == pytest.approx(20.0)
    assert figures["slip_within_20"] == 1.0
    rows = metrics.session_rows(["s"] * 10, frame, frame * 20_000, ["holding"] * 10, np.ones(10), np.ones(10),
                                contact_pred=np.ones(10, bool), slip=slip, slip_pred=slip_pred)
    assert {m: v for s, m, v in rows if s == "all"}["slip_within_20"] == 0.5  # 40 ms and 20 ms late at 20 ms frames


def test_eval_of_a_stream_model_reports_session_figures(trained):
    table, _ = tiny_session(grasps=4, seed=12, trial="test")
    _, rows = evaluate.evaluate_model(trained, table)
    names = {m for s, m, v in rows if s == "all"}
    assert {"rest_mean_abs", "drift_n_per_min", "contact_f1", "grasp_rmse_mean", "contact_rmse"} <= names
    assert any(s.startswith("grasp:test/") for s, m, v in rows)


# ---------------------------------------------------------------- commands


def run(args, stdin=None):
    code = "from neurotac_cli.cli import main; main()"
    return subprocess.run([sys.executable, "-c", code, *args], stdin=stdin, capture_output=True)


def test_train_contacts_then_predict_writes_contact_and_phase(sessions, tmp_path):
    tables.write(str(tmp_path / "s.arrows"), sessions)
    with open(tmp_path / "s.arrows", "rb") as stdin:
        done = run(["train", "--model", "deform-gru", "--contacts", "--epochs", "2", "--hidden", "4", "-o", str(tmp_path / "m.model")], stdin)
    assert done.returncode == 0, done.stderr
    assert b"contacts: 18 in 3 streams" in done.stderr
    assert b"training contacts, " in done.stderr and b"training trial" not in done.stderr
    with open(tmp_path / "s.arrows", "rb") as stdin:
        done = run(["predict", "--model", str(tmp_path / "m.model"), "-o", str(tmp_path / "p.arrows")], stdin)
    assert done.returncode == 0, done.stderr
    out = tables.read([str(tmp_path / "p.arrows")])
    assert {"force_pred", "contact_pred", "phase_pred", "grasp"} <= set(out.schema.names)


def test_train_contacts_refuses_a_classifier(tmp_path):
    done = run(["train", "--model", "material-dnn", "--contacts", "-o", str(tmp_path / "m.model")])
    assert done.returncode == 2 and b"--contacts trains force models" in done.stderr


def test_the_sessions_example_runs_quick(tmp_path):
    """examples/sessions.py --quick end to end (simulate, frame, train on contacts, score) writes its table."""
    script = ROOT / "examples" / "sessions.py"
    done = subprocess.run([sys.executable, str(script), "--quick", "--models", "deform-gru", "--randomised-models", "deform-gru",
                           "--out", str(tmp_path)],
                          capture_output=True, check=False)
    assert done.returncode == 0, done.stderr.decode()[-2000:]
    table = (tmp_path / "sessions.md").read_text()
    assert table.count("| deform-gru |") == 2 and "contact F1" in table and "default-physics test sessions" in table and "deform-gru, randomised" in table


def pooled_material_model():
    """A material classifier trained on tiny labelled trials pooled to one pixel (`crop --pool all`)."""
    from neurotac_cli.ops.crop import CropSpec, crop_table
    from tests.model.helpers import tiny_frames

    pooled = crop_table(tiny_frames(trials=6, size=(SIZE, SIZE)), CropSpec(pool="all"))
    return models.train(pooled, models.make_spec("material-dnn", epochs=3), seed=0)


def test_predict_names_each_contacts_material_when_it_ends(trained):
    material = pooled_material_model()
    table, _ = tiny_session(grasps=4, seed=13, trial="test")
    predictions = session.predict_table(trained, table, material=material)
    touching = predictions.column("contact_pred").to_numpy(zero_copy_only=False)
    ends = [end for _, end in metrics.runs(touching) if end < len(touching)]
    named = predictions.column("material_pred").to_pylist()
    assert [k for k, v in enumerate(named) if v is not None] == ends
    assert {named[k] for k in ends} <= set(material.classes)


def test_a_stream_that_ends_inside_a_contact_names_its_material_in_a_note(trained):
    material = pooled_material_model()
    table, _ = tiny_session(grasps=2, seed=13, trial="test")
    touching = session.predict_table(trained, table).column("contact_pred").to_numpy(zero_copy_only=False)
    start, end = metrics.runs(touching)[-1]
    cut = table.slice(0, (start + end) // 2)  # the input ends in the middle of the last contact
    notes = []
    _, batches = models.stream(trained, cut.schema, iter(cut.to_batches()), material=material, notes=notes)
    named = pa.Table.from_batches(list(batches)).column("material_pred").to_pylist()
    assert sum(v is not None for v in named) == len(metrics.runs(touching)) - 1  # the open contact has no row to name it on
    ended = [line for line in notes if "ended inside a contact" in line]
    assert len(ended) == 1 and ended[0].startswith("trial test:") and ended[0].split("material ")[1].split(" ")[0] in material.classes


def test_a_material_model_that_adapts_by_batches_is_refused_for_contacts_named_alone(trained):
    material = pooled_material_model()
    material.input_spec["adapt"] = {"by": "object", "mean": [], "std": [], "stats": {}}
    with pytest.raises(ModelError, match="trained with --adapt-by object"):
        session.check_material(trained, material)


def test_a_material_model_on_unpooled_frames_is_refused(trained):
    from tests.model.helpers import tiny_frames

    unpooled = models.train(tiny_frames(trials=4, size=(SIZE, SIZE)), models.make_spec("material-dnn", epochs=1), seed=0)
    table, _ = tiny_session(grasps=1, seed=1)
    with pytest.raises(ModelError, match="pooled to one pixel"):
        session.predict_table(trained, table, material=unpooled)


def test_the_feature_distance_is_logged_for_the_frames_read_inside_contacts_only(trained):
    """`predict`'s watcher reads, row for row, the distance of each frame the network read (deform-gru's
    `distance_log`): finite inside contacts, NaN between them, where the network does not run."""
    table, _ = tiny_session(grasps=4, seed=5, trial="test")
    trained.net.distance_log = []
    try:
        schema, batches = models.stream(trained, table.schema, iter(table.to_batches(max_chunksize=50)))
        inside, logged = [], []
        for batch in batches:
            inside.append(batch.column("contact_pred").to_numpy(zero_copy_only=False))
            logged.append(trained.net.distance_log.pop())
            assert not trained.net.distance_log  # one row-for-row array per batch, nothing left over
    finally:
        trained.net.distance_log = None
    inside, logged = np.concatenate(inside), np.concatenate(logged)
    assert len(logged) == table.num_rows and inside.any() and not inside.all()
    read = np.isfinite(logged)
    assert read[inside].all()
    ended = ~inside & np.concatenate([[False], inside[:-1]])  # a contact's last frame: read, then the contact ends
    assert not read[~inside & ~ended].any()


def test_a_stream_whose_frames_do_not_follow_one_another_is_refused(trained):
    from neurotac_cli.errors import InputError

    table, _ = tiny_session(grasps=2, seed=14, trial="test")
    frames = np.arange(table.num_rows)
    for order, said in [(np.concatenate([frames[:30], frames[60:]]), "frame 60 follows frame 29"),
                        (frames[::-1], f"frame {table.num_rows - 2} follows frame {table.num_rows - 1}")]:
        with pytest.raises(InputError, match=said):
            session.predict_table(trained, table.take(pa.array(order)))
    t = table.column("t").to_numpy().copy()
    t[40:] -= 20_000  # frame numbers that go on while the clock steps back two windows
    stepped = table.set_column(table.schema.get_field_index("t"), "t", pa.array(t, table.schema.field("t").type))
    with pytest.raises(InputError, match=rf"frame 40 \(t {t[40]} µs\) follows frame 39 at t {t[39]} µs"):
        session.predict_table(trained, stepped)


def test_scores_say_when_rest_frames_carry_force_and_when_a_session_has_no_grasp(trained):
    table, _ = tiny_session(grasps=3, seed=15, trial="test")
    unlabelled = table.set_column(table.schema.get_field_index("phase"), "phase", pa.array(["none"] * table.num_rows))
    _, rows = evaluate.evaluate_model(trained, unlabelled)
    lines = "\n".join(session.summary_lines({m: v for s, m, v in rows if s == "all"}))
    assert "frames at rest by their phase carry a true force" in lines
    quiet = tiny_session(grasps=0, seed=16, trial="quiet")[0]
    _, rows = evaluate.evaluate_model(trained, quiet)
    lines = "\n".join(session.summary_lines({m: v for s, m, v in rows if s == "all"}))
    assert "carry a true force" not in lines and "no frame in contact" in lines and "contacts: none in the frames" in lines
    assert "nan" not in lines.split("drift")[1]
    force = table.column("force").to_numpy(zero_copy_only=False)
    offset = table.set_column(table.schema.get_field_index("force"), "force", pa.array(force + 2.0, pa.float32()))
    _, rows = evaluate.evaluate_model(trained, offset)  # a log that reads 2 N at rest, phased as a session
    assert "carry a true force" not in "\n".join(session.summary_lines({m: v for s, m, v in rows if s == "all"}))


@pytest.mark.parametrize("column, typ, works", [("grasp", pa.string(), False), ("slip", pa.int8(), True)])
def test_truth_columns_of_another_type_are_cast_or_refused_in_one_line(trained, tmp_path, column, typ, works):
    table, _ = tiny_session(grasps=2, seed=17, trial="test")
    if column == "slip":
        table = table.append_column("slip", pa.array(np.zeros(table.num_rows, bool)))
    index = table.schema.get_field_index(column)
    table = table.set_column(index, column, table.column(column).cast(typ))
    tables.write(str(tmp_path / "f.arrows"), table)
    session_model = tmp_path / "m.model"
    models.save(trained, str(session_model))
    done = run(["eval", "--model", str(session_model), str(tmp_path / "f.arrows"), "-o", str(tmp_path / "p.arrows")])
    if works:
        assert done.returncode == 0 and b"slips: none in the frames" in done.stderr, done.stderr
    else:
        lines = done.stderr.decode().strip().splitlines()
        assert done.returncode == 1 and len(lines) == 1 and "'grasp' has type string, expected an integer" in lines[0]


def test_the_detectors_settings_keep_their_durations_and_event_rates_at_another_window():
    base = contact.ContactConfig()
    assert contact.at_window(base, 10_000) == base and contact.at_window(base, None) == base
    fine = contact.at_window(base, 5_000)
    assert (fine.low_frames, fine.quiet_frames, fine.warmup_frames) == (2 * base.low_frames, 2 * base.quiet_frames, 2 * base.warmup_frames)
    assert fine.min_events == base.min_events / 2 and fine.onset_sigma == base.onset_sigma
    slow = contact.at_window(contact.SlipConfig(), 40_000)
    assert slow.hold_frames == 1 and slow.settle_frames == 1  # never below one frame


def test_training_on_frames_of_another_window_stores_settings_of_the_same_durations(sessions):
    coarse = sessions.replace_schema_metadata(sch.set_meta(sessions.schema, window_us=20_000).metadata)
    model = session.train(coarse, models.make_spec("deform-gru", epochs=1, hidden=4), seed=0)
    assert session.contact_config(model).low_frames == contact.ContactConfig.low_frames // 2
    assert model.config.memory_frames == session.DEFAULT_MEMORY_FRAMES // 2


@pytest.mark.parametrize("figures", [
    {"rest_frames": 1, "rest_mean_abs": 0.0, "rest_max_abs": 0.0, "contact_f1": float("nan"), "contact_true": 0, "contact_found": 0},
    {"rest_frames": 0, "contact_rmse": 1.9, "grasps": 0, "contact_f1": 0.0, "contact_true": 1, "contact_found": 0,
     "contact_hits": 0, "contact_frame_f1": 0.0, "slip_f1": 0.0, "slip_true": 1, "slip_found": 0, "slip_hits": 0},
])
def test_the_session_summary_leaves_out_figures_that_had_no_frames_rather_than_printing_nan(figures):
    """One frame (no drift), no frame at rest, no `grasp` column, no contact or slip found: each read `nan`."""
    lines = "\n".join(session.summary_lines(figures))
    assert "nan" not in lines, lines


def test_session_frames_met_by_a_model_of_whole_trials_and_one_contact_per_stream_are_named(sessions):
    assert "takes each session as one trial" in session.whole_trials_note(sessions.schema, "training without --contacts")
    assert session.whole_trials_note(sessions.drop(["grasp"]).schema, "training") is None
    assert "covering 95% of the frames" in session.one_contact_note({"contacts": 2, "sessions": 2, "frames_in_contacts": 950, "frames": 1000})
    assert session.one_contact_note({"contacts": 12, "sessions": 2, "frames_in_contacts": 600, "frames": 1000}) is None
    merged = session.one_contact_note({"contacts": 1, "found": 6, "merge_frames": 32, "sessions": 1, "frames_in_contacts": 950,
                                       "frames": 1000})
    assert "the 6 contacts found rest less than 32 frames apart, so they train as one" in merged and "--phases" not in merged
    # the detector scored against grasps the phases merged: its contacts are not judged (its slips are)
    poor = {"detection": {"f1": 0.29, "true": 1.0, "found": 6.0, "hits": 1.0, "slip_f1": 0.2, "slip_true": 2.0, "slip_found": 18.0,
                          "slip_hits": 2.0}}
    note = session.detection_note({**poor, "contacts": 1, "sessions": 1, "frames_in_contacts": 950, "frames": 1000})
    assert "presses and releases" not in note and "holds do not show slips" in note
    assert "finds 1 of their 1 contact" in session.detection_note({**poor, "contacts": 1, "sessions": 1, "frames_in_contacts": 500,
                                                                   "frames": 1000})


def test_a_session_given_for_validation_holds_out_every_contact_found_in_it(sessions):
    found, _, _ = session.contacts_table(sessions, contact.ContactConfig())
    chosen = session._contacts_of(found, ["s1"])
    assert chosen and all(name.split("@")[0] == "s1" for name in chosen)
    assert len(chosen) == len({t for t in found.column("trial").to_pylist() if t.startswith("s1@")})
    assert session._contacts_of(found, [chosen[0], "elsewhere"]) == [chosen[0], "elsewhere"]  # a contact, and one left to be refused


def test_training_on_contacts_refuses_frames_with_no_rest_between_grasps():
    """Trials of one grasp, each a contact from its first frame: the model would learn no zero, and
    the detector at run time no background, so it would never find a contact."""
    from tests.model.helpers import tiny_frames

    with pytest.raises(ModelError, match="every one of the 96 training frames lies inside a contact"):
        session.train(tiny_frames(), models.make_spec("deform-gru", epochs=1, hidden=4), seed=0)


def test_predict_names_session_frames_given_to_a_model_of_whole_trials(sessions, tmp_path):
    model = models.train(sessions.drop(["grasp"]), models.make_spec("tdnn", epochs=1), seed=0)
    models.save(model, str(tmp_path / "m.model"))
    tables.write(str(tmp_path / "s.arrows"), sessions)
    with open(tmp_path / "s.arrows", "rb") as stdin:
        done = run(["predict", "--model", str(tmp_path / "m.model"), "-o", str(tmp_path / "p.arrows")], stdin)
    assert done.returncode == 0 and b"a model trained without --contacts takes each session as one trial" in done.stderr


def test_the_summary_says_an_early_onset_is_early():
    figures = {"rest_frames": 0, "contact_f1": 0.8, "contact_true": 8, "contact_found": 12, "contact_hits": 8,
               "contact_end_frames_median": 37.0, "contact_frame_f1": 0.7, "contact_within_2": 0.5}
    early, late = ("\n".join(session.summary_lines({**figures, "contact_onset_frames_median": lag})) for lag in (-110.5, 1.5))
    assert "median onset 110.5 frames early, 50% within 2 frames, median end 37 frames late" in early
    assert "median onset 1.5 frames late" in late


def test_the_summary_gives_median_onsets_and_ends_that_one_merged_contact_does_not_move():
    """Three contacts found on time, a fourth run on into the next grasp: the mean end moves by the
    rest between them, the median (the summary's) reads the others."""
    truth = [np.array([0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 0], bool)]
    found = [np.array([0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0], bool)]
    figures = metrics.detection_figures(truth, found, "contact")
    assert figures["contact_end_frames_mean"] == pytest.approx(11 / 4) and figures["contact_end_frames_median"] == 0.0
    assert figures["contact_onset_frames_median"] == 0.0 and figures["contact_hits"] == 4
    lines = session.summary_lines({"rest_frames": 0, "contact_frame_f1": 0.9, **figures})
    assert "median onset 0 frames late, 100% within 2 frames, median end 0 frames late" in "\n".join(lines)


def test_the_summary_weighs_the_error_in_contact_against_the_best_constant():
    frame = np.arange(8)
    true = np.array([0, 1, 3, 1, 3, 0, 0, 0], float)
    phase = ["none", "holding", "holding", "holding", "holding", "none", "none", "none"]
    for pred, warned in ((true, False), (np.where(true > 0, 2.0, 0.0), True)):
        rows = metrics.session_rows(["s"] * 8, frame, frame * 10_000, phase, true, pred)
        figures = {m: v for s, m, v in rows if s == "all"}
        assert figures["contact_rmse_constant"] == pytest.approx(1.0)
        lines = "\n".join(session.summary_lines(figures))
        assert "(the best constant 1 N)" in lines and ("no better than a constant" in lines) == warned
