"""A grid of cross-validated models: every training of every grid point is one task of
`study.run_tasks`; each point is scored as `neurotac eval --cv` scores one model."""

import math

import pyarrow as pa

from neurotac_cli.metrics import metrics_table
from neurotac_cli.model.cv import fold_tasks, run_fold, unseen_classes_note
from neurotac_cli.model.core import make_spec
from neurotac_cli.model.data import sequences
from neurotac_cli.model.scoring import score_folds
from neurotac_cli.study import run_tasks


def cross_validate_grid(frames, model: str, cv: str, points: list[dict], *, repeats=1, seed=0, val_fraction=0.1,
                        per=None, label="material", nonzero=False, per_trial=True, jobs=1, scheduler=None,
                        cache_dir=None, progress=None, note=None):
    """Cross-validate `model` at every grid point: (predictions, metric rows) with one column per grid
    parameter added to both, in grid order.

    Every training of every point (points × folds × repeats) is one task of a single `run_tasks`
    call, so a cluster works on all of them at once; each point's trainings are then scored by
    `scoring.score_folds`, as `neurotac eval --cv` scores its own.
    """
    specs = [make_spec(model, **point) for point in points]  # refuses unknown names before any work
    data = sequences(frames)
    plans = [fold_tasks(data, spec, cv, repeats, seed, val_fraction, per, label) for spec in specs]
    results = run_tasks(run_fold, [task for _, tasks in plans for task in tasks], jobs=jobs,
                        scheduler=scheduler, cache_dir=cache_dir, label=f"{model} grid", shared={"frames": frames},
                        progress=progress, note=note)
    unseen = unseen_classes_note(results, label)
    if unseen and note:
        note(unseen)
    parts, rows, start = [], [], 0
    for point, (groups, tasks) in zip(points, plans):
        predictions, point_rows = score_folds(results[start : start + len(tasks)], len(groups),
                                                       nonzero=nonzero, per_trial=per_trial, label=label)
        start += len(tasks)
        for name, value in point.items():
            predictions = predictions.append_column(name, pa.array([value] * predictions.num_rows))
        parts.append(predictions)
        rows.append((point, point_rows))
    merged = pa.concat_tables(parts, promote_options="permissive").replace_schema_metadata(parts[0].schema.metadata)
    return merged, rows


def grid_metrics_table(rows, model: str):
    """One metrics table for a grid: scope, metric, value, model, then one column per grid parameter."""
    tables = []
    for point, point_rows in rows:
        table = metrics_table(point_rows, model)
        for name, value in point.items():
            table = table.append_column(name, pa.array([value] * table.num_rows))
        tables.append(table)
    merged = pa.concat_tables(tables, promote_options="permissive")
    return merged.replace_schema_metadata(tables[0].schema.metadata)


def grid_lines(rows, model: str) -> list[str]:
    """One line per grid point for stderr: its parameters, its test score, its validation score."""
    lines = []
    for point, point_rows in rows:
        figures = {metric: value for scope, metric, value in point_rows if scope == "all"}
        shown = ", ".join(f"{name}={value}" for name, value in point.items()) or "(defaults)"
        if "accuracy" in figures:
            summary = f"accuracy {100 * figures['accuracy']:.1f}%"
            validation = figures.get("val_accuracy_fold_mean", math.nan) * 100
            if validation == validation:
                summary += f", validation {validation:.1f}%"
        else:
            summary = f"MSE {figures.get('mse_fold_mean', math.nan):.4g} N² (fold mean)"
            validation = figures.get("val_mse_fold_mean", math.nan)
            if validation == validation:
                summary += f", validation {validation:.4g} N²"
        lines.append(f"{model} {shown}: {summary}")
    return lines
