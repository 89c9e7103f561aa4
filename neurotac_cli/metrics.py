"""Scores of force estimates and material predictions.

Definitions (all forces in newtons):
- MSE (N²), RMSE (N), MAE (N); RMSE as % of the force range (max - min of the measured force in
  the scope); R² = 1 - SSE/SST.
- σ, as the thesis's tables give it: `mse_sd` = standard deviation of the squared errors, `mae_sd` =
  standard deviation of the absolute errors; `error_sd` = standard deviation of the signed error.
- DTW distance (thesis Table 4.5, D_W): dynamic time warping between the measured and estimated force
  of one trial within one phase, cost |a_i - b_j| summed along the optimal warping path (steps
  (1,0), (0,1), (1,1), no window); averaged over trials.
- Bhattacharyya distance (D_B): between the distributions of measured and estimated force values of
  one trial within one phase, each taken as a normal distribution:
  D_B = ¼·ln(¼·(σ₁²/σ₂² + σ₂²/σ₁² + 2)) + ¼·(μ₁-μ₂)²/(σ₁²+σ₂²), variances floored at 1e-4 N² (a 0.01 N resolution), so a flat phase does not blow up; averaged
  over trials.
- `--nonzero` (thesis 4.6): only frames whose measured force is not zero are scored.

DTW is a small vectorised implementation (anti-diagonal sweep): the phases are at most a few
hundred frames, and it keeps a compiled dependency out of the install.
"""

import numpy as np

PHASES = ("grasping", "holding", "releasing")


def regression(true, pred) -> dict:
    true, pred = np.asarray(true, dtype=np.float64), np.asarray(pred, dtype=np.float64)
    keep = ~(np.isnan(true) | np.isnan(pred))
    true, pred = true[keep], pred[keep]
    if len(true) == 0:
        return {"n": 0}
    error = pred - true
    squared, absolute = error**2, np.abs(error)
    mse = float(squared.mean())
    spread = float(true.max() - true.min())
    total = float(((true - true.mean()) ** 2).sum())
    return {
        "n": int(len(true)),
        "mse": mse,
        "rmse": float(np.sqrt(mse)),
        "mae": float(absolute.mean()),
        "rmse_pct_range": float(100 * np.sqrt(mse) / spread) if spread > 0 else float("nan"),
        "mse_sd": float(squared.std()),
        "mae_sd": float(absolute.std()),
        "error_sd": float(error.std()),
        "r2": float(1 - squared.sum() / total) if total > 0 else float("nan"),
    }


def dtw_distance(a, b) -> float:
    """DTW distance with cost |a_i - b_j| (vectorised over anti-diagonals)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    n, m = len(a), len(b)
    if n == 0 or m == 0:
        return float("nan")
    cost = np.abs(a[:, None] - b[None, :])
    total = np.full((n + 1, m + 1), np.inf)
    total[0, 0] = 0.0
    for k in range(2, n + m + 1):
        i = np.arange(max(1, k - m), min(n, k - 1) + 1)
        j = k - i
        best = np.minimum(np.minimum(total[i - 1, j - 1], total[i - 1, j]), total[i, j - 1])
        total[i, j] = cost[i - 1, j - 1] + best
    return float(total[n, m])


VARIANCE_FLOOR_N2 = 1e-4  # D_B's floor on each variance (a 0.01 N resolution): a flat phase does not blow up
NONZERO_N = 1e-9  # --nonzero scores only frames whose true force exceeds this


def bhattacharyya(a, b, floor: float = VARIANCE_FLOOR_N2) -> float:
    """Bhattacharyya distance between normal fits of two samples."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if len(a) == 0 or len(b) == 0:
        return float("nan")
    va, vb = max(a.var(), floor), max(b.var(), floor)
    return float(0.25 * np.log(0.25 * (va / vb + vb / va + 2)) + 0.25 * (a.mean() - b.mean()) ** 2 / (va + vb))


