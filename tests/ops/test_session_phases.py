"""Grasps inside a session: `ops.phases.label_session` on force traces with re-grasps, force changes and partial releases."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from neurotac_cli import metrics
from neurotac_cli.errors import SchemaError
from neurotac_cli.ops.phases import (detect_phases, label_session, rest_drift, rest_levels, rest_line, session_columns, slow_noise,
                                     step_noise)


def ramp(a, b, frames):
    u = np.linspace(0, 1, frames + 1)[1:]
    return a + (b - a) * (3 * u**2 - 2 * u**3)


def runs(phase, grasp):
    """[(first frame, phase, grasp)] at every change of either."""
    out, previous = [], None
    for k, key in enumerate(zip(phase.tolist(), grasp.tolist())):
        if key != previous:
            out.append((k, *key))
            previous = key
    return out


def session_trace(seed=0, noise=0.01):
    rest = np.zeros(20)
    regrasp = np.concatenate([ramp(0, 3, 8), np.full(30, 3.0), ramp(3, 0.5, 4), np.full(5, 0.5), ramp(0.5, 3.2, 6),
                              np.full(20, 3.2), ramp(3.2, 0, 5)])
    # a force change while held (+15% over 20 frames: regulation speed), then a partial release to 1 N
    change_partial = np.concatenate([ramp(0, 2, 10), 2.0 * np.linspace(1, 1.15, 20), np.full(20, 2.3), ramp(2.3, 1.0, 4),
                                     np.full(25, 1.0), ramp(1.0, 0, 4)])
    force = np.concatenate([rest, regrasp, rest, change_partial, rest])
    return force + np.random.default_rng(seed).normal(0, noise, force.size)


def test_regrasp_partial_release_and_force_change_get_their_phases_per_grasp():
    phase, grasp = label_session(session_trace())
    assert grasp.dtype == np.int32
    assert runs(phase, grasp) == [
        (0, "none", -1),
        (21, "grasping", 0), (28, "holding", 0),  # frame 20 reads 0.04 N: not yet in contact
        (58, "releasing", 0), (62, "holding", 0), (67, "grasping", 0), (73, "holding", 0),  # the re-grasp
        (93, "releasing", 0), (98, "none", -1),  # the frame that first reads below contact is releasing
        (119, "grasping", 1), (128, "holding", 1),  # the +15% change over 20 frames stays holding
        (168, "releasing", 1), (172, "holding", 1),  # the partial release, then the lower level held
        (197, "releasing", 1), (201, "none", -1),
    ]


def test_labels_hold_across_noise_draws_and_a_trace_at_rest_is_none():
    for seed in range(5):
        phase, grasp = label_session(session_trace(seed))
        assert set(grasp.tolist()) == {-1, 0, 1}
        assert [k for k, name, g in runs(phase, grasp) if name == "grasping"] == [21, 67, 119]
    phase, grasp = label_session(np.random.default_rng(1).normal(0, 0.01, 500))
    assert set(phase.tolist()) == {"none"} and set(grasp.tolist()) == {-1}
    phase, grasp = label_session(np.full(10, np.nan))
    assert set(phase.tolist()) == {"none"}


def test_a_relaxing_hold_stays_holding_and_a_dip_of_two_frames_does_not_split_a_grasp():
    relax = 3.0 * (1 - 0.22 * -np.expm1(-np.arange(60) / 25.0))  # foam: 22% lost with a 250 ms time constant
    dip = np.concatenate([np.full(10, relax[-1]), [0.0, 0.0], np.full(10, relax[-1])])
    force = np.concatenate([np.zeros(10), ramp(0, 3, 8), relax, np.full(5, relax[-1]), ramp(relax[-1], 0, 5), np.zeros(10)])
    phase, grasp = label_session(force)
    assert set(grasp[10:]) - {-1} == {0}
    assert set(phase[18:18 + 60 + 5].tolist()) == {"holding"}
    trace = np.concatenate([np.zeros(10), ramp(0, 3, 8), np.full(20, 3.0), dip, ramp(3, 0, 5), np.zeros(10)])
    _, grasp = label_session(trace)
    assert set(grasp.tolist()) == {-1, 0}


def test_session_columns_pad_with_none_and_minus_one_and_auto_keeps_single_grasps():
    force = session_trace()
    phase, grasp = session_columns(np.concatenate([force, np.full(7, np.nan)]), force.size, force.size + 7)
    assert phase.size == grasp.size == force.size + 7 and set(grasp[-7:].tolist()) == {-1} and set(phase[-7:]) == {"none"}
    single = np.concatenate([np.zeros(5), ramp(0, 3, 10), np.full(40, 3.0), ramp(3, 0, 6), np.zeros(5)])
    session_phase, session_grasp = label_session(single)
    assert set(session_grasp.tolist()) == {-1, 0}
    assert list(detect_phases(single)).count("holding") > 30  # `auto` is untouched by the session labels


@settings(max_examples=40, deadline=None)
@given(levels=st.lists(st.floats(1.0, 4.0), max_size=6), seed=st.integers(0, 2**32 - 1))
def test_every_grasp_of_a_random_session_is_found_once_and_in_order(levels, seed):
    rng = np.random.default_rng(seed)
    parts, spans = [np.zeros(int(rng.integers(30, 60)))], []  # enough rest to read the noise from
    for level in levels:
        start = sum(part.size for part in parts)
        rise, hold, fall = int(rng.integers(1, 30)), int(rng.integers(5, 80)), int(rng.integers(1, 20))
        parts += [ramp(0, level, rise), np.full(hold, level), ramp(level, 0, fall), np.zeros(int(rng.integers(5, 30)))]
        spans.append((start, start + rise, start + rise + hold, start + rise + hold + fall))
    force = np.concatenate(parts) + rng.normal(0, 0.005, sum(part.size for part in parts))
    phase, grasp = label_session(force)
    assert sorted(set(grasp.tolist()) - {-1}) == list(range(len(levels)))
    for index, (start, loaded, release, end) in enumerate(spans):
        mine = np.flatnonzero(grasp == index)
        assert start <= mine[0] <= loaded and release <= mine[-1] <= end  # contact found in the rise, lost in the fall
        assert phase[mine[0]] == "grasping" and phase[mine[-1]] == "releasing"


def test_a_log_quantised_more_coarsely_than_its_noise_holds_no_grasp():
    """Noise of 4 mN logged in 12.5 mN steps mostly repeats a value: a deviation of 0 made its
    steps of noise grasps (2 found in 4,000 samples of rest). The noise is at least one step."""
    rest = np.round(np.random.default_rng(3).normal(0.0, 0.004, 4_000) / 0.0125) * 0.0125
    phase, grasp = label_session(rest)
    assert (grasp == -1).all() and set(phase) == {"none"}
    loaded = rest.copy()
    loaded[1_000:1_400] += 1.0
    assert set(label_session(loaded)[1]) == {-1, 0}


def test_a_force_sensor_whose_zero_drifts_keeps_its_rests_at_rest():
    """A strain gauge warming: its zero climbs 0.5 N a minute over 3 minutes. Read against one rest
    level for the whole log, the later rests were grasps and the weak grasps among the strong split or
    vanished; each stretch of the log has its own rest level."""
    rng = np.random.default_rng(3)
    parts, peaks = [np.zeros(150)], []
    for k in range(24):
        peak = 0.6 if k % 3 == 0 else 5.0
        hold = int(rng.integers(80, 400))
        parts += [ramp(0, peak, 10), np.full(hold, peak), ramp(peak, 0, 8), np.zeros(int(rng.integers(300, 500)))]
        peaks.append(peak)
    force = np.concatenate(parts)
    drifted = force + 0.5 * np.arange(force.size) / 6000 + rng.normal(0, 0.01, force.size)  # 10 ms frames: 6000 a minute
    assert drifted.size / 6000 > 2.5 and drifted[-1] - drifted[0] > 1.2
    phase, grasp = label_session(drifted)
    assert grasp.max() + 1 == len(peaks)
    assert np.all((grasp >= 0) == (phase != "none"))
    assert np.mean(phase[force == 0] == "none") > 0.99  # the true rests (a grasp's last frame reads below contact)
    assert rest_drift(drifted) == pytest.approx(drifted.size / 6000 * 0.5, abs=0.1) and rest_drift(force + 0.001) is None
    # `eval`'s check that frames at rest carry no force reads the same rest levels: no drifted rest is "loaded"
    frame = np.arange(drifted.size)
    rows = metrics.session_rows(["s"] * frame.size, frame, frame * 10_000.0, phase, drifted, np.zeros(frame.size))
    assert "rest_loaded_frames" not in {metric for scope, metric, _ in rows if scope == "all"}


@pytest.mark.parametrize("drift", [-2.0, -1.0, 0.5, 1.0, 2.0])
def test_a_drifting_log_at_rest_holds_no_grasp(drift):
    """A session without a grasp whose zero drifts 0.5-2 N a minute: each stretch's 5th percentile,
    read flat, sat under most of its rest by half the stretch's drift, above the 5-noise-σ bar (the
    whole log one grasp); read about the line through the stretches, and followed to the log's ends."""
    n = 30_000
    drifted = np.random.default_rng(1).normal(0, 0.003, n) + drift * np.arange(n) / 6000
    phase, grasp = label_session(drifted)
    assert (grasp == -1).all() and set(phase) == {"none"}
    with_grasps = drifted.copy()
    for start in range(2_000, n - 1_000, 4_000):
        with_grasps[start:start + 300] += np.r_[ramp(0, 3.0, 20), np.full(260, 3.0), ramp(3.0, 0, 20)]
    grasp = label_session(with_grasps)[1]
    assert grasp.max() + 1 == len(range(2_000, n - 1_000, 4_000))
    assert np.mean(grasp[with_grasps - drifted == 0] == -1) > 0.995


