"""Scoring predictions: metric rows of one model's predictions or of a cross-validation's folds,
and the summary a person reads on stderr."""

import numpy as np
import pyarrow as pa

from neurotac_cli import metrics
from neurotac_cli.errors import SchemaError
from neurotac_cli.units import counted, first_few


def score(predictions: pa.Table, *, nonzero=False, per_trial=True, classes=None, label="material", whole=True) -> list:
    """Metric rows of a predictions table (force or material); `whole`: as `metrics.force_rows`."""
    names = predictions.schema.names
    if "force_pred" in names:
        rows = metrics.force_rows(
            predictions.column("trial").to_pylist(), predictions.column("phase").to_pylist(),
            predictions.column("force").to_numpy(zero_copy_only=False), predictions.column("force_pred").to_numpy(zero_copy_only=False),
            nonzero=nonzero, per_trial=per_trial, whole=whole, series=_series(predictions),
        )
        if "contact_pred" in names:  # a model run on streams: rest, drift, contact and per-grasp figures
            from neurotac_cli.model.session import session_rows

            rows += session_rows(predictions)
        return rows
    if label not in names:
        raise SchemaError(f"the frames have no {label!r} column to score the classifier against (label columns: "
                          f"{', '.join(n for n in names if not n.startswith('prob_') and n != f'{label}_pred') or 'none'}); "
                          "use `neurotac classify` to predict without scoring")
    true = predictions.column(label).to_pylist()
    pred = predictions.column(f"{label}_pred").to_pylist()
    classes = classes or [n[len("prob_"):] for n in names if n.startswith("prob_")]
    return metrics.classification_rows(true, pred, classes)


def _series(predictions: pa.Table) -> list | None:
    """Which frames form one time series for DTW and D_B: a trial, once per cross-validation repeat,
    and within a session (a `grasp` column) each grasp, so the holds of a session's grasps are not
    strung into one series (None: the trial)."""
    names = [name for name in ("repeat", "trial", "grasp") if name in predictions.schema.names]
    if names == ["trial"]:
        return None
    return ["/".join(map(str, key)) for key in zip(*(predictions.column(name).to_pylist() for name in names))]


def score_folds(results: list, folds: int, *, nonzero=False, per_trial=True, label="material"):
    """`evaluate.cross_validate`'s predictions and rows from the results of `cv.run_fold` on the tasks of
    `cv.fold_tasks` (in their order: repeat after repeat of `folds` folds)."""
    parts, per_fold = [], []
    for index, (predictions, validation) in enumerate(results):
        repeat, fold = divmod(index, folds)
        rows = score(predictions, nonzero=nonzero, per_trial=False, label=label, whole=False)
        rows += [("all", name, float(value)) for name, value in validation.items()]
        per_fold.append(rows)
        n = predictions.num_rows
        parts.append(predictions.append_column("repeat", pa.array(np.full(n, repeat, np.int32)))
                     .append_column("fold", pa.array(np.full(n, fold, np.int32))))
    schema = parts[0].schema
    merged = pa.concat_tables([p.select(p.schema.names) for p in parts], promote_options="default")
    merged = merged.replace_schema_metadata(schema.metadata)
    rows = score(merged, nonzero=nonzero, per_trial=per_trial, label=label)
    for index, fold_rows in enumerate(per_fold):
        repeat, fold = divmod(index, folds)
        rows += [(f"fold:{repeat}/{fold}", metric, value) for scope, metric, value in fold_rows if scope == "all"]
    rows += metrics.fold_summary(per_fold)
    return merged, rows


ORDER = ("mse", "rmse", "mae", "rmse_pct_range", "mse_sd", "mae_sd", "r2", "dtw", "bhattacharyya", "n")


