"""frame: half-open windows from t0, conservation, tonic equality on real recordings, force, phases."""

import os
import subprocess
import sys

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest
from hypothesis import given, settings, strategies as st

from neurotac_cli import schema as sch, tables
from neurotac_cli.errors import NeurotacError
from neurotac_cli.io import kernels
from neurotac_cli.ops import frame as fr
from neurotac_cli.ops import phases as ph

W, H = 24, 18


def random_events(seed, n=2000, span=95_000, start=0, width=W, height=H):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.integers(start, start + span, n))
    return t, rng.integers(0, width, n), rng.integers(0, height, n), rng.integers(0, 2, n)


def recordings(trials, width=W, height=H):
    return sch.recordings_table(trials, width, height)


def trapezoid_force(end_ms=200):
    t_ms = np.arange(0, end_ms + 1, 2)
    force = np.interp(t_ms, [0, 20, 60, 140, 170, end_ms], [0, 0, 3, 3, 0, 0])
    return t_ms * 1000, force


def counts_of(table):
    return sch.counts_numpy(table.column("counts"))


# ---------------------------------------------------------------- windows and conservation


def test_windows_are_half_open_from_t0_and_empty_windows_are_zero_frames():
    t = np.array([-5, 0, 9_999, 10_000, 45_000])
    x, y, p = np.array([0, 1, 2, 3, 4]), np.zeros(5), np.array([0, 0, 1, 1, 0])
    force_t, force_v = np.arange(0, 50_001, 2000), np.ones(26)
    table = recordings([{"trial": "a", "t0": 7, "events": (t, x, y, p), "force": (force_t, force_v)}])
    report = fr.FramingReport()
    frames = fr.frame_recordings(table, 10_000, report=report)
    counts = counts_of(frames)
    assert frames.column("t").to_pylist() == [0, 10_000, 20_000, 30_000, 40_000, 50_000]
    assert counts[0].sum() == 2 and counts[0][0, 0, 1] == 1 and counts[0][1, 0, 2] == 1  # 0 and 9999 in [0, 10ms)
    assert counts[1][1, 0, 3] == 1  # 10000 starts the next window
    assert counts[2].sum() == counts[3].sum() == 0  # empty windows are zero frames, not missing rows
    assert report.before_start == 1 and report.framed == 4


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), window=st.sampled_from([1_000, 7_000, 10_000]), keep=st.booleans(),
       chunk=st.sampled_from([7, 100, 100_000]))
def test_counts_of_all_frames_equal_the_events_inside_the_windows(seed, window, keep, chunk):
    t, x, y, p = random_events(seed, start=1_234_567)
    table = sch.events_table(t, x, y, p, W, H)
    report = fr.FramingReport()
    framing = fr.Framing(window_us=window, partial="keep" if keep else "drop")
    schema, batches = fr.frame_events(table.schema, table.to_batches(max_chunksize=chunk), framing, report)
    frames = pa.Table.from_batches(list(batches), schema=schema)
    counts = counts_of(frames)
    n = len(counts)
    inside = (t - t[0]) < n * window
    assert counts.sum() == inside.sum() == report.framed
    assert report.framed + report.dropped == len(t)
    assert frames.column("frame").to_pylist() == list(range(n))
    # every event is in the frame of its window, on its pixel and channel
    k = (t[inside] - t[0]) // window
    expected = np.zeros_like(counts)
    np.add.at(expected, (k, p[inside], y[inside], x[inside]), 1)
    assert np.array_equal(counts, expected)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), pad=st.sampled_from([None, "longest", 3, 30]))
def test_recording_counts_equal_events_inside_windows_and_drops_are_counted(seed, pad):
    rng = np.random.default_rng(seed)
    trials = []
    for i in range(3):
        t, x, y, p = random_events(seed + i, n=500, span=int(rng.integers(20_000, 120_000)), start=-15_000)
        force_t = np.arange(0, int(rng.integers(10_000, 110_000)), 2000)
        trials.append({"trial": f"g{i}", "t0": 10**6, "events": (t, x, y, p), "force": (force_t, np.ones(len(force_t)))})
    report = fr.FramingReport()
    frames = fr.frame_recordings(recordings(trials), 10_000, report=report, pad_to=pad)
    assert counts_of(frames).sum() == report.framed
    assert report.framed + report.before_start + report.after_end == report.events == 1500
    lengths = [frames.filter(pc.equal(frames.column("trial"), f"g{i}")).num_rows for i in range(3)]
    if pad == "longest":
        assert len(set(lengths)) == 1
    elif isinstance(pad, int):
        assert lengths == [pad] * 3