def seventy_grasps(rng):
    """(force, true contact per frame) of 70 grasps of 0.5-6 N, rises of 5-30 frames, holds of
    0.6-3.4 s and rests of 0.3-3 s, at 10 ms frames, without noise."""
    parts, truth = [np.zeros(200)], [np.zeros(200, dtype=bool)]
    for _ in range(70):
        peak, rise, hold, rest = rng.uniform(0.5, 6.0), int(rng.integers(5, 30)), int(rng.integers(60, 340)), int(rng.integers(30, 300))
        parts += [ramp(0, peak, rise), np.full(hold, peak), ramp(peak, 0, rise), np.zeros(rest)]
        truth += [np.ones(2 * rise + hold - 1, dtype=bool), np.zeros(rest + 1, dtype=bool)]
    return np.concatenate(parts), np.concatenate(truth)


@pytest.mark.parametrize("noise", [0.1, 0.15])
def test_a_noisy_load_cell_s_grasps_are_found_whole(noise):
    """Noise of 0.1-0.2 N on grasps of 0.5-6 N: a bar of 5 noise σ on the log as logged lost weak
    grasps and the edges of the others (76-97% of the contact frames, 56-69 grasps of 70). The log is
    read through the shortest centred median that puts its noise under the bar."""
    rng = np.random.default_rng(4)
    force, truth = seventy_grasps(rng)
    grasp = label_session(force + rng.normal(0, noise, force.size))[1]
    assert grasp.max() + 1 == 70
    assert np.mean(grasp[truth] >= 0) > 0.97 and np.mean(grasp[~truth] >= 0) < 0.01


