"""Scores of force estimates and material predictions.

Definitions (all forces in newtons):
- MSE (N²), RMSE (N), MAE (N); RMSE as % of the force range (max - min of the measured force in
  the scope); R² = 1 - SSE/SST.
- σ, as the thesis's tables give it: `mse_sd` = standard deviation of the squared errors, `mae_sd` =
  standard deviation of the absolute errors; `error_sd` = standard deviation of the signed error.
- DTW distance (thesis Table 4.5, D_W): dynamic time warping between the measured and estimated force
  of one trial (one grasp of a session) within one phase, cost |a_i - b_j| summed along the optimal warping path (steps
  (1,0), (0,1), (1,1), no window); averaged over trials.
- Bhattacharyya distance (D_B): between the distributions of measured and estimated force values of
  one trial (one grasp of a session) within one phase, each taken as a normal distribution:
  D_B = ¼·ln(¼·(σ₁²/σ₂² + σ₂²/σ₁² + 2)) + ¼·(μ₁-μ₂)²/(σ₁²+σ₂²), variances floored at 1e-4 N² (a 0.01 N resolution), so a flat phase does not blow up; averaged
  over trials.
- `--nonzero` (thesis 4.6): only frames whose measured force is not exactly zero are scored (the thesis
  pads trials with zero frames to the longest one); rest frames of a noisy log stay.

DTW is a small vectorised implementation (anti-diagonal sweep): the phases are at most a few
hundred frames, and it keeps a compiled dependency out of the install.
"""

import types

import numpy as np

from neurotac_cli.errors import NeurotacError, UsageError
from neurotac_cli.ops.phases import rest_block, rest_levels, slow_noise, step_noise

PHASES = ("grasping", "holding", "releasing")



def check_nonzero(nonzero: bool, classifier: bool) -> None:
    """`--nonzero` scores a force model's frames of non-zero force; a classifier has none to leave out."""
    if nonzero and classifier:
        raise UsageError("--nonzero leaves out frames of no force from a force model's scores; a classifier is scored on whole trials")


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


def nonzero_frames(true) -> np.ndarray:
    """The frames `--nonzero` scores: a measured force other than zero (NaN: none measured, not scored)."""
    return np.abs(np.asarray(true, dtype=np.float64)) > NONZERO_N


