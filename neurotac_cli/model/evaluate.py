"""`neurotac eval` and `neurotac study`: score a trained model on frames, cross-validate a model
spec, or cross-validate it at every point of a hyperparameter grid."""

from dataclasses import dataclass

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import InputError
from neurotac_cli.metrics import metrics_table
from neurotac_cli.model.core import classify_table, make_spec
from neurotac_cli.model.predict import predict_table
from neurotac_cli.model.cv import fold_tasks, run_fold, unseen_classes_note
from neurotac_cli.model.data import sequences
from neurotac_cli.model.grid import cross_validate_grid, grid_lines, grid_metrics_table
from neurotac_cli.model.scoring import score, score_folds, summary
from neurotac_cli.model.store import load
from neurotac_cli.study import grid_points, run_tasks
from neurotac_cli.units import counted


@dataclass(frozen=True)
class Folds:
    """How a cross-validation trains each fold (see `cv.fold_tasks`)."""

    cv: str
    repeats: int = 1
    seed: int = 0
    val_fraction: float = 0.1
    per: str | None = None
    label: str = "material"


@dataclass(frozen=True)
class Runner:
    """Where a study's tasks run (see `study.run_tasks`): results do not depend on it."""

    jobs: int = 1
    scheduler: str | None = None
    cache: str | None = None


@dataclass(frozen=True)
class Evaluation:
    """What `evaluate` and `study` found: predictions, their metrics table, and a summary for people."""

    name: str
    predictions: pa.Table
    metrics: pa.Table
    summary: str
    spec: dict | None = None


def evaluate(frames: pa.Table, *, model_path=None, model_spec=None, hyperparameters=None, grid=(), folds=None,
             nonzero=False, per_trial=True, runner=Runner(), progress=None) -> Evaluation:
    """Score the model file `model_path` on `frames`, or cross-validate `model_spec` with `folds`
    (at every point of `grid` when one is given: see `study`)."""
    if grid:
        return study(frames, model_spec, grid, hyperparameters, folds, nonzero=nonzero, per_trial=per_trial, runner=runner,
                     progress=progress)
    if folds is not None:
        spec = make_spec(model_spec, **(hyperparameters or {}))
        predictions, rows = cross_validate(
            frames, spec, folds.cv, repeats=folds.repeats, seed=folds.seed, val_fraction=folds.val_fraction,
            per=folds.per, label=folds.label, nonzero=nonzero, per_trial=per_trial, jobs=runner.jobs,
            scheduler=runner.scheduler, cache=runner.cache, progress=progress)
        name = model_spec
    else:
        model = load(model_path)
        notes = []
        predictions, rows = evaluate_model(model, frames, nonzero=nonzero, per_trial=per_trial, notes=notes)
        for note in notes if progress else ():
            progress(f"warning: {note}")
        name, spec = model.name, None
    trials = len(set(predictions.column("trial").to_pylist()))
    title = f"{name} on {counted(trials, 'trial')}" + (" (non-zero force only)" if nonzero else "")
    return Evaluation(name, predictions, metrics_table(rows, name), summary(rows, title=title), spec)


def study(frames: pa.Table, model_spec: str, grid, fixed: dict | None, folds: Folds, *, nonzero=False, per_trial=True,
          runner=Runner(), progress=None) -> Evaluation:
    """Cross-validate `model_spec` at every point of the `--grid` specs `grid` (each with the `fixed`
    hyperparameters): out-of-fold predictions and metrics with one column per grid parameter, and
    one summary line per point."""
    points = grid_points(grid, fixed)
    predictions, rows = cross_validate_grid(
        frames, model_spec, folds.cv, points, repeats=folds.repeats, seed=folds.seed, val_fraction=folds.val_fraction,
        per=folds.per, label=folds.label, nonzero=nonzero, per_trial=per_trial, jobs=runner.jobs,
        scheduler=runner.scheduler, cache_dir=runner.cache, note=progress)
    lines = "\n".join(grid_lines(rows, model_spec))
    return Evaluation(model_spec, predictions, grid_metrics_table(rows, model_spec), lines)


def evaluate_model(model, table: pa.Table, *, nonzero=False, per_trial=True, notes: list | None = None):
    """(predictions, metric rows) of a trained model on a frames table; `notes` as `classify_table`'s."""
    if model.task == "material":
        label = model.training.get("label", "material")
        predictions = classify_table(model, table, notes)
        if label in predictions.column_names:
            given = {value for value in predictions.column(label).to_pylist() if value is not None}
            if given and not given & set(model.classes):
                raise InputError(f"none of the trials' {label} values ({', '.join(sorted(map(str, given)))}) is a class of model "
                                 f"{model.name!r} ({', '.join(model.classes)}): nothing to score; `neurotac classify` names them")
        return predictions, score(predictions, classes=model.classes, label=label)
    if "force" not in table.column_names or not np.isfinite(table.column("force").to_numpy(zero_copy_only=False).astype(np.float64)).any():
        raise InputError("no frame has a true force to score the estimates against (the force column is empty); "
                         "`neurotac predict` gives the estimates alone")
    measured = table.column("force").drop_null().to_numpy(zero_copy_only=False)
    sch.check_force(measured, "the frames' force column")
    sch.check_force_range(measured, "the frames scored")
    predictions = predict_table(model, table)
    return predictions, score(predictions, nonzero=nonzero, per_trial=per_trial)


def cross_validate(table: pa.Table, spec: dict, cv: str, *, repeats=1, seed=0, val_fraction=0.1, per=None,
                   label="material", nonzero=False, per_trial=True, jobs=1, scheduler=None, cache=None, progress=None):
    """Out-of-fold predictions (columns `repeat`, `fold` added) and metric rows: pooled over all
    out-of-fold predictions, per fold (scope `fold:R/F`), and mean / σ over folds.

    Each fold also reports its validation score (`cv.validation_figures`: `val_mse` in N² for force
    models, `val_accuracy` for classifiers, `epochs`, `best_epoch`: the members' mean for a model of
    several) in its `fold:R/F` scope; their mean and σ over folds are `val_mse_fold_mean` /
    `val_mse_fold_sd` ... in scope `all` (the thesis's model-selection tables 3.1 and 3.3 and Fig.
    4.4(a)). There is no pooled validation figure: the folds' validation trials overlap."""
    data = sequences(table)
    groups, tasks = fold_tasks(data, spec, cv, repeats, seed, val_fraction, per, label)
    if progress:
        progress(f"cross-validation {cv}: {len(groups)} folds x {repeats} repeats = {len(tasks)} trainings of {spec['model']}")
    results = run_tasks(run_fold, tasks, jobs=jobs, scheduler=scheduler, cache_dir=cache,
                        label=f"{spec['model']} folds", shared={"frames": table}, note=progress)
    unseen = unseen_classes_note(results, label)
    if unseen and progress:
        progress(unseen)
    return score_folds(results, len(groups), nonzero=nonzero, per_trial=per_trial, label=label)