@pytest.mark.parametrize("seconds", [1, 5, 12, 19])
@pytest.mark.parametrize("end", ["start", "end"])
def test_a_sensor_tared_near_the_log_s_ends_keeps_its_rests_at_rest(seconds, end):
    """A log 1.5 N off its zero until the sensor is tared 1-19 s after it began (or re-tared that
    long before it stopped): the stretch read as one grasp from the first frame (to the last), 1-7%
    of the rest frames, swallowing the grasps in it. One sample from a rest to a rest is a tare."""
    rng = np.random.default_rng(2)
    parts = [np.zeros(200)]
    for _ in range(40):
        peak = rng.uniform(0.5, 6.0)
        parts += [ramp(0, peak, 15), np.full(int(rng.integers(100, 300)), peak), ramp(peak, 0, 15), np.zeros(int(rng.integers(40, 300)))]
    force = np.concatenate(parts)
    at = seconds * 100  # 10 ms frames
    if end == "end":
        at = force.size - at
    while force[at - 20:at + 20].any():  # a lab tares at rest
        at += 1
    logged = force + rng.normal(0, 0.01, force.size)
    logged[:at] += 1.5 if end == "start" else 0.0
    logged[at:] += 1.5 if end == "end" else 0.0
    phase, grasp = label_session(logged)
    assert grasp.max() + 1 == 40
    assert np.mean(grasp[force == 0] == -1) > 0.995


