import json
import subprocess
import sys

import numpy as np
import pyarrow as pa
import pytest

from neurotac_cli import model as models
from neurotac_cli import schema as sch
from neurotac_cli import tables
from neurotac_cli.model.predict import EVENTS_MARGIN
from tests.model.helpers import tiny_frames, write_stream


def run(args, stdin):
    code = "from neurotac_cli.cli import main; main()"
    return subprocess.run([sys.executable, "-c", code, *args], stdin=stdin, capture_output=True)


@pytest.mark.parametrize("name", ["deform-gru", "convlstm", "tdnn", "gp", "lstm", "cnnlstm"])
def test_streaming_in_pieces_equals_eval(name):
    frames = tiny_frames(trials=4)
    options = {"epochs": 2} if name != "gp" else {"restarts": 0, "max_points": 100}
    model = models.train(frames, models.make_spec(name, **options), seed=0)
    whole = models.predict_table(model, frames).column("force_pred").to_numpy()
    # frames arriving one or a few at a time, trials interleaved
    order = np.argsort(np.tile(np.arange(12), 4), kind="stable")
    shuffled = frames.take(pa.array(order))
    schema, batches = models.stream(model, shuffled.schema, iter(shuffled.to_batches(max_chunksize=3)))
    streamed = pa.Table.from_batches(list(batches), schema=schema)
    back = {(t, f): v for t, f, v in zip(streamed.column("trial").to_pylist(), streamed.column("frame").to_pylist(),
                                          streamed.column("force_pred").to_pylist())}
    keys = zip(frames.column("trial").to_pylist(), frames.column("frame").to_pylist())
    np.testing.assert_allclose([back[k] for k in keys], whole, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("order", [[0, 1, 3, 2], [3, 2, 1, 0]])
def test_a_trial_s_frames_out_of_order_are_refused_by_the_stream(order):
    """Out of order, the carried state gave other estimates than `eval`, which sorts, without a word."""
    from neurotac_cli.errors import InputError

    frames = tiny_frames(trials=1).slice(0, 4)
    model = models.train(tiny_frames(trials=2), models.make_spec("tdnn", epochs=1), seed=0)
    shuffled = frames.take(pa.array(order))
    schema, batches = models.stream(model, shuffled.schema, iter(shuffled.to_batches(max_chunksize=1)))
    with pytest.raises(InputError, match=r"frame \d+ comes after frame \d+; a stream reads each trial's frames in the order"):
        list(batches)


def test_predict_command_streams_equal_to_eval_command(tmp_path):
    frames = tiny_frames(trials=3)
    model = models.train(frames, models.make_spec("deform-gru", epochs=2), seed=0)
    models.save(model, str(tmp_path / "m.model"))
    path = write_stream(frames, tmp_path / "f.arrows", chunk=1)
    with open(path, "rb") as stdin:
        streamed = run(["predict", "--model", str(tmp_path / "m.model"), "-o", str(tmp_path / "s.arrows")], stdin)
    with open(path, "rb") as stdin:
        evaluated = run(["eval", "--model", str(tmp_path / "m.model"), "-o", str(tmp_path / "e.arrows")], stdin)
    assert streamed.returncode == 0 and evaluated.returncode == 0, streamed.stderr + evaluated.stderr
    a = tables.read([str(tmp_path / "s.arrows")])
    b = tables.read([str(tmp_path / "e.arrows")])
    np.testing.assert_allclose(a.column("force_pred").to_numpy(), b.column("force_pred").to_numpy(), atol=1e-5)
    assert a.column("trial").to_pylist() == b.column("trial").to_pylist()


def test_predict_writes_each_batch_before_reading_the_next(tmp_path):
    """A frame's estimate comes out while later frames have not been written yet (a live pipe)."""
    frames = tiny_frames(trials=1)
    model = models.train(frames, models.make_spec("deform-gru", epochs=1), seed=0)
    models.save(model, str(tmp_path / "m.model"))
    code = "from neurotac_cli.cli import main; main()"
    proc = subprocess.Popen([sys.executable, "-c", code, "predict", "--model", str(tmp_path / "m.model")],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    import pyarrow.ipc as ipc

    writer = ipc.new_stream(proc.stdin, frames.schema)
    writer.write_batch(frames.to_batches(max_chunksize=1)[0])
    proc.stdin.flush()
    reader = ipc.open_stream(proc.stdout)
    first = reader.read_next_batch()  # arrives although the input stream is still open
    assert first.num_rows == 1 and first.column("frame").to_pylist() == [0]
    for batch in frames.to_batches(max_chunksize=1)[1:]:
        writer.write_batch(batch)
    writer.close()
    proc.stdin.close()
    rest = reader.read_all()
    assert rest.num_rows == frames.num_rows - 1
    assert proc.wait(timeout=60) == 0


def test_classify_command_one_row_per_trial(tmp_path):
    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("material-dnn", epochs=3), seed=0)
    models.save(model, str(tmp_path / "c.model"))
    path = write_stream(frames, tmp_path / "f.arrows")
    with open(path, "rb") as stdin:
        done = run(["classify", "--model", str(tmp_path / "c.model"), "-o", str(tmp_path / "c.arrows")], stdin)
    assert done.returncode == 0, done.stderr
    table = tables.read([str(tmp_path / "c.arrows")])
    assert table.column("trial").to_pylist() == ["t0", "t1", "t2", "t3"]
    assert {"material_pred", "prob_foam", "prob_steel"} <= set(table.schema.names)
    probs = np.stack([table.column("prob_foam").to_numpy(), table.column("prob_steel").to_numpy()], axis=1)
    np.testing.assert_allclose(probs.sum(axis=1), 1, atol=1e-5)


def test_frames_busier_than_any_training_frame_are_named_at_once_and_counted(tmp_path):
    frames = tiny_frames(trials=3)
    model = models.train(frames, models.make_spec("deform-gru", epochs=2), seed=0)
    models.save(model, str(tmp_path / "m.model"))
    with open(write_stream(frames, tmp_path / "f.arrows"), "rb") as stdin:
        quiet = run(["predict", "--model", str(tmp_path / "m.model"), "-o", str(tmp_path / "q.arrows")], stdin)
    assert quiet.returncode == 0 and b"warning" not in quiet.stderr, quiet.stderr
    counts = schema_counts(frames) * 3
    busy = frames.set_column(frames.schema.get_field_index("counts"), "counts", sch.counts_array(counts))
    with open(write_stream(busy, tmp_path / "b_in.arrows"), "rb") as stdin:
        done = run(["predict", "--model", str(tmp_path / "m.model"), "-o", str(tmp_path / "b.arrows")], stdin)
    lines = done.stderr.decode().splitlines()
    assert done.returncode == 0, done.stderr
    assert lines[0].startswith("neurotac predict: warning: trial ") and "times the events of the busiest training frame" in lines[0]
    assert any(line.startswith("neurotac predict: warning: ") and " frames held more than 1.5 times the events" in line for line in lines[1:])
    assert tables.read([str(tmp_path / "b.arrows")]).num_rows == busy.num_rows


def test_frames_missing_inside_a_trial_are_counted_for_a_model_of_whole_trials():
    frames = tiny_frames(trials=2)
    model = models.train(frames, models.make_spec("tdnn", epochs=1), seed=0)
    kept = frames.filter(pa.array([f not in (3, 4, 5) for f in frames.column("frame").to_pylist()]))
    notes = []
    _, batches = models.stream(model, kept.schema, iter(kept.to_batches(max_chunksize=2)), notes=notes)
    list(batches)
    assert notes == ["warning: 6 frames missing inside 2 trials (t0: 3): the model's state ran over each gap as if its frames had come"]
    notes = []
    list(models.stream(model, frames.schema, iter(frames.to_batches(max_chunksize=2)), notes=notes)[1])
    assert notes == []


def test_estimates_beyond_the_training_forces_are_counted_and_older_model_files_still_run():
    frames = tiny_frames(trials=2)
    model = models.train(frames, models.make_spec("lstm", epochs=1), seed=0)
    model.training.pop("events_per_frame_max")  # a model file written before the busiest frame was kept
    outside = models.Outside.of(model)
    outside.max_force = 1e-3  # every estimate is beyond it
    said = []
    outside.say = said.append
    schema, batches = models.stream(model, frames.schema, iter(frames.to_batches(max_chunksize=5)), outside=outside)
    assert sum(batch.num_rows for batch in batches) == frames.num_rows
    assert len(said) == 1 and "beyond the training forces" in said[0]
    assert outside.busy == 0 and outside.strong > 0
    assert outside.messages() == [f"{outside.strong} of {frames.num_rows} estimates went beyond 1.2 times the largest training "
                                  f"force (0.001 N; up to {outside.strongest:.3g} N)"]


def schema_counts(table):
    return sch.counts_numpy(table.column("counts")).astype(np.uint16)


def test_a_busy_frame_outside_any_contact_is_not_named_for_a_model_trained_on_contacts():
    """A session model reads zero between contacts (an LED blink before the first touch): nothing extrapolated there."""
    from tests.model.test_session import tiny_session
    from neurotac_cli.model import session

    table, _ = tiny_session(grasps=4, seed=1)
    model = session.train(table, models.make_spec("deform-gru", epochs=1, hidden=4), seed=0)
    counts = schema_counts(table).copy()
    counts[5] += 50  # a blink in the stream's first frames (the detector's warm-up), far busier than any training frame
    blinked = table.set_column(table.schema.get_field_index("counts"), "counts", sch.counts_array(counts))
    outside = models.Outside.of(model)
    assert counts[5].sum() > EVENTS_MARGIN * outside.max_events  # a trial model would have it named
    schema, batches = models.stream(model, blinked.schema, iter(blinked.to_batches(max_chunksize=7)), outside=outside)
    out = pa.Table.from_batches(list(batches), schema=schema)
    assert not out.column("contact_pred").to_numpy(zero_copy_only=False)[5]
    assert outside.busy == 0 and outside.frames == blinked.num_rows


def _swept_bar(frames):
    """The frames' events per frame laid on a bar that turns round the frame's centre: a scene of
    another kind (a rotating disk, a waved hand) at ordinary event rates."""
    counts = schema_counts(frames)
    n, _, height, width = counts.shape
    per_pixel = np.maximum(counts.reshape(n, -1).sum(axis=1) // 9, 1)
    bar = np.zeros_like(counts)
    for i in range(n):
        for r in range(-4, 5):
            y, x = int(height / 2 + r * np.sin(0.4 * i)), int(width / 2 + r * np.cos(0.4 * i))
            bar[i, i % 2, y % height, x % width] += per_pixel[i]
    return frames.set_column(frames.schema.get_field_index("counts"), "counts", sch.counts_array(bar))


def test_a_scene_unlike_the_training_frames_is_named_though_its_event_rates_are_ordinary():
    model = models.train(tiny_frames(trials=24, length=40, seed=0), models.make_spec("deform-gru", epochs=3), seed=0)
    assert float(model.net.distance_p99) > 0
    held_out = tiny_frames(trials=8, length=40, seed=1)
    for frames, expected in ((held_out, False), (_swept_bar(held_out), True)):
        said = []
        outside = models.Outside.of(model, say=said.append)
        schema, batches = models.stream(model, frames.schema, iter(frames.to_batches(max_chunksize=7)), outside=outside)
        assert sum(batch.num_rows for batch in batches) == frames.num_rows
        assert model.net.distance_log is None  # the network logs only while a stream is watched
        assert outside.busy == 0  # no frame is busier than the training ones: the events alone say nothing
        assert (outside.unlike > 0) == expected, said
        if expected:
            assert "a scene unlike any the model learnt from" in said[0]
            assert outside.messages()[0].startswith(f"{outside.unlike} of {frames.num_rows} frames lay further from the training frames")


def test_a_model_file_without_the_feature_distance_runs_unwatched(tmp_path):
    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    from neurotac_cli.model.store import DIGEST_KEY, HEADER_KEY

    model = models.train(tiny_frames(trials=24, seed=0), models.make_spec("deform-gru", epochs=1), seed=0)
    models.save(model, str(tmp_path / "m.model"))
    with safe_open(str(tmp_path / "m.model"), "pt") as handle:
        metadata = handle.metadata()
    # a file written before the distance was kept: its tensors lack the two buffers, its header a checksum
    tensors = {k: v for k, v in load_file(str(tmp_path / "m.model")).items() if k not in ("feature_precision", "distance_p99")}
    header = json.loads(metadata[HEADER_KEY])
    del header[DIGEST_KEY]
    metadata = {**metadata, HEADER_KEY: json.dumps(header)}
    save_file(tensors, str(tmp_path / "old.model"), metadata=metadata)
    old = models.load(str(tmp_path / "old.model"))
    frames = _swept_bar(tiny_frames(trials=4, seed=1))
    outside = models.Outside.of(old)
    schema, batches = models.stream(old, frames.schema, iter(frames.to_batches()), outside=outside)
    assert sum(batch.num_rows for batch in batches) == frames.num_rows and outside.unlike == 0


@pytest.mark.parametrize("number, code, said", [("SIGINT", 130, "interrupted"), ("SIGTERM", 143, "terminated")])
def test_a_signal_while_the_model_loads_ends_the_run_with_one_line(tmp_path, number, code, said):
    """Raised in the main thread while the loader imported torch beside it, a Ctrl-C left modules
    half made: tracebacks, a run to the end as if nothing had come, or a hang on an import lock."""
    import signal
    import time

    from neurotac_cli.model import session
    from tests.model.test_session import tiny_session

    # a model trained with --contacts: `predict` imports the detector and the session's model while
    # torch is imported beside it (a model of whole trials read its input and waited: it never broke)
    frames = tiny_session(grasps=3, seed=1)[0]
    models.save(session.train(frames, models.make_spec("deform-gru", epochs=1, hidden=8, members=1), seed=0), str(tmp_path / "m.model"))
    path = write_stream(frames, tmp_path / "f.arrows")
    # the loader imports torch for about a second; the first instants fall in the main thread's own imports
    for delay in np.arange(1, 9) / 10:
        process = subprocess.Popen(["neurotac", "predict", "--model", str(tmp_path / "m.model"), path, "-o", str(tmp_path / "p.arrows")],
                                   stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        time.sleep(delay)
        process.send_signal(getattr(signal, number))
        ended, stderr = process.wait(60), process.stderr.read().decode()
        if ended == -getattr(signal, number) and not stderr:  # before the interpreter handles signals (a slow start)
            continue
        assert ended == code and stderr.strip() == f"neurotac predict: {said}", (delay, ended, stderr)