def summary(rows: list, title: str = "") -> str:
    """A readable table of the overall and per-phase figures (and fold mean ± σ when present)."""
    by_scope = {}
    for scope, metric, value in rows:
        by_scope.setdefault(scope, {})[metric] = value
    lines = [title] if title else []
    if "accuracy" in by_scope.get("all", {}):
        figures = by_scope["all"]
        lines.append(f"accuracy {100 * figures['accuracy']:.1f}% over {counted(int(figures.get('n', 0)), 'trial')}")
        if "accuracy_fold_mean" in figures:
            lines.append(f"accuracy per fold {100 * figures['accuracy_fold_mean']:.1f}% ± {100 * figures['accuracy_fold_sd']:.1f}%")
        unknown = [s[len("unknown:"):] for s in by_scope if s.startswith("unknown:")]
        if unknown:
            lines.append(f"  {counted(int(figures.get('unknown_class', 0)), 'trial')} of classes the model was not trained on "
                         f"({', '.join(unknown)}), counted as wrong")
        if figures.get("unlabelled"):
            lines.append(f"  {counted(int(figures['unlabelled']), 'trial')} without a label, counted as wrong")
        classes = [s[len("class:"):] for s in by_scope if s.startswith("class:")]
        for name in classes:
            recall = by_scope[f"class:{name}"].get("recall")
            if recall is not None:
                lines.append(f"  recall {name:<12} {100 * recall:.1f}%")
        matrix_classes = [s[len("confusion:"):] for s in by_scope if s.startswith("confusion:")]
        if matrix_classes:
            width = max(8, *(len(c) + 1 for c in matrix_classes))
            lines.append("confusion (rows true, columns predicted):")
            lines.append(" " * width + "".join(f"{c:>{width}}" for c in matrix_classes))
            for a in matrix_classes:
                lines.append(f"{a:<{width}}" + "".join(f"{int(by_scope[f'confusion:{a}'].get(f'pred:{b}', 0)):>{width}}" for b in matrix_classes))
        return "\n".join(lines + _validation_lines(figures))
    scopes = ["all"] + [s for s in by_scope if s.startswith("phase:")]
    metrics_here = [m for m in ORDER if any(m in by_scope.get(s, {}) for s in scopes)]
    header = f"{'scope':<18}" + "".join(f"{m:>15}" for m in metrics_here)
    lines.append(header)
    for scope in scopes:
        figures = by_scope.get(scope, {})
        cells = []
        for m in metrics_here:
            value = figures.get(m)
            if value is None or not np.isfinite(value):
                cells.append(f"{'-':>15}")
            elif f"{m}_fold_mean" in figures:
                cells.append(f"{figures[f'{m}_fold_mean']:>8.4g}±{figures[f'{m}_fold_sd']:<6.3g}")
            else:
                cells.append(f"{value:>15.4g}" if m != "n" else f"{int(value):>15d}")
        lines.append(f"{scope:<18}" + "".join(cells))
    if any("_fold_mean" in m for s in scopes for m in by_scope.get(s, {})):
        lines.append("(a±b: mean ± σ over folds; pooled figures in the metrics table)")
    lines += _left_out_lines(rows, by_scope.get("all", {}))
    lines += _validation_lines(by_scope.get("all", {}))
    if "rest_frames" in by_scope.get("all", {}):  # a model run on streams (train --contacts)
        from neurotac_cli.model.session import summary_lines

        lines += summary_lines(by_scope["all"])
    return "\n".join(lines)


def _left_out_lines(rows: list, figures: dict) -> list:
    """What the figures leave out: frames without a measured force, scopes whose force does not vary."""
    lines = []
    if figures.get("unforced_frames"):
        lines.append(f"{counted(int(figures['unforced_frames']), 'frame')} with no measured force (null in the force column) left out of these figures")
    flat = sorted({scope for scope, metric, value in rows if metric in ("r2", "rmse_pct_range") and not np.isfinite(value)})
    if flat:
        lines.append(f"R² and the % of the range are undefined where the measured force does not vary: {counted(len(flat), 'scope')} "
                     f"({first_few(flat)}), '-' here and NaN in the metrics table")
    return lines


def _validation_lines(figures: dict) -> list:
    """`validation MSE 0.0123 ± 0.004 N² over 48 folds (early-stopping trials, best epoch 37 of 57 on average)`."""
    lines = []
    for metric, text, scale, unit in (("val_mse", "validation MSE", 1, " N²"), ("val_accuracy", "validation accuracy", 100, "%")):
        mean = figures.get(f"{metric}_fold_mean")
        if mean is None or not np.isfinite(mean):
            continue
        line = f"{text} {scale * mean:.4g} ± {scale * figures.get(f'{metric}_fold_sd', float('nan')):.3g}{unit} (mean ± σ over folds, early-stopping trials"
        epochs, best = figures.get("epochs_fold_mean"), figures.get("best_epoch_fold_mean")
        if epochs is not None and np.isfinite(epochs):
            line += f"; best epoch {best:.0f} of {epochs:.0f} on average"
        lines.append(line + ")")
    return lines
