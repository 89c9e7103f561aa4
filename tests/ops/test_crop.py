"""crop: boxes, centres, pooling on frames, recordings and events; what is cut is counted."""

import os
import select
import subprocess
import sys

import numpy as np
import pyarrow as pa
import pytest
from hypothesis import given, settings, strategies as st

from neurotac_cli import schema as sch, tables
from neurotac_cli.errors import NeurotacError
from neurotac_cli.ops import crop as cr
from neurotac_cli.ops import frame as fr

W, H = 24, 18


def random_events(seed, n=1500, span=60_000):
    rng = np.random.default_rng(seed)
    return np.sort(rng.integers(0, span, n)), rng.integers(0, W, n), rng.integers(0, H, n), rng.integers(0, 2, n)


def frames_of(seed):
    t, x, y, p = random_events(seed)
    trial = {"trial": "a", "t0": 0, "events": (t, x, y, p), "force": (np.arange(0, 60_001, 2000), np.zeros(31))}
    return fr.frame_recordings(sch.recordings_table([trial], W, H), 10_000), (t, x, y, p)


boxes = st.tuples(st.integers(0, W - 1), st.integers(0, H - 1)).flatmap(
    lambda corner: st.tuples(st.just(corner[0]), st.just(corner[1]), st.integers(1, W - corner[0]), st.integers(1, H - corner[1]))
)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), box=boxes)
def test_cropped_frames_hold_the_events_inside_the_box_and_the_rest_is_counted(seed, box):
    frames, (t, x, y, p) = frames_of(seed)
    report = cr.CropReport()
    cropped = cr.crop_table(frames, cr.CropSpec(box=box), report)
    x0, y0, w, h = box
    inside = (x >= x0) & (x < x0 + w) & (y >= y0) & (y < y0 + h)
    counts = sch.counts_numpy(cropped.column("counts"))
    assert counts.shape[2:] == (h, w) and sch.sensor_of(cropped.schema) == (w, h)
    assert counts.sum() == inside.sum() == report.kept and report.cut == len(t) - inside.sum()


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), box=boxes)
def test_cropped_events_and_recordings_keep_the_events_inside_the_box(seed, box):
    t, x, y, p = random_events(seed)
    x0, y0, w, h = box
    inside = (x >= x0) & (x < x0 + w) & (y >= y0) & (y < y0 + h)
    report = cr.CropReport()
    events = cr.crop_table(sch.events_table(t, x, y, p, W, H), cr.CropSpec(box=box), report)
    assert events.num_rows == inside.sum() == report.kept and report.cut == (~inside).sum()
    assert (events.column("x").to_numpy() == x[inside] - x0).all() and sch.sensor_of(events.schema) == (w, h)
    half = len(t) // 2
    trials = [
        {"trial": "a", "t0": 0, "events": (t[:half], x[:half], y[:half], p[:half]), "force": ([0], [0])},
        {"trial": "b", "t0": 0, "events": (t[half:], x[half:], y[half:], p[half:]), "force": ([0], [0])},
    ]
    report = cr.CropReport()
    cropped = cr.crop_table(sch.recordings_table(trials, W, H), cr.CropSpec(box=box), report)
    lengths = [len(row) for row in cropped.column("events").to_pylist()]
    assert lengths == [inside[:half].sum(), inside[half:].sum()] and report.cut == (~inside).sum()