def test_streamed_frames_equal_whole_frames_with_a_small_buffer(monkeypatch):
    monkeypatch.setattr(fr, "BUFFER_CELLS", 2 * H * W * 3)  # three frames of buffer: frames leave early
    monkeypatch.setattr(fr, "SCAN_EVENTS", 700)  # one big input batch is scanned in slices
    t, x, y, p = random_events(3, n=5000, span=400_000)
    t[2000:2100] += 150_000  # a gap of empty windows
    t = np.sort(t)
    table = sch.events_table(t, x, y, p, W, H)
    streamed = fr.frames_from_events_table(table, 5_000)
    n = len(counts_of(streamed))
    assert np.array_equal(counts_of(streamed), fr.count_frames(t, x, y, p, 5_000, n, H, W, start=int(t[0])))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), gaps=st.lists(st.integers(0, 80_000), min_size=0, max_size=4),
       batch=st.sampled_from([1, 37, 500, 10_000]), frames=st.integers(2, 5))
def test_streamed_frames_hold_no_stale_counts_across_gaps_and_batch_sizes(seed, gaps, batch, frames):
    # frames are zeroed lazily as events reach them: a frame no event reached must still leave as zeros
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(fr, "BUFFER_CELLS", 2 * H * W * frames)
        t, x, y, p = random_events(seed, n=3000, span=300_000)
        for position, gap in zip(np.random.default_rng(seed).integers(0, 3000, len(gaps)), gaps):
            t[position:] += gap  # runs of empty windows, some longer than the buffer
        table = sch.events_table(t, x, y, p, W, H)
        schema, batches = fr.frame_events(table.schema, table.to_batches(max_chunksize=batch), fr.Framing(window_us=5_000),
                                          fr.FramingReport())
        streamed = np.concatenate([counts_of(pa.Table.from_batches([b])).copy() for b in batches])
    assert np.array_equal(streamed, fr.count_frames(t, x, y, p, 5_000, len(streamed), H, W, start=int(t[0])))


def test_a_stream_whose_frames_are_let_go_counts_into_two_buffers_in_turn(monkeypatch):
    """A fresh buffer's first touch costs page faults (a stalled frame in a live stream); once the
    frames of a buffer have been let go downstream, it is reused."""
    monkeypatch.setattr(fr, "BUFFER_CELLS", 2 * H * W * 4)
    made = []
    empty_like = np.empty_like
    monkeypatch.setattr(np, "empty_like", lambda a, *args, **kw: made.append(a.shape) or empty_like(a, *args, **kw))
    t, x, y, p = random_events(5, n=20_000, span=900_000)
    table = sch.events_table(t, x, y, p, W, H)
    schema, batches = fr.frame_events(table.schema, table.to_batches(max_chunksize=500), fr.Framing(window_us=5_000), fr.FramingReport())
    streamed = np.concatenate([counts_of(pa.Table.from_batches([b])).copy() for b in batches])
    assert len(streamed) == 180
    assert made == [(4, 2, H, W)]  # the first buffer, then the second, then the two in turn
    assert np.array_equal(streamed, fr.count_frames(t, x, y, p, 5_000, len(streamed), H, W, start=int(t[0])))


def test_frames_held_downstream_keep_their_counts_while_later_frames_are_counted(monkeypatch):
    monkeypatch.setattr(fr, "BUFFER_CELLS", 2 * H * W * 4)
    t, x, y, p = random_events(4, n=20_000, span=900_000)
    table = sch.events_table(t, x, y, p, W, H)
    schema, batches = fr.frame_events(table.schema, table.to_batches(max_chunksize=500), fr.Framing(window_us=5_000), fr.FramingReport())
    copies, kept = [], []
    for i, batch in enumerate(batches):
        copies.append(counts_of(pa.Table.from_batches([batch])).copy())
        if i % 3 == 0:
            kept.append(batch)  # some frames stay held: their buffers must not be reused
    streamed = np.concatenate(copies)
    assert np.array_equal(streamed, fr.count_frames(t, x, y, p, 5_000, len(streamed), H, W, start=int(t[0])))
    held = np.concatenate([counts_of(pa.Table.from_batches([b])) for b in kept])
    first = [b.column("frame")[0].as_py() for b in kept]
    lengths = [b.num_rows for b in kept]
    expected = np.concatenate([streamed[f:f + n] for f, n in zip(first, lengths)])
    assert np.array_equal(held, expected)


def test_events_out_of_time_order_are_refused_with_their_count_and_first_place():
    t = np.array([0, 10_000, 50_000, 60_000, 5_000, 70_000, 20_000, 80_000])  # two step back more than a window
    x = y = np.zeros(8, dtype=int)
    p = np.ones(8, dtype=int)
    table = sch.events_table(t, x, y, p, W, H)
    schema, batches = fr.frame_events(table.schema, table.to_batches(max_chunksize=3), fr.Framing(window_us=10_000), fr.FramingReport())
    with pytest.raises(NeurotacError, match=r"^2 events more than one window out of time order \(the first: event 4 at t = 5000 µs, after an event at 60000 µs; sort them with --sort"):
        list(batches)


