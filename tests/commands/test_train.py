import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from neurotac_cli import model as models, tables
from neurotac_cli.errors import ModelError
from tests.model.helpers import tiny_frames, write_stream

NEUROTAC = [sys.executable, "-m", "neurotac_cli.cli"]


def run(args, stdin=None):
    code = "from neurotac_cli.cli import main; main()"
    return subprocess.run([sys.executable, "-c", code, *args], stdin=stdin, capture_output=True)


def test_split_that_separates_a_trial_from_its_augmented_copy_is_refused():
    frames = tiny_frames(trials=6, augmented_copies=1)
    with pytest.raises(ModelError, match="augmented copies fall on both sides"):
        models.train(frames, models.make_spec("deform-gru", epochs=1), val_trials=["t0"], seed=0)


def test_fraction_split_keeps_copies_together():
    frames = tiny_frames(trials=6, augmented_copies=1)
    model = models.train(frames, models.make_spec("deform-gru", epochs=1), val_fraction=0.3, seed=0)
    every = set(frames.column("trial").to_pylist())
    sources = lambda names: {n.split("~")[0] for n in names}  # noqa: E731
    # each member's validation draw holds whole source groups, and the member trains on the rest
    for val in [model.training["trials"]["validation"], *model.training["trials"]["member_validation"]]:
        assert val and not (sources(val) & sources(every - set(val)))


def test_val_where_picks_a_label_value():
    frames = tiny_frames(trials=6)
    model = models.train(frames, models.make_spec("tdnn", epochs=1), val_where="object=large", seed=0)
    assert model.training["trials"]["validation"] == ["t1", "t3", "t5"]


def test_leak_is_refused_on_the_command_line(tmp_path):
    path = write_stream(tiny_frames(trials=4, augmented_copies=1), tmp_path / "f.arrows")
    with open(path, "rb") as stdin:
        done = run(["train", "--model", "deform-gru", "--epochs", "1", "--val-trials", "t0", "-o", str(tmp_path / "m.model")], stdin)
    assert done.returncode == 1
    assert b"neurotac train: error: trial 't0' and its augmented copies fall on both sides" in done.stderr
    assert b"Traceback" not in done.stderr


def test_model_from_a_different_input_spec_is_refused(tmp_path):
    model = models.train(tiny_frames(trials=4), models.make_spec("deform-gru", epochs=1), seed=0)
    path = tmp_path / "m.model"
    models.save(model, str(path))
    other = write_stream(tiny_frames(trials=2, size=(8, 9)), tmp_path / "small.arrows")
    with open(other, "rb") as stdin:
        done = run(["eval", "--model", str(path)], stdin)
    assert done.returncode == 1
    message = done.stderr.decode()
    assert "was trained on 9x9 frames of 10 ms, this input has 9x8 frames of 10 ms (different crop)" in message
    with pytest.raises(ModelError, match="different window"):
        models.predict_table(models.load(str(path)), tiny_frames(trials=2, window_us=7000))


def test_train_command_writes_model_curve_and_plot(tmp_path):
    path = write_stream(tiny_frames(trials=4), tmp_path / "f.arrows")
    with open(path, "rb") as stdin:
        done = run(["train", "--model", "tdnn", "--epochs", "3", "--layers", "2", "--units", "5", "-o", str(tmp_path / "m.model"),
                    "--curve", str(tmp_path / "curve.parquet"), "--plot", str(tmp_path / "curve.png")], stdin)
    assert done.returncode == 0, done.stderr
    assert b"tdnn: 3 epochs" in done.stderr
    assert (tmp_path / "curve.png").stat().st_size > 1000
    import pyarrow.parquet as pq

    curve = pq.read_table(tmp_path / "curve.parquet")
    assert curve.num_rows == 6 and set(curve.column("metric").to_pylist()) == {"train_loss", "val_loss"}
    model = models.load(str(tmp_path / "m.model"))
    assert model.config.layers == 2 and model.config.units == 5