def test_pooling_sums_neighbours_and_all_keeps_one_pixel_per_channel():
    frames, (t, x, y, p) = frames_of(1)
    pooled = cr.crop_table(frames, cr.CropSpec(pool=(2, 3)))
    counts = sch.counts_numpy(frames.column("counts"))
    pooled_counts = sch.counts_numpy(pooled.column("counts"))
    assert pooled_counts.shape[2:] == (H // 3, W // 2) and pooled_counts.sum() == counts.sum()
    assert pooled_counts[0, 1, 0, 0] == counts[0, 1, :3, :2].sum()
    everything = sch.counts_numpy(cr.crop_table(frames, cr.CropSpec(pool="all")).column("counts"))
    assert everything.shape[1:] == (2, 1, 1)
    assert everything[:, :, 0, 0].tolist() == counts.sum(axis=(2, 3)).tolist()
    events = cr.crop_table(sch.events_table(t, x, y, p, W, H), cr.CropSpec(box=(0, 0, 20, 18), pool=(2, 2)))
    assert sch.sensor_of(events.schema) == (10, 9) and events.column("x").to_numpy().max() <= 9
    with pytest.raises(NeurotacError, match="divide evenly"):
        cr.crop_table(frames, cr.CropSpec(pool=(5, 5)))


def test_pooled_counts_past_uint16_widen_to_uint32_instead_of_clipping():
    counts = np.full((1, 2, 2, 2), 30_000, dtype=np.uint16)
    table = pa.Table.from_batches([fr._frames_batch(sch.frames_schema(2, 2), "a", counts, None, None, {}, (), 10_000, None)])
    report = cr.CropReport()
    pooled = cr.crop_table(table, cr.CropSpec(pool="all"), report)
    values = sch.counts_numpy(pooled.column("counts"))
    assert values.dtype == np.uint32 and values.max() == 120_000 and report.as_dict()["widened_to"] == "uint32"
    small = cr.crop_table(pa.Table.from_batches([fr._frames_batch(sch.frames_schema(2, 2), "a", counts // 100, None, None, {}, (), 10_000, None)]),
                          cr.CropSpec(pool="all"))
    assert sch.counts_numpy(small.column("counts")).dtype == np.uint16


def test_auto_centre_is_the_largest_contact_area():
    activity = np.random.default_rng(0).poisson(0.5, (180, 240)).astype(float)
    activity[50:90, 150:200] += 40  # the contact
    activity[10:14, 10:14] += 40  # a smaller blob
    activity[170, 5] += 5000  # a hot pixel
    cx, cy = cr.contact_center(activity)
    assert abs(cx - 174.5) <= 1 and abs(cy - 69.5) <= 1


def test_auto_box_moves_inside_the_sensor_and_given_box_past_it_is_refused():
    activity = np.zeros((H, W))
    activity[0:3, 0:3] = 10
    report = cr.CropReport()
    box = cr.resolve_box(cr.CropSpec(size=(10, 10), center="auto"), (W, H), activity, report)
    assert box == (0, 0, 10, 10) and max(report.center) <= 2 and report.center_from == "auto"
    with pytest.raises(NeurotacError, match="reaches past"):
        cr.resolve_box(cr.CropSpec(size=(10, 10), center=(2, 2)), (W, H))
    with pytest.raises(NeurotacError, match="reaches past"):
        cr.resolve_box(cr.CropSpec(box=(20, 0, 10, 10)), (W, H))
    with pytest.raises(NeurotacError):
        cr.CropSpec(box=(0, 0, 5, 5), size=(5, 5), center="auto")


def test_crop_command_records_the_auto_centre_in_history(tmp_path):
    frames, _ = frames_of(2)
    source = tmp_path / "f.arrows"
    tables.write(str(source), frames)
    env = {**os.environ, "PATH": f"{os.path.dirname(sys.executable)}:{os.environ['PATH']}"}
    done = subprocess.run(["neurotac", "crop", "--size", "10x8", "--center", "auto", str(source), "-o", str(tmp_path / "c.arrows")],
                          capture_output=True, env=env)
    assert done.returncode == 0, done.stderr
    cropped = tables.read([str(tmp_path / "c.arrows")], kind="frames")
    step = sch.get_meta(cropped.schema, sch.HISTORY)[-1]
    assert step["command"] == "crop" and len(step["args"]["report"]["center"]) == 2
    x, y = step["args"]["report"]["center"]  # said on stderr, for a live stream's fixed box
    assert f"the contact's centre {x},{y} (box ".encode() in done.stderr and f"--center {x},{y})".encode() in done.stderr
    assert step["args"]["report"]["kept"] + step["args"]["report"]["cut"] == sch.counts_numpy(frames.column("counts")).sum()
    done = subprocess.run(["neurotac", "crop", "--box", "0,0,4,4", "--warn-above", "0.5", str(source), "-o", str(tmp_path / "d.arrows")],
                          capture_output=True, env=env)
    assert done.returncode == 0 and b"warning: the crop cut away" in done.stderr


def test_a_box_past_a_sensor_guessed_from_the_events_says_how_to_give_the_size(tmp_path):
    t, x, y, p = np.arange(50), np.arange(50) % 20, np.arange(50) % 15, np.arange(50) % 2
    events = sch.events_table(t, x, y, p, 20, 15)
    events = events.replace_schema_metadata(sch.set_meta(events.schema, **{"source": {"format": "dat", "sensor_from": "events"}}).metadata)
    source = tmp_path / "e.arrows"
    tables.write(str(source), events)
    env = {**os.environ, "PATH": f"{os.path.dirname(sys.executable)}:{os.environ['PATH']}"}
    for args, said in [(["--size", "32x32", "--center", "10,7"], "larger than the 20x15 input"),
                       (["--pool", "3x3"], "cannot pool 20x15 by 3x3")]:  # the pool of a whole sensor that is a guess
        done = subprocess.run(["neurotac", "crop", *args, str(source)], capture_output=True, env=env)
        lines = done.stderr.decode().strip().splitlines()
        assert done.returncode == 1 and len(lines) == 1
        assert said in lines[0] and "20x15 is the extent of the events" in lines[0] and "give it with --sensor WxH" in lines[0]
    own = subprocess.run(["neurotac", "crop", "--size", "10x10", "--center", "10,7", "--pool", "3x3", str(source)], capture_output=True, env=env)
    assert own.returncode == 1 and b"cannot pool 10x10" in own.stderr and b"extent" not in own.stderr  # the user's own box


# ---------------------------------------------------------------- streams


@pytest.mark.parametrize("spec", [cr.CropSpec(box=(2, 3, 12, 10)), cr.CropSpec(size=(12, 10), center=(10, 9), pool=(2, 2)),
                                  cr.CropSpec(pool="all")])
def test_a_streamed_crop_equals_the_crop_of_the_whole_table(spec):
    frames, events = frames_of(3)
    small = frames.to_batches(max_chunksize=2)  # a stream arrives a few frames at a time
    schema, batches, report = cr.crop(frames.schema, iter(small), spec)
    assert report.streamed and report.kept == 0  # nothing is read before the first batch is asked for
    streamed = pa.Table.from_batches(list(batches), schema=schema)
    whole_report = cr.CropReport()
    whole = cr.crop_table(frames, spec, whole_report)
    assert sch.frames_shape(streamed.schema) == sch.frames_shape(whole.schema)
    assert np.array_equal(sch.counts_numpy(streamed.column("counts")), sch.counts_numpy(whole.column("counts")))
    assert streamed.drop_columns(["counts"]).equals(whole.drop_columns(["counts"]))
    assert (report.kept, report.cut) == (whole_report.kept, whole_report.cut) and report.kept + report.cut == len(events[0])
    recordings = sch.recordings_table([{"trial": "a", "t0": 0, "events": events, "force": (np.zeros(1), np.zeros(1))}], W, H)
    schema, batches, _ = cr.crop(recordings.schema, iter(recordings.to_batches()), spec)
    assert pa.Table.from_batches(list(batches), schema=schema).equals(cr.crop_table(recordings, spec), check_metadata=True)


def test_a_frame_leaves_crop_through_a_pipe_before_its_input_ends():
    """The input stays open: the first cropped frame must arrive while crop still waits for more."""
    import pyarrow.ipc as ipc

    frames, _ = frames_of(4)
    process = subprocess.Popen(["neurotac", "crop", "--size", "12x10", "--center", "10,9", "--pool", "2x2"],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        writer = ipc.new_stream(process.stdin, frames.schema)
        writer.write_batch(frames.slice(0, 1).to_batches()[0])
        process.stdin.flush()
        assert select.select([process.stdout], [], [], 30)[0], "crop held its first frame back"
        reader = ipc.open_stream(process.stdout)
        first = reader.read_next_batch()  # arrives while crop's input is still open
        assert first.column("frame").to_pylist() == [0] and sch.frames_shape(reader.schema) == (5, 6)
        assert process.poll() is None
        writer.write_batch(frames.slice(1).to_batches()[0])
        writer.close()
        process.stdin.close()
        assert reader.read_all().num_rows == frames.num_rows - 1 and process.wait(timeout=30) == 0
        assert b"cut " in process.stderr.read()
    finally:
        process.kill()


def test_the_fixed_centre_crop_suggests_for_a_contact_near_the_edge_gives_the_same_box():
    report = cr.CropReport(box=[0, 33, 115, 115], center=[14, 90], center_from="auto")
    (line,) = report.messages(1.0)
    assert line.endswith("--center 57,90)")
    assert cr.resolve_box(cr.CropSpec(size=(115, 115), center=(57, 90)), (240, 180)) == (0, 33, 115, 115)