def test_events_before_the_first_event_are_out_of_order_not_an_empty_table():
    t = np.array([3_000, 1_000, 2_000, 500])  # three of four before the first: no frame would hold them
    table = sch.events_table(t, np.zeros(4, int), np.zeros(4, int), np.zeros(4, int), W, H)
    with pytest.raises(NeurotacError, match="^3 events more than one window out of time order"):
        fr.frames_from_events_table(table, 10_000)
    report = fr.FramingReport()
    frames = fr.frames_from_events_table(table, 1_000, report=report, sort=True)
    assert counts_of(frames).sum() == 4 and frames.num_rows == 3 and report.framed == 4


def test_sort_frames_shuffled_events_as_sorted_ones():
    t, x, y, p = random_events(5, n=3000, span=200_000)
    order = np.random.default_rng(5).permutation(len(t))
    shuffled = sch.events_table(t[order], x[order], y[order], p[order], W, H)
    ordered = fr.frames_from_events_table(sch.events_table(t, x, y, p, W, H), 5_000)
    assert np.array_equal(counts_of(fr.frames_from_events_table(shuffled, 5_000, sort=True)), counts_of(ordered))


def test_pad_to_cuts_a_stream_even_when_whole_batches_lie_past_it():
    t = np.array([0, 5_000, 15_000, 50_000, 60_000, 70_000])  # the second batch lies past frame 3
    table = sch.events_table(t, np.zeros(6, int), np.zeros(6, int), np.zeros(6, int), W, H)
    report = fr.FramingReport()
    schema, batches = fr.frame_events(table.schema, table.to_batches(max_chunksize=3), fr.Framing(window_us=10_000, pad_to=5), report)
    frames = pa.Table.from_batches(list(batches), schema=schema)
    assert frames.num_rows == 5 and counts_of(frames).sum() == 3 == report.framed and report.after_end == 3


def test_sort_refuses_more_events_than_it_may_hold(monkeypatch):
    monkeypatch.setattr(fr, "SORT_EVENTS", 1_000)
    t, x, y, p = random_events(6, n=1_500)
    with pytest.raises(NeurotacError, match=r"^more than 1,000 events to sort \(--sort holds them in memory"):
        fr.frames_from_events_table(sch.events_table(t, x, y, p, W, H), 5_000, sort=True)


def test_events_late_by_less_than_a_window_after_their_frame_left_are_counted_as_late():
    t = np.array([0, 10_000, 20_500, 19_000, 30_000])  # 19000 arrives after window [10, 20 ms) has left
    table = sch.events_table(t, np.zeros(5, int), np.zeros(5, int), np.ones(5, int), W, H)
    report = fr.FramingReport()
    schema, batches = fr.frame_events(table.schema, table.to_batches(max_chunksize=1), fr.Framing(window_us=10_000), report)
    frames = pa.Table.from_batches(list(batches), schema=schema)
    assert report.late == 1 and counts_of(frames).sum() == 4 and report.framed + report.dropped == 5


def test_saturation_holds_at_65535_and_is_counted():
    n = 70_000
    t, x, y, p = np.zeros(n, np.int64), np.full(n, 3), np.full(n, 2), np.ones(n)
    out = np.zeros((1, 2, H, W), np.uint16)
    inside, saturated, *_ = kernels.count_events(t, x, y, p, 0, 10_000, 0, out)
    assert out[0, 1, 2, 3] == 65535 and inside == n and saturated == n - 65535


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), first=st.integers(-2, 5), zeroed=st.integers(0, 6))
def test_count_events_counts_each_event_in_its_window_and_classifies_the_rest(seed, first, zeroed):
    t, x, y, p = random_events(seed, n=3000, span=120_000, start=-20_000)
    out = np.full((6, 2, H, W), 7, np.uint16)  # frames from `zeroed` on hold garbage until counted into
    out[:zeroed] = 0
    inside, saturated, before, late, beyond, k_max, now_zeroed, _, _ = kernels.count_events(t, x, y, p, 0, 10_000, first, out, zeroed)
    k = t // 10_000
    j = k - first
    keep = (k >= 0) & (j >= 0) & (j < 6)
    expected = np.zeros_like(out)
    np.add.at(expected, (j[keep], p[keep], y[keep], x[keep]), 1)
    assert np.array_equal(out[:now_zeroed], expected[:now_zeroed]) and not expected[now_zeroed:].any()
    assert (inside, saturated, before, late, beyond, k_max) == (keep.sum(), 0, (k < 0).sum(), ((k >= 0) & (j < 0)).sum(), (j >= 6).sum(), k.max())