def test_a_noisy_log_s_glitches_are_still_said():
    """The median takes a noisy log's glitches out before they are runs of contact, which `frame`
    counted and warned of: 0 of 20 said. They are found on the log as logged (above 5 of its noise σ,
    peaking 10 σ over its rest, away from the grasps), and a log without one has none said."""
    rng = np.random.default_rng(5)
    force, truth = seventy_grasps(rng)
    logged = force + rng.normal(0, 0.2, force.size)
    quiet, said = [], []
    clean = label_session(logged, spikes=quiet)[1]
    at = [a for a in rng.choice(np.flatnonzero(~truth)[10:-10], 20, replace=False) if not truth[a - 3:a + 5].any()]
    for a in at:
        logged[a:a + 2] += 3.0
    grasp = label_session(logged, spikes=said)[1]
    assert not quiet and sorted(first for first, _, _ in said) == sorted(at)
    assert np.mean(grasp == clean) > 0.999


def test_a_noisy_log_is_read_through_a_median_only_where_that_helps():
    """The median is for a long log's white noise. A log of under three stretches has one or two
    rest levels, which a drift passes under the median's lower bar (15 s drifting 2 N a minute: 42%
    of the rest labelled grasp); a slow noise is not lowered by a few samples' median, which only
    took off the peaks that carried weak grasps over the bar (198 grasps found of 210, 204 as
    logged); and a drifting log's scale is read above its rest levels, not from its spread, which
    the drift fills."""
    from scipy.signal import lfilter

    from neurotac_cli.ops.phases import _calm

    rng = np.random.default_rng(7)
    short = np.zeros(1500)
    short[400:700] = np.r_[ramp(0, 3.0, 20), np.full(260, 3.0), ramp(3.0, 0, 20)]
    drifting = short + rng.normal(0, 0.1, short.size) + 2.0 * np.arange(short.size) / 6000
    assert np.mean(label_session(drifting)[1][short == 0] >= 0) < 0.02
    found = 0
    for seed in range(3):  # 70 grasps each under one-pole low-passed noise of 0.2 N: 66, 68 and 70 found as logged
        rng = np.random.default_rng(seed)
        force = seventy_grasps(rng)[0]
        found += label_session(force + lfilter([0.5], [1, -0.5], rng.normal(0, 0.35, force.size)))[1].max() + 1
    assert found >= 202
    white = rng.normal(0, 0.2, 72_000) + 1.0 * np.arange(72_000) / 6000  # 12 minutes, 1 N a minute
    for start in range(500, 71_000, 1_500):
        white[start:start + 400] += 3.0
    calm, noise, _ = _calm(white, 0.05, 1000)
    assert calm is not white and noise < 0.1