@pytest.mark.parametrize("number, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_training_stopped_by_the_user_writes_its_best_epoch_s_model_and_ends_as_interrupted(tmp_path, number, code):
    path = write_stream(tiny_frames(trials=4), tmp_path / "f.arrows")
    process = subprocess.Popen([sys.executable, "-c", "from neurotac_cli.cli import main; main()", "train", "--model", "tdnn",
                                "--epochs", "100000", "--patience", "100000", "--layers", "2", "--units", "5",
                                "-o", str(tmp_path / "m.model"), str(path)], stderr=subprocess.PIPE)
    lines = [process.stderr.readline()]
    while lines[-1] and b"tdnn: epoch 1 " not in lines[-1]:  # off a terminal, the first epoch's line is shown
        lines.append(process.stderr.readline())
    time.sleep(0.5)
    process.send_signal(number)
    stderr = b"".join(lines) + process.communicate(timeout=60)[1]
    assert process.returncode == code, stderr
    assert b"Traceback" not in stderr and b"stopped by the interrupt after" in stderr and b"holds its best epoch's weights" in stderr
    model = models.load(str(tmp_path / "m.model"))
    assert model.config.layers == 2 and 1 <= len(model.training["curve"]) < 100000


@pytest.mark.parametrize("command", [
    ["train", "--model", "tdnn", "--epochs", "3", "-o", "{tmp}/m.model", "--plot", "{missing}/curve.png"],
    ["train", "--model", "tdnn", "--epochs", "3", "-o", "{missing}/m.model"],
    ["eval", "--cv", "kfold:2", "--model-spec", "tdnn", "--epochs", "3", "--metrics", "{missing}/m.parquet"],
])
def test_an_output_in_a_missing_folder_is_refused_before_any_training(tmp_path, command):
    path = write_stream(tiny_frames(trials=4), tmp_path / "f.arrows")
    with open(path, "rb") as stdin:
        done = run([part.format(missing=tmp_path / "no-such", tmp=tmp_path) for part in command], stdin)
    lines = done.stderr.decode().splitlines()
    assert done.returncode == 1 and len(lines) == 1, done.stderr
    assert "folder" in lines[0] and "does not exist" in lines[0] and not any(p.suffix == ".model" for p in tmp_path.iterdir())


def test_eval_cross_validation_folds_and_classification(tmp_path):
    path = write_stream(tiny_frames(trials=6), tmp_path / "f.arrows")
    with open(path, "rb") as stdin:
        done = run(["eval", "--cv", "kfold:3", "--model-spec", "material-curves", "--epochs", "5",
                    "--metrics", str(tmp_path / "m.parquet"), "--plot", str(tmp_path / "cm.png"), "-o", str(tmp_path / "oof.parquet")], stdin)
    assert done.returncode == 0, done.stderr
    assert b"confusion (rows true, columns predicted)" in done.stderr
    import pyarrow.parquet as pq

    oof = pq.read_table(tmp_path / "oof.parquet")
    assert sorted(oof.column("trial").to_pylist()) == [f"t{i}" for i in range(6)]
    assert set(oof.column("fold").to_pylist()) == {0, 1, 2}
    metrics = pq.read_table(tmp_path / "m.parquet").to_pylist()
    assert any(row["metric"] == "accuracy_fold_mean" for row in metrics)
    assert (tmp_path / "cm.png").stat().st_size > 1000


def test_eval_cv_held_out_group_scores_only_that_group(tmp_path):
    frames = tiny_frames(trials=6)
    from neurotac_cli.model import evaluate

    predictions, rows = evaluate.cross_validate(frames, models.make_spec("deform-gru", epochs=2), "group:object=large", seed=0)
    assert set(predictions.column("object").to_pylist()) == {"large"}
    figures = {(s, m): v for s, m, v in rows}
    assert np.isfinite(figures[("all", "rmse")]) and ("phase:holding", "dtw") in figures


def test_non_finite_force_in_frames_is_refused_but_null_is_unknown():
    import pyarrow as pa

    from neurotac_cli.errors import SchemaError
    from neurotac_cli.model.data import sequences

    table = tiny_frames()
    index = table.schema.get_field_index("force")
    force = table.column("force").to_numpy(zero_copy_only=False).copy()
    with_null = table.set_column(index, table.schema.field("force"), pa.array([None] + list(force[1:]), pa.float32()))
    assert np.isnan(np.concatenate(sequences(with_null).force)).sum() == 1
    for bad in (np.nan, np.inf):
        force[3] = bad
        broken = table.set_column(index, table.schema.field("force"), pa.array(force, pa.float32()))
        with pytest.raises(SchemaError, match="NaN or infinite"):
            sequences(broken)


def test_a_model_header_missing_a_part_is_one_clear_error(tmp_path):
    import json

    from safetensors.torch import load_file, save_file

    from neurotac_cli.model import store

    path = tmp_path / "m.model"
    models.save(models.train(tiny_frames(), models.make_spec("tdnn", epochs=1)), str(path))
    header = store.read_header(str(path))
    del header["input"]
    save_file(load_file(str(path)), str(tmp_path / "broken.model"), metadata={store.HEADER_KEY: json.dumps(header)})
    with pytest.raises(ModelError, match="lacks input"):
        models.load(str(tmp_path / "broken.model"))
    with pytest.raises(ModelError, match="not a regular file"):
        models.load(str(tmp_path))


def test_progress_off_a_terminal_shows_the_first_epoch_every_25th_and_a_slow_one(monkeypatch, capsys):
    from neurotac_cli.options import progress_printer

    clock = [0.0]
    monkeypatch.setattr("time.monotonic", lambda: clock[0])
    show = progress_printer("train")
    for epoch in range(1, 61):
        clock[0] += 40.0 if epoch == 33 else 1.0  # epoch 33 ends 40 s after the line before it
        show(f"m: epoch {epoch} loss 1 best 1 (0/20 without improvement, 1s)")
    show("m: 60 epochs, best epoch 3; wrote m.model")
    lines = capsys.readouterr().err.splitlines()
    assert [line.split()[2] for line in lines[:-1]] == ["1", "25", "33", "50"]
    assert lines[-1].startswith("m: 60 epochs")
    for epoch in range(1, 30):  # a member's epochs are thinned alike
        show(f"deform-gru member 2/3: epoch {epoch} loss 1 val 1 best 1 (0/40 without improvement, 1s)")
    show("warning: the training frames carry forces up to 900 N")
    lines = capsys.readouterr().err.splitlines()
    assert [line.split()[4] for line in lines[:-1]] == ["1", "25"]
    assert lines[-1] == "neurotac train: warning: the training frames carry forces up to 900 N"


def test_a_model_file_the_disk_cannot_hold_is_one_line_and_keeps_the_old_file(tmp_path):
    # safetensors says a full disk in its own error type, which went up as a traceback
    frames = tmp_path / "f.arrows"
    tables.write(str(frames), tiny_frames(trials=4))
    (tmp_path / "m.model").write_bytes(b"old model")
    done = subprocess.run(["bash", "-c", f"ulimit -f 2; neurotac train --model gp -o m.model {frames}"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.splitlines()[-1].startswith("neurotac train: error: cannot write m.model (file too large")
    assert (tmp_path / "m.model").read_bytes() == b"old model"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.arrows", "m.model"]


def test_an_interrupt_that_leaves_a_member_untrained_says_no_model_was_written(capsys):
    from neurotac_cli.commands.train import _said_when_lost

    stop = KeyboardInterrupt()
    with pytest.raises(KeyboardInterrupt), _said_when_lost([("deform-gru member 1/3", 12, stop)]):
        raise stop  # raised again by the next member's fit
    assert "deform-gru member 1/3: stopped by the interrupt after 12 epochs, before the members after it began: no model written" \
        in capsys.readouterr().err
    with pytest.raises(KeyboardInterrupt), _said_when_lost([("tdnn", 3, KeyboardInterrupt())]):  # a second interrupt, after the fit
        raise KeyboardInterrupt
    assert "tdnn: stopped by the interrupt after 3 epochs, and again before its model was written: none written" in capsys.readouterr().err
    with pytest.raises(KeyboardInterrupt), _said_when_lost([]):  # interrupted before any epoch ended: the exit says it
        raise KeyboardInterrupt
    assert capsys.readouterr().err == ""