def force_rows(trial, phase, true, pred, *, nonzero=False, per_trial=True, series=None) -> list:
    """(scope, metric, value) rows: overall, per phase, per trial; DTW and D_B per phase (mean over
    time series). `series`: which frames form one time series (default: the trial; cross-validation
    repeats predict a trial once per seed, and each prediction is a series of its own)."""
    trial = np.asarray(trial, dtype=object)
    series = trial if series is None else np.asarray(series, dtype=object)
    phase = np.asarray([p if p is not None else "none" for p in phase], dtype=object)
    true, pred = np.asarray(true, dtype=np.float64), np.asarray(pred, dtype=np.float64)
    keep = ~np.isnan(true)
    if nonzero:
        keep &= np.abs(true) > NONZERO_N
    trial, series, phase, true, pred = trial[keep], series[keep], phase[keep], true[keep], pred[keep]
    rows = []

    def add(scope, figures):
        rows.extend((scope, name, float(value)) for name, value in figures.items())

    add("all", regression(true, pred))
    for name in [p for p in PHASES if p in set(phase)] + sorted(set(phase) - set(PHASES) - {"none"}):
        inside = phase == name
        figures = regression(true[inside], pred[inside])
        dtw, bhat = [], []
        for one in dict.fromkeys(series[inside]):
            mask = inside & (series == one)
            dtw.append(dtw_distance(true[mask], pred[mask]))
            bhat.append(bhattacharyya(true[mask], pred[mask]))
        figures["dtw"] = float(np.nanmean(dtw)) if dtw else float("nan")
        figures["bhattacharyya"] = float(np.nanmean(bhat)) if bhat else float("nan")
        add(f"phase:{name}", figures)
    if per_trial:
        for one in dict.fromkeys(trial):
            mask = trial == one
            add(f"trial:{one}", regression(true[mask], pred[mask]))
    return rows


def classification_rows(true, pred, classes) -> list:
    """Accuracy, per-class recall, and the confusion matrix as rows (scope `confusion:TRUE`, metric `pred:PRED`)."""
    true, pred = np.asarray(true, dtype=object), np.asarray(pred, dtype=object)
    rows = [("all", "n", float(len(true))), ("all", "accuracy", float(np.mean(true == pred)) if len(true) else float("nan"))]
    for name in classes:
        mine = true == name
        if mine.any():
            rows.append((f"class:{name}", "recall", float(np.mean(pred[mine] == name))))
        predicted = pred == name
        if predicted.any():
            rows.append((f"class:{name}", "precision", float(np.mean(true[predicted] == name))))
    matrix = confusion(true, pred, classes)
    for i, a in enumerate(classes):
        for j, b in enumerate(classes):
            rows.append((f"confusion:{a}", f"pred:{b}", float(matrix[i, j])))
    return rows


def confusion(true, pred, classes) -> np.ndarray:
    """Counts (n_classes, n_classes): row = true class, column = predicted class."""
    index = {c: i for i, c in enumerate(classes)}
    matrix = np.zeros((len(classes), len(classes)), dtype=np.int64)
    for a, b in zip(true, pred):
        if a in index and b in index:
            matrix[index[a], index[b]] += 1
    return matrix


def fold_summary(rows_per_fold: list, scopes=("all",) + tuple(f"phase:{p}" for p in PHASES)) -> list:
    """Mean and σ over folds of every (scope, metric) found in all folds: rows (scope, metric+'_mean'|'_fold_sd', value)."""
    values = {}
    for rows in rows_per_fold:
        for scope, metric, value in rows:
            if scope in scopes or scope.startswith("class:") or scope == "all":
                values.setdefault((scope, metric), []).append(value)
    out = []
    for (scope, metric), found in values.items():
        found = np.asarray(found, dtype=np.float64)
        out.append((scope, f"{metric}_fold_mean", float(np.nanmean(found)) if np.isfinite(found).any() else float("nan")))
        out.append((scope, f"{metric}_fold_sd", float(np.nanstd(found)) if np.isfinite(found).any() else float("nan")))
    return out


def metrics_table(rows, model: str, extra_meta: dict | None = None):
    import pyarrow as pa

    from neurotac_cli import schema as sch

    schema = sch.set_meta(
        pa.schema([("scope", pa.string()), ("metric", pa.string()), ("value", pa.float64()), ("model", pa.string())]),
        kind="metrics", **(extra_meta or {}),
    )
    return pa.Table.from_arrays(
        [pa.array([r[0] for r in rows], pa.string()), pa.array([r[1] for r in rows], pa.string()),
         pa.array([r[2] for r in rows], pa.float64()), pa.array([model] * len(rows), pa.string())],
        schema=schema,
    )