@pytest.mark.parametrize("keep", [0.9, 0.95])
def test_a_load_cell_low_passed_below_its_sample_rate_keeps_its_rests_at_rest(keep):
    """Noise of 0.2 N that keeps 0.9-0.95 of itself from one sample to the next (a sensor's filter
    well below the logger's rate) steps by a third to a fifth of its σ, so a bar of 5 step σ lay
    inside it: 14-39% of the rest frames labelled grasps, 1.5-2.2 times as many grasps as there were.
    Read over lags up to 640 ms away from the grasps, the bar sits above the noise; the grasps under
    it (peaks under 10 of its σ: 8-13 of 70) are lost, as a white noise of that σ loses them. A
    white noise's labels are as before (its lags read what its steps read)."""
    from scipy.signal import lfilter

    from neurotac_cli.ops.frame import Framing, _LabelDoubts

    rng = np.random.default_rng(11)
    force, truth = seventy_grasps(rng)
    slow = lfilter([1 - keep], [1, -keep], rng.normal(0, 0.2, force.size)) / np.sqrt((1 - keep) / (1 + keep))
    said = []
    grasp = label_session(force + slow, slow=said)[1]
    assert np.mean(grasp[~truth] >= 0) < 0.01 and 55 <= grasp.max() + 1 <= 70
    (sigma, steps), = said
    assert 0.15 < sigma < 0.25 and steps < sigma / 2.5
    # the zero `--zero rest` takes off: no step read in the noise's wander, within 0.15 N r.m.s.
    line = rest_line(force + slow)
    assert np.sqrt(np.mean(line ** 2)) < 0.15 and np.abs(line).max() < 0.4
    assert rest_drift(force + slow, line, noise=sigma) is None
    doubts = _LabelDoubts(Framing(window_us=10_000, phases="session"))
    doubts.look_at_spikes("s", [], said)
    assert any(f"noise is slower than its samples in 1 session (s: σ {sigma:.3g}" in n for n in doubts.notes()), doubts.notes()
    assert np.mean(grasp[truth & (force > 2.5)] >= 0) > 0.97
    # `eval`'s check that frames at rest carry no force reads the same noise: the rests are not "loaded"
    frame = np.arange(force.size)
    phase = label_session(force + slow)[0]
    rows = metrics.session_rows(["s"] * frame.size, frame, frame * 10_000.0, phase, force + slow, np.zeros(frame.size))
    assert "rest_loaded_frames" not in {metric for scope, metric, _ in rows if scope == "all"}
    for sigma in (0.02, 0.2):
        white = force + rng.normal(0, sigma, force.size)
        assert slow_noise(white, white - rest_levels(white), ~truth, step_noise(np.diff(white)), 1000) is None


@pytest.mark.parametrize("seed", [3, 12, 16])
def test_grasps_packed_close_under_a_white_noise_keep_its_step_noise(seed):
    """Between grasps 0.2-0.6 s apart, a first reading of the noise over lags between samples that
    were only not in a grasp took the weak grasps' edges for noise (2.5-5 times the σ of a 0.2 N
    white noise) and the session was labelled again at it: 0-8 grasps found of 16-18."""
    rng = np.random.default_rng(seed)
    parts = [np.zeros(40)]
    for _ in range(20):
        peak = rng.uniform(0.5, 6)
        parts += [np.linspace(0, peak, 10), np.full(rng.integers(40, 200), peak), np.linspace(peak, 0, 10), np.zeros(rng.integers(20, 60))]
    clean = np.concatenate(parts)
    said = []
    grasp = label_session(clean + rng.normal(0, 0.2, clean.size), block=1000, slow=said)[1]
    assert not said and grasp.max() + 1 >= 15


def test_a_press_of_one_sample_held_to_near_the_log_s_end_is_a_grasp():
    """A 15 s log pressed in one sample and let go five samples before it ends: a few samples at
    rest after the hold tell it from a sensor re-tared before the log stopped."""
    force = np.zeros(1500)
    force[178:1495] = 8.0
    grasp = label_session(force + np.random.default_rng(0).normal(0, 0.02, force.size))[1]
    assert grasp.max() == 0 and np.mean(grasp[178:1495] == 0) > 0.99