@pytest.mark.parametrize("accumulate", [False, True])
def test_a_long_trial_is_framed_in_pieces_equal_to_the_whole(monkeypatch, accumulate):
    t, x, y, p = random_events(9, n=4000, span=300_000)
    order = np.random.default_rng(9).permutation(len(t))  # a trial's events in any order
    trial = {"trial": "a", "t0": 0, "events": (t[order], x[order], y[order], p[order]), "force": (np.array([], np.int64), np.array([]))}
    whole = counts_of(fr.frame_recordings(recordings([trial]), 5_000, accumulate=accumulate, pad_to=70))
    monkeypatch.setattr(fr, "BUFFER_CELLS", 2 * H * W * 7)  # seven frames a piece
    pieces = fr.frame_recordings(recordings([trial]), 5_000, accumulate=accumulate, pad_to=70)
    expected = fr.count_frames(t, x, y, p, 5_000, 70, H, W)
    if accumulate:  # the padding frames add no events: they hold the last accumulated counts
        expected = np.cumsum(expected, axis=0).astype(expected.dtype)
    assert np.array_equal(counts_of(pieces), whole) and np.array_equal(whole, expected)
    assert pieces.column("frame").to_pylist() == list(range(70))


def test_sliced_recordings_frame_like_whole_ones():
    trials = [{"trial": f"g{i}", "t0": 0, "events": random_events(i, n=300, span=50_000), "force": (np.arange(0, 50_001, 2000), np.zeros(26))}
              for i in range(4)]
    table = recordings(trials)
    whole = fr.frame_recordings(table, 10_000)
    tail = fr.frame_recordings(table.slice(2), 10_000)
    assert tail.column("trial").unique().to_pylist() == ["g2", "g3"]
    assert np.array_equal(counts_of(tail), counts_of(whole)[-len(counts_of(tail)):])


def test_last_partial_window_kept_or_dropped_and_counted():
    force_t, force_v = np.arange(0, 25_001, 2000) * 1, np.ones(13)  # covers [0, 26 ms)
    t = np.array([1_000, 21_000, 25_500])
    trial = {"trial": "a", "t0": 0, "events": (t, np.zeros(3), np.zeros(3), np.zeros(3)), "force": (force_t, force_v)}
    kept = fr.frame_recordings(recordings([trial]), 10_000)
    report = fr.FramingReport()
    dropped = fr.frame_recordings(recordings([trial]), 10_000, report=report, partial="drop")
    assert kept.num_rows == 3 and dropped.num_rows == 2
    assert report.after_end == 2 and counts_of(dropped).sum() == 1


def test_accumulate_counts_from_the_trial_start():
    t = np.array([1_000, 12_000, 13_000, 35_000])
    trial = {"trial": "a", "t0": 0, "events": (t, np.zeros(4), np.zeros(4), np.ones(4)), "force": (np.arange(0, 38_001, 2000), np.zeros(20))}
    frames = fr.frame_recordings(recordings([trial]), 10_000, accumulate=True)
    assert counts_of(frames)[:, 1, 0, 0].tolist() == [1, 3, 3, 4]


def test_float32_divides_each_channel_by_its_largest_count_and_records_the_scale():
    t = np.array([1_000, 2_000, 3_000, 12_000])
    p = np.array([1, 1, 0, 1])
    trial = {"trial": "a", "t0": 0, "events": (t, np.zeros(4), np.zeros(4), p), "force": (np.arange(0, 18_001, 2000), np.zeros(10))}
    frames = fr.frame_recordings(recordings([trial]), 10_000, dtype="float32")
    counts = counts_of(frames)
    assert counts.dtype == np.float32 and counts[0, 1, 0, 0] == 1.0 and counts[1, 1, 0, 0] == 0.5 and counts[0, 0, 0, 0] == 1.0
    assert sch.get_meta(frames.schema, "neurotac:scale") == [1.0, 2.0]


# ---------------------------------------------------------------- force and phases


def test_force_per_frame_end_mean_median():
    force_t = np.arange(0, 30_001, 2_000)
    force_v = force_t / 1000.0  # 1 N per ms
    end = fr.frame_force(force_t, force_v, 10_000, 4, "end")
    mean = fr.frame_force(force_t, force_v, 10_000, 4, "mean")
    median = fr.frame_force(force_t, force_v, 10_000, 4, "median")
    assert end.tolist() == [10.0, 20.0, 30.0, 30.0]  # the last one holds the trace's last sample
    assert mean[:3].tolist() == [4.0, 14.0, 24.0] and median[:3].tolist() == [4.0, 14.0, 24.0]


