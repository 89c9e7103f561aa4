"""`eval --cv` records each fold's validation error (thesis Table 3.1), and `eval --cv --grid` is the
study `neurotac study` runs."""

import math

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

torch = pytest.importorskip("torch")

from neurotac_cli import model as models  # noqa: E402
from neurotac_cli.model.cv import run_fold  # noqa: E402
from tests.model.helpers import tiny_frames, write_stream  # noqa: E402


def _run(args):
    from neurotac_cli.cli import cli

    return CliRunner().invoke(cli, args)


def _rows(path):
    table = pq.read_table(path)
    names = table.schema.names
    rows = zip(*(table.column(name).to_pylist() for name in names))
    return names, sorted((tuple("nan" if v != v else v for v in row) for row in rows), key=str)


@pytest.fixture(scope="module")
def frames_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("frames") / "frames.arrows"
    write_stream(tiny_frames(trials=5), path)
    return str(path)


def test_a_folds_validation_error_is_the_restored_best_epochs_mse_in_newtons_squared():
    frames = tiny_frames(trials=6)
    spec = models.make_spec("tdnn", layers=1, units=4, epochs=6, patience=2)
    predictions, validation = run_fold(frames, spec, ["t0"], seed=5, val_fraction=0.3, per=None)
    assert set(predictions.column("trial").to_pylist()) == {"t0"}

    # the same training by hand: the fold's early stopping watched this curve, in normalised units
    train_table = frames.filter(np.asarray(frames.column("trial").to_pylist()) != "t0")
    model = models.train(train_table, spec, val_fraction=0.3, seed=5)
    curve = model.training["curve"]
    best = min(row["val_loss"] for row in curve)
    assert validation["val_mse"] == pytest.approx(best * model.force_scale**2, rel=1e-4)
    assert validation["epochs"] == len(curve)
    assert validation["best_epoch"] == min(curve, key=lambda row: row["val_loss"])["epoch"]


def test_a_folds_epochs_and_best_epoch_are_the_means_over_the_models_members():
    """They were the first member's alone, though each member of a deform-gru stops on its own draw."""
    frames = tiny_frames(trials=12)
    spec = models.make_spec("deform-gru", members=3, epochs=12, patience=2, lr=0.02)
    _, validation = run_fold(frames, spec, ["t0"], seed=3, val_fraction=0.25, per=None)

    train_table = frames.filter(np.asarray(frames.column("trial").to_pylist()) != "t0")
    model = models.train(train_table, spec, val_fraction=0.25, seed=3)
    lengths = [len(curve) for curve in model.training["member_curves"]]
    assert len(set(lengths)) > 1  # members that stopped apart, or the first's figures would pass for the mean
    assert validation["epochs"] == pytest.approx(np.mean(lengths))
    assert validation["best_epoch"] == pytest.approx(np.mean(model.training["member_best_epochs"]))


def test_eval_cv_metrics_hold_validation_error_per_fold_and_its_mean_and_sd(frames_file, tmp_path):
    done = _run(["eval", "--cv", "loo", "--model-spec", "tdnn", "--layers", "1", "--units", "3", "--epochs", "3",
                 "--seed", "1", frames_file, "--metrics", str(tmp_path / "m.parquet"), "-o", str(tmp_path / "p.arrows")])
    assert done.exit_code == 0, done.output
    assert "validation MSE" in done.stderr
    table = pq.read_table(tmp_path / "m.parquet")
    figures = {(s, m): v for s, m, v in zip(*(table.column(c).to_pylist() for c in ("scope", "metric", "value")))}
    folds = [v for (s, m), v in figures.items() if s.startswith("fold:") and m == "val_mse"]
    assert len(folds) == 5 and all(v > 0 and math.isfinite(v) for v in folds)
    assert figures[("all", "val_mse_fold_mean")] == pytest.approx(np.mean(folds))
    assert figures[("all", "val_mse_fold_sd")] == pytest.approx(np.std(folds))
    assert ("all", "val_mse") not in figures  # no pooled figure: the folds' validation trials overlap


def test_classifier_folds_record_validation_accuracy():
    frames = tiny_frames(trials=8)
    spec = models.make_spec("material-dnn", layers=1, units=4, epochs=3)
    _, validation = run_fold(frames, spec, ["t0"], seed=1, val_fraction=0.3, per="material")
    assert 0.0 <= validation["val_accuracy"] <= 1.0