def bhattacharyya(a, b, floor: float = VARIANCE_FLOOR_N2) -> float:
    """Bhattacharyya distance between normal fits of two samples."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if len(a) == 0 or len(b) == 0:
        return float("nan")
    va, vb = max(a.var(), floor), max(b.var(), floor)
    return float(0.25 * np.log(0.25 * (va / vb + vb / va + 2)) + 0.25 * (a.mean() - b.mean()) ** 2 / (va + vb))


def force_rows(trial, phase, true, pred, *, nonzero=False, per_trial=True, series=None, whole=True) -> list:
    """(scope, metric, value) rows: overall, per phase, per trial; DTW and D_B per phase (mean over
    time series). `series`: which frames form one time series (default: the trial; cross-validation
    repeats predict a trial once per seed, and each prediction is a series of its own). `whole`: the
    frames are all that is scored (not one fold of several), so nothing left by --nonzero is refused."""
    trial = np.asarray(trial, dtype=object)
    series = trial if series is None else np.asarray(series, dtype=object)
    phase = np.asarray([p if p is not None else "none" for p in phase], dtype=object)
    true, pred = np.asarray(true, dtype=np.float64), np.asarray(pred, dtype=np.float64)
    keep = ~np.isnan(true)
    unforced = int(np.count_nonzero(~keep))  # frames without a measured force: left out, and said (scoring.summary)
    if nonzero:
        keep &= nonzero_frames(true)
        if whole and len(keep) and not keep.any():
            raise NeurotacError("--nonzero: no frame has a measured force other than zero, so nothing is left to score")
    trial, series, phase, true, pred = trial[keep], series[keep], phase[keep], true[keep], pred[keep]
    rows = []

    def add(scope, figures):
        rows.extend((scope, name, float(value)) for name, value in figures.items())

    add("all", regression(true, pred))
    if unforced:
        rows.append(("all", "unforced_frames", float(unforced)))
    for name in [p for p in PHASES if p in set(phase)] + sorted(set(phase) - set(PHASES) - {"none"}):
        inside = phase == name
        figures = regression(true[inside], pred[inside])
        dtw, bhat = [], []
        for one in dict.fromkeys(series[inside]):
            mask = inside & (series == one)
            dtw.append(dtw_distance(true[mask], pred[mask]))
            bhat.append(bhattacharyya(true[mask], pred[mask]))
        figures["dtw"], figures["bhattacharyya"] = _mean_of_known(dtw), _mean_of_known(bhat)
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
    unlabelled = np.array([value is None for value in true], dtype=bool)
    unknown = ~np.isin(true, np.asarray(list(classes), dtype=object)) & ~unlabelled
    if unknown.any():  # trials of a class the classifier cannot name: counted as wrong, and said so
        rows.append(("all", "unknown_class", float(unknown.sum())))
        rows += [(f"unknown:{name}", "n", float(np.sum(true == name))) for name in dict.fromkeys(true[unknown].tolist())]
    if unlabelled.any():
        rows.append(("all", "unlabelled", float(unlabelled.sum())))
    # a class the classifier cannot name has a recall too (0): a fold's mean over folds must not skip the folds that lack it
    for name in list(classes) + list(dict.fromkeys(true[unknown].tolist())):
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


# counts a fold's rows hold only where they are not 0: a fold without one counts 0 in their mean over folds
COUNTED_WHERE_FOUND = ("unforced_frames", "unknown_class", "unlabelled", "rest_loaded_frames", "rest_loaded_max")


def fold_summary(rows_per_fold: list, scopes=("all",) + tuple(f"phase:{p}" for p in PHASES)) -> list:
    """Mean and σ over the folds that have it of every (scope, metric) (a count of `COUNTED_WHERE_FOUND`:
    over every fold): rows (scope, metric+'_fold_mean'|'_fold_sd', value)."""
    values = {}
    for rows in rows_per_fold:
        for scope, metric, value in rows:
            if scope in scopes or scope.startswith("class:") or scope == "all":
                values.setdefault((scope, metric), []).append(value)
    for (scope, metric), found in values.items():
        if metric in COUNTED_WHERE_FOUND:
            found += [0.0] * (len(rows_per_fold) - len(found))
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


# ---------------------------------------------------------------- sessions
#
# A session is one long trial of many grasps. Besides the figures above it is scored on:
# - `contact_rmse`: RMSE over the frames whose true phase is not none (the grasps themselves), and
#   `contact_rmse_constant`, that of the best constant there (their true mean: their standard deviation);
# - rest: frames whose true phase is none (no contact, the true force zero): mean and max |estimate|
#   (`rest_mean_abs`, `rest_max_abs`, N), and as % of the force range (`rest_mean_abs_pct_range`);
# - drift: the least-squares slope of |estimate| at rest against time, per session, in N per minute
#   (`drift_n_per_min`: the mean over sessions; `drift_pct_range_per_min` as % of the range);
# - per grasp (`grasp` column, -1 or null between grasps): RMSE and MAE of each grasp's frames (scope `grasp:TRIAL/G`), and their
#   mean over grasps in scope `all` (`grasp_rmse_mean`);
# - contact: true contacts are runs of frames whose phase is not none, detected ones runs of
#   `contact_pred`; a detection that overlaps a true contact not yet matched is a hit (F1 over
#   contacts, `contact_f1`), its onset latency the frames from the true onset (`contact_onset_frames_*`,
#   mean, median, max, min; `contact_within_2`: the share of hits within 2 frames), and from its true end
#   to the found end (`contact_end_frames_mean`, `_median`, `_max`: a contact that runs on after the
#   release); `contact_frame_f1` per frame;
# - slip (where the table has a `slip` truth column): the same for runs of `slip` and `slip_pred`,
#   latency in ms (`slip_latency_ms_*`, between the frames' start times `t`; `slip_within_20`; `slip_end_ms_*`).

REST_PHASES = (None, "none")


def runs(flags) -> list[tuple[int, int]]:
    """(start, end) index pairs, end exclusive, of the runs of True in a boolean sequence."""
    flags = np.asarray(flags, dtype=bool)
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def match_runs(true_runs, found_runs) -> list[tuple[int, int]]:
    """Pairs (true index, found index): each found run matched to the first unmatched true run it overlaps."""
    pairs, used = [], set()
    for j, (a, b) in enumerate(found_runs):
        for i, (c, d) in enumerate(true_runs):
            if i not in used and a < d and c < b:
                pairs.append((i, j))
                used.add(i)
                break
    return pairs


SLIP_TIMING = types.MappingProxyType({"units": "ms", "timing": "latency", "tolerance": 20.0})  # slips: ms from their start, within 20


def detection_figures(true_flags_per_session, found_flags_per_session, name: str, unit: float = 1.0, units="frames",
                      timing="onset", tolerance: float = 2.0, clocks_per_session=None) -> dict:
    """F1 over runs, onset latency (`{name}_{timing}_{units}_*`: in frames x `unit`, or, with
    `clocks_per_session`, in each frame's clock reading x `unit`; the share of hits within `tolerance`
    of the true onset), the same from the true end to the found end (`{name}_end_{units}_*`), and F1
    over frames, pooled over sessions. Mean, median and extremes: one contact merged with the next
    moves the mean by its whole length, the median not."""
    hits = n_true = n_found = 0
    latency, ends, tp_frames, true_frames, found_frames = [], [], 0, 0, 0
    clocks_per_session = clocks_per_session if clocks_per_session is not None else [None] * len(true_flags_per_session)
    for truth, found, clock in zip(true_flags_per_session, found_flags_per_session, clocks_per_session):
        truth, found = np.asarray(truth, dtype=bool), np.asarray(found, dtype=bool)
        clock = np.arange(len(truth)) if clock is None else np.asarray(clock, dtype=np.float64)
        true_runs, found_runs = runs(truth), runs(found)
        pairs = match_runs(true_runs, found_runs)
        hits, n_true, n_found = hits + len(pairs), n_true + len(true_runs), n_found + len(found_runs)
        latency += [(clock[found_runs[j][0]] - clock[true_runs[i][0]]) * unit for i, j in pairs]
        ends += [(clock[found_runs[j][1] - 1] - clock[true_runs[i][1] - 1]) * unit for i, j in pairs]
        tp_frames += int((truth & found).sum())
        true_frames += int(truth.sum())
        found_frames += int(found.sum())
    f1 = lambda tp, t, f: 2 * tp / (t + f) if t + f else float("nan")  # noqa: E731
    latency = np.asarray(latency, dtype=np.float64)
    figures = {f"{name}_f1": f1(hits, n_true, n_found), f"{name}_true": n_true, f"{name}_found": n_found, f"{name}_hits": hits,
               f"{name}_frame_f1": f1(tp_frames, true_frames, found_frames)}
    if len(latency):
        ends, stem = np.asarray(ends, dtype=np.float64), f"{name}_{timing}_{units}"
        figures.update({f"{stem}_mean": float(latency.mean()), f"{stem}_median": float(np.median(latency)),
                        f"{stem}_max": float(latency.max()), f"{stem}_min": float(latency.min()),
                        f"{name}_within_{tolerance:g}": float(np.mean(np.abs(latency) <= tolerance)),
                        f"{name}_end_{units}_mean": float(ends.mean()), f"{name}_end_{units}_median": float(np.median(ends)),
                        f"{name}_end_{units}_max": float(ends.max())})
    return figures


def session_rows(trial, frame, t_us, phase, true, pred, *, grasp=None, contact_pred=None, slip=None, slip_pred=None) -> list:
    """(scope, metric, value) rows scoring sessions (see the block comment above); scope `all`, `grasp:...`."""
    trial, phase = np.asarray(trial, dtype=object), np.asarray(phase, dtype=object)
    t_us, true, pred = np.asarray(t_us, dtype=np.float64), np.asarray(true, dtype=np.float64), np.asarray(pred, dtype=np.float64)
    order = np.lexsort((np.asarray(frame), trial))
    sessions = [order[trial[order] == one] for one in dict.fromkeys(trial[order])]
    rest = np.isin(phase, REST_PHASES)
    known = ~np.isnan(true)
    spread = float(np.nanmax(true) - np.nanmin(true)) if known.any() else float("nan")
    pct = (lambda v: 100 * v / spread) if spread > 0 else (lambda v: float("nan"))
    rows = []
    at_rest = np.abs(pred[rest])
    slopes = [_slope(t_us[idx][rest[idx]] / 60e6, np.abs(pred[idx][rest[idx]])) for idx in sessions]
    slopes = [s for s in slopes if np.isfinite(s)]
    figures = {"rest_frames": int(rest.sum())}
    # the force's rest level and noise as `ops.phases.label_session` reads them: a log need not read 0 N at rest
    steps = np.concatenate([np.diff(true[idx][known[idx]]) for idx in sessions]) if sessions else np.zeros(0)
    steady = step_noise(steps)
    noise = np.full(len(true), steady)
    above = np.zeros(len(true))
    for idx in sessions:  # each session's own rest level, which a drifting sensor moves, over its frames' period
        period = float(np.median(np.diff(t_us[idx]))) if len(idx) > 1 else None
        level = np.nan_to_num(true[idx] - rest_levels(true[idx], block=rest_block(period)))
        slow = slow_noise(true[idx], level, rest[idx], steady, rest_block(period))
        if slow is not None:  # its rest levels, as the labels read them
            noise[idx], level = slow, np.nan_to_num(true[idx] - rest_levels(true[idx], block=rest_block(period), noise=slow))
        above[idx] = np.abs(level)
    loaded = rest & known & (above > np.maximum(REST_FORCE_SHARE * spread, REST_FORCE_NOISE * noise))
    if loaded.any():  # frames at rest by their phase that carry force: phases not a session's
        figures.update(rest_loaded_frames=int(loaded.sum()), rest_loaded_max=float(above[loaded].max()))
    touching = ~rest & known
    if touching.any():  # the grasps' own frames: comparable between a session and its grasps cut into trials
        figures["contact_rmse"] = regression(true[touching], pred[touching])["rmse"]
        # the best constant in hindsight (the true mean in contact): a model near it has learnt little
        figures["contact_rmse_constant"] = float(np.std(true[touching]))
    if len(at_rest):
        figures.update(rest_mean_abs=float(at_rest.mean()), rest_max_abs=float(at_rest.max()),
                       rest_mean_abs_pct_range=pct(float(at_rest.mean())))
    if slopes:
        figures.update(drift_n_per_min=float(np.mean(slopes)), drift_max_abs_n_per_min=float(np.max(np.abs(slopes))),
                       drift_pct_range_per_min=pct(float(np.mean(slopes))))
    if grasp is not None:
        figures.update(_grasp_rows(rows, trial, np.asarray(grasp, dtype=np.float64), true, pred))
    if contact_pred is not None:
        contact_pred = np.asarray(contact_pred, dtype=bool)
        figures.update(detection_figures([~rest[idx] for idx in sessions], [contact_pred[idx] for idx in sessions], "contact"))
    if slip is not None and slip_pred is not None:
        slip, slip_pred = np.asarray(slip, dtype=bool), np.asarray(slip_pred, dtype=bool)
        figures.update(detection_figures([slip[idx] for idx in sessions], [slip_pred[idx] for idx in sessions], "slip", unit=1 / 1000,
                                         clocks_per_session=[t_us[idx] for idx in sessions], **SLIP_TIMING))
    rows[:0] = [("all", name, float(value)) for name, value in figures.items()]
    return rows


# A frame at rest whose true force lies above the rest level (the 5th percentile) by this share of the
# range, and by this many times the force's noise (s.d. of its frame-to-frame steps, robustly), is
# loaded: its phase is not a session's.
REST_FORCE_SHARE, REST_FORCE_NOISE = 0.1, 10.0


def _slope(x, y) -> float:
    if len(x) < 2 or np.ptp(x) <= 0:
        return float("nan")
    return float(np.polyfit(x, y, 1)[0])


def _grasp_rows(rows, trial, grasp, true, pred) -> dict:
    """Per-grasp RMSE / MAE rows appended to `rows`; returns their mean over grasps."""
    rmse = []
    inside = (np.nan_to_num(grasp, nan=-1.0) >= 0) & ~np.isnan(true)  # -1 or null: between grasps
    keys = dict.fromkeys(zip(trial[inside], grasp[inside].astype(int)))
    for one, index in keys:
        mask = inside & (trial == one) & (grasp == index)
        figures = regression(true[mask], pred[mask])
        rmse.append(figures["rmse"])
        rows += [(f"grasp:{one}/{index}", "rmse", figures["rmse"]), (f"grasp:{one}/{index}", "mae", figures["mae"])]
    return {"grasp_rmse_mean": float(np.mean(rmse)), "grasp_rmse_max": float(np.max(rmse)), "grasps": len(rmse)} if rmse else {}


def _mean_of_known(values: list) -> float:
    """The mean of the values that are not NaN; NaN (and no numpy warning) where none is."""
    known = np.asarray(values, dtype=np.float64)
    known = known[~np.isnan(known)]
    return float(known.mean()) if len(known) else float("nan")