def test_phases_follow_rise_plateau_and_fall_of_the_force():
    force_t, force_v = trapezoid_force()
    frames = fr.frame_recordings(
        recordings([{"trial": "a", "t0": 0, "events": ([5], [0], [0], [0]), "force": (force_t, force_v)}]), 10_000, pad_to=25
    )
    phase = frames.column("phase").to_pylist()
    assert phase[0] == "none" and phase[3] == "grasping" and phase[10] == "holding" and phase[15] == "releasing"
    assert phase[-1] == "none" and phase.index("holding") < phase.index("releasing")
    assert frames.column("force").null_count == 0


def test_a_grasp_that_relaxes_while_held_keeps_holding_until_its_final_fall():
    """ch3's foam loses ~15% of its force while held (viscoelastic), which left the plateau band 30
    frames before the gripper opened: holding must last until the fall itself, and a fast fall after
    a flat plateau keeps the plateau rule's frames exactly."""
    rng = np.random.default_rng(0)
    rise, hold, fall, after = np.linspace(0, 2.1, 10), np.linspace(2.1, 1.75, 60), 1.75 * np.exp(-np.arange(1, 16) / 5), np.zeros(10)
    force = np.concatenate([np.zeros(5), rise, hold, fall, after]) + rng.normal(0, 0.01, 100)
    labels = list(ph.detect_phases(force))
    assert labels.index("releasing") in (75, 76, 77), labels.index("releasing")  # the fall starts at frame 75
    assert set(labels[labels.index("holding"):75]) == {"holding"}
    flat = np.concatenate([np.zeros(5), rise, np.full(30, 2.0), [1.0, 0.1], np.zeros(10)])
    assert list(ph.detect_phases(flat)).index("releasing") == 45  # the first frame that reads below the plateau


def test_phases_given_as_frame_ranges():
    assert ph.parse_ranges("0-21,22-121,122-143") == [(0, 21), (22, 121), (122, 143)]
    labels = ph.phases_from_ranges(6, [(0, 1), (2, 3), (4, 4)])
    assert labels.tolist() == ["grasping", "grasping", "holding", "holding", "releasing", "none"]
    for bad in ("0-21,22-121", "5-2,3-4,5-6", "0-5,5-6,7-8", "a-b,1-2,3-4"):
        with pytest.raises(NeurotacError):
            ph.parse_ranges(bad)


# ---------------------------------------------------------------- real recordings vs tonic


REAL_FILES = [
    "davis240c_rotdisk.aedat", "davis346_aestream.aedat4", "dvxplorer_tonic.aedat4", "prophesee_vga_faery.evt2.raw",
    "prophesee_hd_expelliarmus.evt3.raw", "atis_ncars_loris.dat", "atis_ncars_loris.es",
]


@pytest.mark.parametrize("name", REAL_FILES)
@pytest.mark.parametrize("window", [7_000, 10_000])  # the thesis windows
def test_frames_of_real_recordings_equal_tonic_to_frame(name, window, real_data):
    tonic = pytest.importorskip("tonic.transforms")
    from neurotac_cli.io import read_events_table

    path = real_data / name
    if not path.is_file():
        pytest.skip(f"{name} not in {real_data}")
    table = read_events_table(str(path))
    width, height = sch.sensor_of(table.schema)
    events = np.zeros(table.num_rows, dtype=[("x", "<i8"), ("y", "<i8"), ("t", "<i8"), ("p", "<i8")])
    for name_ in "xytp":
        events[name_] = table.column(name_).to_numpy()
    span = int(events["t"][-1] - events["t"][0])
    for keep in (False, True):
        ours = counts_of(fr.frames_from_events_table(table, window, partial="keep" if keep else "drop"))
        theirs = tonic.ToFrame(sensor_size=(width, height, 2), time_window=window, include_incomplete=keep)(events)
        if not keep and span < window:
            assert len(ours) == 0 and len(theirs) == 1  # tonic keeps one incomplete frame here (documented)
            continue
        if keep and span % window == 0:
            theirs_sum = theirs.sum()  # tonic drops the events at the last instant here (documented)
            assert ours[: len(theirs)].sum() >= theirs_sum
            continue
        assert ours.shape == theirs.shape
        assert np.array_equal(ours.astype(np.int64), theirs.astype(np.int64))


# ---------------------------------------------------------------- command line


def run(args, stdin=None):
    return subprocess.run(["neurotac", *args],
                          input=stdin, capture_output=True, env={**os.environ, "PATH": f"{os.path.dirname(sys.executable)}:{os.environ['PATH']}"})