def test_eval_grid_is_the_study_of_neurotac_study(frames_file, tmp_path):
    common = ["--model-spec", "tdnn", "--grid", "layers=1..2", "--units", "3", "--epochs", "2", "--seed", "4", frames_file]
    via_eval = _run(["eval", "--cv", "loo", "--no-per-trial", *common, "--metrics", str(tmp_path / "e.parquet"),
                     "-o", str(tmp_path / "e.arrows")])
    via_study = _run(["study", "--cv", "loo", *common, "--metrics", str(tmp_path / "s.parquet"), "-o", str(tmp_path / "s.arrows")])
    assert via_eval.exit_code == 0 and via_study.exit_code == 0, via_eval.output + via_study.output
    names, rows = _rows(tmp_path / "e.parquet")
    assert names == ["scope", "metric", "value", "model", "layers", "units", "epochs"]
    assert (names, rows) == _rows(tmp_path / "s.parquet")
    assert "tdnn layers=2, units=3, epochs=2: MSE" in via_eval.stderr and ", validation " in via_eval.stderr


@pytest.mark.parametrize("args, code, words", [
    (["--grid", "layers=1,2"], 2, "--grid needs --cv"),
    (["--cv", "loo", "--model-spec", "tdnn", "--grid", "layers=1,2", "--layers", "3"], 2, "given both as an option and in --grid"),
    (["--cv", "loo", "--model-spec", "tdnn", "--grid", "layers=1,2", "--plot", "x.png"], 2, "--plot draws one model"),
    (["--cv", "loo", "--model-spec", "tdnn", "--grid", "layers"], 2, "is not NAME=VALUES"),
])
def test_eval_grid_misuse_says_what_to_do(frames_file, args, code, words):
    done = _run(["eval", *args, frames_file])
    assert done.exit_code == code
    assert words in done.output + done.stderr


def test_a_members_validation_error_scores_each_member_alone_on_the_trials_it_validated_on():
    from neurotac_cli.model.cv import validation_figures
    from neurotac_cli.model.data import padded, sequences

    frames = tiny_frames(trials=16)
    model = models.train(frames, models.make_spec("deform-gru", members=3, epochs=30, lr=0.02), val_fraction=0.25, seed=3)
    trials = model.training["trials"]
    draws = [trials["validation"], *trials["member_validation"]]
    # the other members trained on a member's validation trials, so the mean's error there would flatter it
    data = sequences(frames)
    features = model.net.encode(torch.as_tensor(padded(data.counts)), None)
    force = torch.as_tensor(padded(data.force, fill=np.nan))
    errors = []
    with torch.no_grad():
        for i, draw in enumerate(draws):
            rows = [data.trials.index(t) for t in draw]
            estimate = model.net.forward_encoded(features[rows], member=i) * model.force_scale
            known = ~torch.isnan(force[rows])
            errors.append(((estimate - force[rows])[known] ** 2).numpy())
    assert validation_figures(model, frames)["val_mse"] == pytest.approx(float(np.concatenate(errors).mean()), rel=1e-4)


def _with_huge_force(table, trial="t0"):
    import pyarrow as pa
    import pyarrow.compute as pc

    index = table.schema.get_field_index("force")
    force = pc.if_else(pc.equal(table.column("trial"), trial), pa.scalar(1e30, pa.float32()), table.column("force"))
    return table.set_column(index, table.schema.field(index), force).replace_schema_metadata(table.schema.metadata)


def test_a_measured_force_train_would_refuse_is_not_scored_by_eval_or_a_cross_validation(tmp_path):
    from neurotac_cli.errors import SchemaError
    from neurotac_cli.model.evaluate import Folds, evaluate

    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("tdnn", epochs=1), seed=0)
    path = tmp_path / "m.model"
    models.save(model, str(path))
    huge = _with_huge_force(frames)
    with pytest.raises(SchemaError, match=r"the frames scored carry a force of 1e\+30 N, beyond any contact force"):
        evaluate(huge, model_path=str(path))
    with pytest.raises(SchemaError, match=r"the frames cross-validated carry a force of 1e\+30 N"):
        evaluate(huge, model_spec="tdnn", hyperparameters={"epochs": 1}, folds=Folds("kfold:2"))


def test_a_class_a_fold_never_trained_on_is_named():
    import pyarrow as pa

    from neurotac_cli.model.cv import unseen_classes_note

    seen = pa.table({"trial": ["t0", "t1"], "material": ["foam", "rock"], "material_pred": ["foam", "foam"],
                     "prob_foam": [1.0, 1.0], "prob_steel": [0.0, 0.0]})
    note = unseen_classes_note([(seen, {})], "material")
    assert note.startswith("warning: 1 trial (t1) scored by a fold whose model never trained on their material (rock)")
    assert unseen_classes_note([(seen.slice(0, 1), {})], "material") is None


@pytest.mark.parametrize("k", [0, 1])
def test_kfold_below_two_is_a_usage_error(k):
    from neurotac_cli.errors import UsageError
    from neurotac_cli.model.cv import folds
    from neurotac_cli.model.data import sequences

    with pytest.raises(UsageError, match=f"--cv kfold:{k} needs 2 <= K <= 4"):
        folds(sequences(tiny_frames(trials=4)), f"kfold:{k}", np.random.default_rng(0))