def test_presses_of_one_sample_into_long_flat_holds_are_grasps_not_tares():
    """A gripper that steps to its force in one sample and holds it flat for 5-30 s: from rest to a
    flat level in one sample, as a tare is. Read as tares anywhere in the log, 21 of 26 such grasps
    were lost; a tare is only looked for where the blocks cannot see one, at the log's ends."""
    rng = np.random.default_rng(0)
    parts, truth = [np.zeros(300)], [np.zeros(300, dtype=bool)]
    while sum(part.size for part in parts) < 60_000:
        hold, rest = int(rng.uniform(5, 30) * 100), int(rng.uniform(2, 10) * 100)
        parts += [np.full(hold, rng.uniform(0.5, 6.0)), np.zeros(rest)]
        truth += [np.ones(hold, dtype=bool), np.zeros(rest, dtype=bool)]
    force, truth = np.concatenate(parts), np.concatenate(truth)
    grasp = label_session(force + rng.normal(0, 0.01, force.size))[1]
    assert grasp.max() + 1 == len(parts) // 2 and np.mean(grasp[truth] >= 0) > 0.999


def test_a_hold_longer_than_the_rest_level_s_stretches_reads_no_rest_of_its_own():
    """A rest level read per 10 s stretch would take a minute-long hold's middle for rest, split the
    grasp and lose its weak neighbours: a stretch that stands above the line through its neighbours
    holds no rest, drifting or not."""
    for drift in (0.0, 0.5):
        parts = [np.zeros(2000)]
        for peak, hold in ((3.0, 6000), (0.6, 300), (5.0, 400), (0.6, 200), (4.0, 500)):
            parts += [ramp(0, peak, 10), np.full(hold, peak), ramp(peak, 0, 8), np.zeros(800)]
        force = np.concatenate(parts)
        noisy = force + drift * np.arange(force.size) / 6000 + np.random.default_rng(4).normal(0, 0.01, force.size)
        phase, grasp = label_session(noisy)
        assert grasp.max() + 1 == 5 and np.mean(phase[force == 0] == "none") > 0.99