def test_frame_command_streams_an_events_table_and_records_history(tmp_path):
    t, x, y, p = random_events(1, n=3000, span=100_000, start=5_000_000)
    source = tmp_path / "ev.arrows"
    tables.write(str(source), sch.events_table(t, x, y, p, W, H))
    done = run(["frame", "--window", "10ms", str(source), "-o", str(tmp_path / "f.parquet")])
    assert done.returncode == 0, done.stderr
    frames = tables.read([str(tmp_path / "f.parquet")], kind="frames")
    assert counts_of(frames).sum() == 3000 and frames.num_rows == 10
    step = sch.get_meta(frames.schema, sch.HISTORY)[-1]
    assert step["command"] == "frame" and step["args"]["window_us"] == 10_000
    assert frames.column("trial").unique().to_pylist() == ["events"]  # no camera file recorded


def test_frame_names_the_trial_after_the_imported_camera_file(tmp_path):
    camera = tmp_path / "grasp-07.csv"
    camera.write_text("t_us,x,y,p\n" + "".join(f"{1000 * i},{i % 20},{i % 15},{i % 2}\n" for i in range(200)))
    imported = tmp_path / "e.arrows"
    assert run(["import", str(camera), "--sensor", "20x15", "-o", str(imported)]).returncode == 0
    done = run(["frame", "--window", "10ms", str(imported), "-o", str(tmp_path / "f.arrows")])
    assert done.returncode == 0, done.stderr
    assert tables.read([str(tmp_path / "f.arrows")], kind="frames").column("trial").unique().to_pylist() == ["grasp-07"]
    done = run(["frame", "--window", "10ms", "--trial", "g1", str(imported), "-o", str(tmp_path / "g.arrows")])
    assert tables.read([str(tmp_path / "g.arrows")], kind="frames").column("trial").unique().to_pylist() == ["g1"]


def test_frame_command_rejects_a_bare_number_and_bad_ranges(tmp_path):
    assert run(["frame", "--window", "10"]).returncode == 2
    t, x, y, p = random_events(1)
    source = tmp_path / "ev.arrows"
    tables.write(str(source), sch.events_table(t, x, y, p, W, H))
    done = run(["frame", "--window", "10ms", "--phases", "1-2", str(source)])
    assert done.returncode == 2 and done.stderr.decode().count("\n") == 1 and "phases" in done.stderr.decode()


@pytest.mark.parametrize("scale", ["nan", "inf", "1e-45", "1e-40", "1e39", "0", "-1", "40,nan"])
def test_a_scale_that_is_not_finite_positive_or_that_overflows_float32_is_a_one_line_usage_error(scale, tmp_path):
    source = tmp_path / "rec.arrows"
    trial = {"trial": "a", "t0": 0, "events": (np.array([1_000, 12_000]), np.zeros(2), np.zeros(2), np.array([1, 0])),
             "force": (np.arange(0, 18_001, 2000), np.zeros(10))}
    tables.write(str(source), recordings([trial]))
    done = run(["frame", "--window", "10ms", "--dtype", "float32", f"--scale={scale}", str(source)])
    assert done.returncode == 2 and b"RuntimeWarning" not in done.stderr and b"scale" in done.stderr, done.stderr
    assert done.stdout == b""


def test_events_table_options_are_refused_with_a_recordings_table_and_an_empty_trial_id(tmp_path):
    source = tmp_path / "rec.arrows"
    trial = {"trial": "a", "t0": 0, "events": (np.array([1_000, 12_000]), np.zeros(2), np.zeros(2), np.array([1, 0])),
             "force": (np.arange(0, 18_001, 2000), np.zeros(10))}
    tables.write(str(source), recordings([trial]))
    for options, named in ((["--start", "1s"], "--start is"), (["--trial", "X"], "--trial is"), (["--sort"], "--sort is")):
        done = run(["frame", "--window", "10ms", *options, str(source)])
        message = done.stderr.decode()
        assert done.returncode == 2 and message.count("\n") == 1 and named in message, message
    t, x, y, p = random_events(1)
    events = tmp_path / "ev.arrows"
    tables.write(str(events), sch.events_table(t, x, y, p, W, H))
    done = run(["frame", "--window", "10ms", "--trial", "", str(events)])
    assert done.returncode == 2 and b"trial id cannot be empty" in done.stderr


def test_frame_command_refuses_a_window_that_is_not_positive():
    for window in ("0ms", "-5ms"):
        done = run(["frame", "--window", window])
        assert done.returncode == 2 and "positive duration" in done.stderr.decode()


# ---------------------------------------------------------------- bounded work


def test_a_clock_jump_is_refused_before_its_frames_are_written_with_where_it_is(tmp_path):
    t = np.array([0, 5_000, 12_000, 10**12, 10**12 + 10])  # a clock jump of 278 hours at event 3
    source = tmp_path / "ev.arrows"
    tables.write(str(source), sch.events_table(t, np.zeros(5, int), np.zeros(5, int), np.zeros(5, int), W, H))
    done = run(["frame", "--window", "10ms", str(source), "-o", str(tmp_path / "f.arrows")])
    message = done.stderr.decode()
    assert done.returncode == 1 and message.count("\n") == 1, message
    assert "frames to write, more than --max-frames 1,000,000" in message
    assert "a gap of 277.8 hours at event 3, from t = 12000 to 1000000000000 µs" in message
    assert not (tmp_path / "f.arrows").exists()


def test_a_window_too_small_for_the_span_is_refused_and_the_limit_can_be_raised():
    t = np.arange(0, 50_000, 10)
    table = sch.events_table(t, np.zeros(len(t), int), np.zeros(len(t), int), np.zeros(len(t), int), W, H)
    with pytest.raises(NeurotacError, match=r"at least 49,991 frames to write, more than --max-frames 1,000 \(the events span 50.0 ms: a window of 1 µs is too small"):
        fr.frames_from_events_table(table, 1, max_frames=1_000)
    assert fr.frames_from_events_table(table, 1, max_frames=50_000).num_rows == 49_991


def test_a_long_gap_within_the_limit_is_reported_with_where_it_is():
    t = np.array([0, 5_000, 20_000_000, 20_005_000, 20_010_000])
    table = sch.events_table(t, np.zeros(5, int), np.zeros(5, int), np.zeros(5, int), W, H)
    report = fr.FramingReport()
    frames = fr.frames_from_events_table(table, 10_000, report=report)
    assert frames.num_rows == 2_002 and counts_of(frames).sum() == 5
    assert report.notes == ["a gap of 20.0 s at event 2 (from t = 5000 to 20000000 µs): 1,999 empty frames in the middle of the stream"]
    coarse = fr.FramingReport()
    fr.frames_from_events_table(table, 100_000, report=coarse)  # the same gap is 200 windows of 100 ms: not reported
    assert coarse.notes == []


def test_recordings_past_the_frame_limit_are_refused_naming_the_trial():
    far = {"trial": "late", "t0": 0, "events": (np.array([0, 10**11]), np.zeros(2), np.zeros(2), np.zeros(2)), "force": (np.array([], np.int64), np.array([]))}
    near = {"trial": "ok", "t0": 0, "events": random_events(1, n=50), "force": (np.array([], np.int64), np.array([]))}
    with pytest.raises(NeurotacError, match=r"^10,000,\d{3} frames to write, .*\(trial late: a gap of 27.8 hours at event 1, from t = 0 to 100000000000 µs"):
        fr.frame_recordings(recordings([near, far]), 10_000)
    logged = {"trial": "logged", "t0": 0, "events": random_events(2, n=50), "force": (np.arange(0, 3_000_000_000, 2_000), np.zeros(1_500_000))}
    with pytest.raises(NeurotacError, match=r"\(trial logged: the force samples span 50.0 min: a window of 1.0 ms is too small for it"):
        fr.frame_recordings(recordings([logged]), 1_000)


def test_float32_without_a_scale_spills_to_disk_and_equals_the_counts_divided_by_their_maxima(monkeypatch):
    monkeypatch.setattr(fr, "BUFFER_CELLS", 2 * H * W * 3)
    t, x, y, p = random_events(8, n=4000, span=300_000)
    table = sch.events_table(t, x, y, p, W, H)
    counts = counts_of(fr.frames_from_events_table(table, 5_000))
    report = fr.FramingReport()
    scaled = fr.frames_from_events_table(table, 5_000, report=report, dtype="float32")
    peaks = counts.max(axis=(0, 2, 3)).astype(np.float32)
    assert report.scale == [float(v) for v in peaks] and sch.get_meta(scaled.schema, "neurotac:scale") == report.scale
    assert np.array_equal(counts_of(scaled), counts.astype(np.float32) / peaks[None, :, None, None])


# ---------------------------------------------------------------- live