@pytest.mark.parametrize("step", [1.0, -1.0, 0.3, 2.0])
@pytest.mark.parametrize("drift", [0.0, 0.4])
def test_a_sensor_re_tared_between_grasps_keeps_its_rests_at_rest(step, drift):
    """A zero that steps (re-tared, a cable knocked) and stays: its later rests stood above the line
    through their neighbours, were taken for a hold one after another to the log's end, and 15-30%
    of the rest frames after it were labelled grasps; zeroing ramped across the step for 10 s."""
    rng = np.random.default_rng(6)
    parts = [np.zeros(200)]
    for k in range(40):
        peak = 0.6 if k % 4 == 0 else float(rng.uniform(2, 6))
        parts += [ramp(0, peak, 10), np.full(int(rng.integers(80, 350)), peak), ramp(peak, 0, 8), np.zeros(int(rng.integers(60, 300)))]
    force = np.concatenate(parts)
    rests = np.flatnonzero(force == 0)
    at = int(rests[np.argmin(np.abs(rests - force.size // 2))])  # in a rest, as a re-tare is
    zero = drift * np.arange(force.size) / 6000 + rng.normal(0, 0.02, force.size)
    zero[at:] += step
    phase, grasp = label_session(force + zero)
    assert grasp.max() + 1 == 40 and np.mean(phase[force == 0] == "none") > 0.99
    assert np.sqrt(np.mean((force + zero - rest_line(force + zero) - force) ** 2)) < 0.03


def test_a_re_tare_inside_a_gap_of_the_log_that_begins_in_a_grasp_is_read_from_the_known_samples():
    """The gap's samples bridged from a held grasp to the rest after it were read as levels: a step up
    went before the grasp, whose zero was 2.3 N off; the step is put at the gap's start."""
    rng = np.random.default_rng(0)
    one = np.r_[ramp(0, 4.0, 10), np.full(300, 4.0), ramp(4.0, 0, 8)]
    before = np.concatenate([np.r_[np.zeros(600), one] for _ in range(12)])
    force = np.r_[before, np.zeros(600), *[np.r_[one, np.zeros(600)] for _ in range(12)]]
    gap = before.size - 100  # the log drops out 1 s before a release, for 30 s
    logged = force + rng.normal(0, 0.02, force.size)
    logged[before.size:] += 1.0
    logged[gap:gap + 3000] = np.nan
    plain = force + rng.normal(0, 0.02, force.size)
    plain[gap:gap + 3000] = np.nan
    assert label_session(logged)[1].max() == label_session(plain)[1].max()
    held = slice(gap - 300, gap)
    assert np.abs(logged[held] - rest_line(logged)[held] - force[held]).max() < 0.1


def test_a_force_sensor_s_glitches_are_no_grasps_and_are_said():
    """Spikes of 1-3 frames above the rest level (a load cell's interference) were each a grasp: 20
    glitches among 40 grasps gave 60."""
    from neurotac_cli.ops.frame import Framing, _LabelDoubts

    rng = np.random.default_rng(7)
    parts = [np.zeros(200)]
    for _ in range(40):
        parts += [ramp(0, float(rng.uniform(1, 5)), 10), np.full(int(rng.integers(40, 300)), 3.0), ramp(3.0, 0, 8),
                  np.zeros(int(rng.integers(100, 300)))]
    force = np.concatenate(parts) + rng.normal(0, 0.01, sum(map(len, parts)))
    rests = [k for k in np.flatnonzero(np.concatenate(parts) == 0) if k > 20 and (np.concatenate(parts)[k - 20:k + 25] == 0).all()]
    places = rests[::max(1, len(rests) // 20)][:20]
    glitched = force.copy()
    for k, place in enumerate(places):
        glitched[place:place + 1 + k % 3] += 4.0
    spikes = []
    phase, grasp = label_session(glitched, spikes=spikes)
    assert grasp.max() + 1 == 40 and len(spikes) == len(places) and (grasp[places] == -1).all()
    assert sorted(first for first, _, _ in spikes) == sorted(places)
    # a grasp cut by the log's end is kept however short; 50 ms frames take no run of contact for a glitch
    cut = np.r_[force[:places[0]], 2.0, 3.0]
    assert label_session(cut)[1][-2:].tolist() == [0, 0]
    assert label_session(glitched, block=200)[1].max() + 1 == 40 + len(places)  # 200 frames in 10 s: 50 ms frames
    doubts = _LabelDoubts(Framing(window_us=10_000, phases="session"))
    doubts.look_at_spikes("s", spikes, [])
    assert any(f"into contact for under 40 ms {len(places)} times in 1 session (s: {len(places)}" in n for n in doubts.notes()), doubts.notes()


def test_the_rest_level_s_stretches_are_seconds_at_any_frame_window_and_bridge_missing_force():
    """The stretches were counted in frames (10 s at 10 ms, 50 s at 50 ms frames), and missing force
    was filled with the whole log's level, which dragged a drifting log's local level."""
    rng = np.random.default_rng(5)
    parts = [np.zeros(40)]
    for k in range(20):
        peak = 0.6 if k % 3 == 0 else 4.0
        parts += [ramp(0, peak, 3), np.full(int(rng.integers(10, 40)), peak), ramp(peak, 0, 3), np.zeros(int(rng.integers(30, 80)))]
    force = np.concatenate(parts)  # 50 ms frames: 1,200 a minute
    drifted = force + 1.0 * np.arange(force.size) / 1200 + rng.normal(0, 0.01, force.size)
    assert drifted.size / 1200 > 1.3  # 1.4 minutes: eight 10 s stretches
    assert session_columns(drifted, drifted.size, drifted.size, window_us=50_000)[1].max() + 1 == 20
    gapped = drifted.copy()
    gapped[drifted.size // 2: drifted.size // 2 + 600] = np.nan  # 30 s without force
    phase, grasp = session_columns(gapped, gapped.size, gapped.size, window_us=50_000)
    known_rest = (force == 0) & ~np.isnan(gapped)
    assert np.mean(phase[known_rest] == "none") > 0.98



def test_frames_zeroed_at_rest_take_a_drifting_sensor_s_zero_out_of_the_force():
    """`frame --zero rest`: a strain gauge whose zero climbs 0.5 N a minute labelled every later grasp
    and rest high by the drift; the force less the rest level where it is, and the rest's median
    (the levels are low percentiles, 1.6 noise σ under it), is the true force within the noise."""
    from neurotac_cli.ops.frame import held_level, rest_zeroed as zeroed_with

    def rest_zeroed(force, n_real, window_us, trial=""):  # as `frame` calls it, at 10 ms frames
        line = rest_line(force[:n_real], block=1000)
        if line is None:
            return force, None
        zeroed = zeroed_with(force, n_real, line, trial)
        return zeroed, held_level(force, n_real, line, label_session(zeroed[:n_real])[1])

    rng = np.random.default_rng(3)
    parts = [np.zeros(150)]
    for k in range(24):
        peak = 0.6 if k % 3 == 0 else 5.0
        parts += [ramp(0, peak, 10), np.full(int(rng.integers(80, 400)), peak), ramp(peak, 0, 8), np.zeros(int(rng.integers(300, 500)))]
    force = np.concatenate(parts)
    noise = rng.normal(0, 0.01, force.size)
    drifted = force + 0.5 * np.arange(force.size) / 6000 + noise  # 10 ms frames
    padded = np.r_[drifted, np.zeros(5), np.nan].astype(np.float32)  # padding frames, and a frame without force
    zeroed, held = rest_zeroed(padded, drifted.size, 10_000)
    assert held is None
    error = zeroed[: drifted.size] - (force + noise)
    assert abs(np.mean(error)) < 0.005 and np.sqrt(np.mean(error**2)) < 0.02 and zeroed.dtype == np.float32
    assert np.abs(drifted - (force + noise)).max() > 1.2  # what the log alone labels
    # padding frames (the log's last sample) lose the last frame's level, as it does
    assert np.allclose(zeroed[drifted.size : -1] - padded[drifted.size : -1], zeroed[drifted.size - 1] - padded[drifted.size - 1])
    assert np.isnan(zeroed[-1])
    again, before = label_session(zeroed[: drifted.size])[1], label_session(drifted)[1]
    assert again.max() == before.max() == 23 and np.mean(again == before) > 0.999
    assert np.array_equal(rest_zeroed(np.full(4, np.nan), 4, 10_000)[0], np.full(4, np.nan), equal_nan=True)
    # a drift followed to the log's ends: a minute at rest drifting 0.5 N
    ramp_only = 0.5 * np.arange(6000) / 6000 + np.random.default_rng(2).normal(0, 0.01, 6000)
    ends = rest_zeroed(ramp_only, 6000, 10_000)[0]
    assert np.abs(ends[:300]).mean() < 0.015 and np.abs(ends[-300:]).mean() < 0.015
    # a trial cut inside a hold has no rest: its force is taken off, and the level is given back to be warned
    hold = 3.0 + np.random.default_rng(1).normal(0, 0.01, 400)
    assert rest_zeroed(hold, hold.size, 10_000)[1] == pytest.approx(3.0, abs=0.05)
    with pytest.raises(SchemaError, match="trial t: its force less its rest level passes float32's range"):
        rest_zeroed(np.r_[np.full(50, -2e38), np.linspace(-2e38, 1.8e38, 50)].astype(np.float32), 100, 10_000, "t")


def test_frame_names_what_zeroing_at_rest_could_not_do():
    """A trial held throughout has its force taken off as rest, and a trial without a log has nothing to
    zero: each said; the drift warning says grasps are found above the level only where they are."""
    from neurotac_cli.ops.frame import Framing, _LabelDoubts

    doubts = _LabelDoubts(Framing(window_us=10_000, zero="rest", phases="none"))
    drifting = 0.5 * np.arange(6000) / 6000 + np.random.default_rng(2).normal(0, 0.01, 6000)
    doubts.look("d", drifting, 6000, rest_line(drifting, 1000))
    doubts.look("nolog", None, 100)
    doubts.look_at_zero("inside", 2.97)
    notes = doubts.notes()
    assert any("a force sensor whose zero drifts or was re-tared; the frames' force is taken from that level (--zero rest)" in n for n in notes), notes
    assert any("found no grasp in 1 trial whose rest level lies far from the log's zero (inside: +2.97)" in n for n in notes), notes
    assert any("--zero rest: 1 trial (nolog) has no force log" in n for n in notes), notes