def test_a_frame_leaves_through_a_pipe_as_soon_as_its_window_has_closed():
    """The input stays open: the first frame must arrive once an event past its window has, not at the end."""
    import pyarrow.ipc as ipc

    schema = sch.events_schema(W, H)
    process = subprocess.Popen(["neurotac", "frame", "--window", "10ms"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        writer = ipc.new_stream(process.stdin, schema)
        writer.write_batch(sch.events_batch(np.array([0, 4_000]), np.array([1, 2]), np.array([1, 2]), np.array([0, 1]), schema))
        writer.write_batch(sch.events_batch(np.array([12_000]), np.array([3]), np.array([3]), np.array([1]), schema))
        process.stdin.flush()
        reader = ipc.open_stream(process.stdout)  # blocks until frame's schema has arrived
        first = reader.read_next_batch()  # ... and its first frame, while its input is still open
        assert first.column("frame").to_pylist() == [0] and counts_of(pa.Table.from_batches([first])).sum() == 2
        assert process.poll() is None
        writer.close()
        process.stdin.close()
        rest = reader.read_all()
        assert rest.column("frame").to_pylist() == [1] and process.wait(timeout=30) == 0
    finally:
        process.kill()


def test_the_report_counts_a_streams_small_drops_and_warns_on_large_ones():
    from neurotac_cli.ops.frame import FramingReport

    small = FramingReport(events=10_000, late=5)
    assert small.messages() == ["5 of 10000 events lie outside the frames (before start 0, after end 0, out of time order 5)"]
    assert small.messages(lead_in_expected=True) == []  # a synced trial's lead-in is dropped by design
    large = FramingReport(events=100, after_end=50)
    assert [line.startswith("warning: 50 of 100 events") for line in large.messages()] == [True]


def test_a_session_framed_as_one_grasp_and_a_force_log_with_a_hole_are_named():
    t_ms = np.arange(0, 1_001, 2)
    force = np.where((t_ms % 500 > 100) & (t_ms % 500 < 300), 2.0, 0.0)  # two grasps with a rest between
    events = random_events(1, span=1_000_000)
    table = recordings([{"trial": "s", "t0": 0, "events": events, "force": (t_ms * 1000, force)}])
    report = fr.FramingReport()
    fr.frame_recordings(table, 10_000, report=report)
    assert any("comes back to rest between grasps in 1 trial (s)" in note for note in report.notes)
    report = fr.FramingReport()
    fr.frame_recordings(table, 10_000, report=report, phases="session")
    assert not any("rest between grasps" in note for note in report.notes)
    holed = (t_ms < 300) | (t_ms > 700)
    table = recordings([{"trial": "s", "t0": 0, "events": events, "force": (t_ms[holed] * 1000, force[holed])}])
    report = fr.FramingReport()
    fr.frame_recordings(table, 10_000, report=report, phases="session")
    assert any("no sample for a stretch" in note and "0.404 s from 0.298 s" in note for note in report.notes)
    report = fr.FramingReport()
    fr.frame_recordings(recordings([{"trial": "a", "t0": 0, "events": random_events(2), "force": trapezoid_force()}]), 10_000, report=report)
    assert not any("rest between grasps" in note or "no sample" in note for note in report.notes)


def test_a_true_slip_at_rest_outside_every_grasp_is_named():
    t_ms = np.arange(0, 1_001, 2)
    force = np.where((t_ms % 500 > 100) & (t_ms % 500 < 300), 2.0, 0.0)
    table = recordings([{"trial": "s", "t0": 0, "events": random_events(1, span=1_000_000), "force": (t_ms * 1000, force)}])
    report = fr.FramingReport()
    fr.frame_recordings(table, 10_000, report=report, phases="session", slips={"s": [(20_000, 60_000), (150_000, 200_000)]})
    assert any("1 true slip lies at rest" in note for note in report.notes)


def test_frames_before_a_force_log_that_starts_late_are_named():
    t_ms = np.arange(0, 1_001, 2)
    late = t_ms >= 400  # the logger started 0.4 s after the sync instant
    table = recordings([{"trial": "s", "t0": 0, "events": random_events(1, span=1_000_000), "force": (t_ms[late] * 1000, np.zeros(late.sum()))}])
    report = fr.FramingReport()
    frames = fr.frame_recordings(table, 10_000, report=report)
    assert np.isnan(frames.column("force").to_numpy(zero_copy_only=False)).sum() == 39
    assert any("39 frames of 1 trial come before the force log's first sample" in note for note in report.notes)


def test_a_live_stream_runs_past_the_frame_limit_while_a_jump_in_it_is_refused():
    """A sensor runs for hours: a million 10 ms windows are 2.8 of them. Only frames opened at once count."""
    t = np.arange(0, 200_000, 100)  # 200 ms of events, 2,000 batches of one event: 200 frames of 1 ms
    events = sch.events_table(t, np.zeros(len(t), int), np.zeros(len(t), int), np.zeros(len(t), int), W, H)
    framing = fr.Framing(window_us=1_000, max_frames=50)
    schema, batches = fr.frame_events(events.schema, events.to_batches(max_chunksize=1), framing, fr.FramingReport())
    assert sum(batch.num_rows for batch in batches) == 200
    jump = sch.events_table(np.append(t, 10**9), np.zeros(len(t) + 1, int), np.zeros(len(t) + 1, int), np.zeros(len(t) + 1, int), W, H)
    schema, batches = fr.frame_events(jump.schema, jump.to_batches(max_chunksize=1), framing, fr.FramingReport())
    with pytest.raises(NeurotacError, match="frames to write, more than --max-frames 50"):
        list(batches)
