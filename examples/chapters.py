"""Write one chapter's reproduced tables and figures into a results page, beside the thesis's numbers.

    python examples/chapters.py ch3 OUT/ch3 docs/results.md --figures docs/results

Reads the metrics tables the chapter's script left in OUT/chN (written by `neurotac eval --metrics`)
and replaces the text between `<!-- results:chN:start -->` and `<!-- results:chN:end -->` in the page
(creating the page or the section when missing). Everything else in the page is left as it is.
Figures are PNGs in --figures, linked relative to the page.

Metrics file names: `NAME.metrics.parquet`, or `NAME@key=value,key=value.metrics.parquet` for one grid
point (so a grid can be run point by point, each point a cross-validated study of its own).
"""

import argparse
import math
import os
import pathlib
import re
import sys

import pyarrow.parquet as pq

# ------------------------------------------------------------------------------------------------
# The thesis's published numbers (chapters 3.7, 4.6, 5.5).

THESIS_TDNN_VAL = {  # Table 3.1: mean MSE over 48 leave-one-out folds on each fold's validation set
    1: [0.23, 0.19, 0.18, 0.19, 0.20, 0.18, 0.16, 0.16],
    2: [0.21, 0.19, 0.16, 0.17, 0.17, 0.17, 0.17, 0.17],
    3: [0.19, 0.20, 0.18, 0.18, 0.16, 0.17, 0.17, 0.17],
    4: [0.20, 0.19, 0.16, 0.17, 0.18, 0.17, 0.17, 0.15],
    5: [0.20, 0.16, 0.20, 0.18, 0.18, 0.16, 0.17, 0.16],
}
THESIS_TDNN_TEST = {  # Table 3.2: mean MSE over 48 leave-one-out folds, k layers x n units
    1: [0.16, 0.24, 0.15, 0.22, 0.19, 0.16, 0.24, 0.15],
    2: [0.17, 0.16, 0.16, 0.16, 0.17, 0.18, 0.15, 0.35],
    3: [0.18, 0.18, 0.16, 0.17, 0.16, 0.16, 0.16, 0.16],
    4: [0.18, 0.17, 0.16, 0.16, 0.16, 0.17, 0.19, 0.16],
    5: [0.18, 0.16, 0.24, 0.17, 0.20, 0.15, 0.24, 0.18],
}
THESIS_TDNN_UNITS = [5, 10, 15, 20, 25, 30, 35, 40]
THESIS_GP_MSE = 0.17
THESIS_MATERIAL_VAL = {  # Table 3.3: accuracy (%) on the validation data
    1: [80.21, 76.56, 83.33, 84.38, 85.94, 83.85],
    2: [70.31, 81.25, 84.38, 85.94, 86.98, 90.10],
    3: [64.06, 77.60, 81.77, 85.42, 86.98, 88.54],
    4: [67.19, 77.60, 78.65, 84.38, 84.90, 89.06],
    5: [60.42, 68.75, 76.56, 81.25, 86.46, 90.10],
    6: [60.94, 69.79, 74.48, 81.77, 85.42, 86.46],
}
THESIS_MATERIAL_TEST = {  # Table 3.4: accuracy (%) on the left-out trial over 48 folds
    1: [70.83, 68.75, 62.50, 70.83, 62.50, 68.75],
    2: [58.33, 62.50, 68.75, 75.00, 60.42, 79.17],
    3: [50.00, 58.33, 56.25, 72.92, 72.92, 77.08],
    4: [60.42, 58.33, 72.92, 68.75, 60.42, 75.00],
    5: [50.00, 45.83, 54.17, 62.50, 68.75, 72.92],
    6: [39.58, 58.33, 66.67, 58.33, 70.83, 75.00],
}
THESIS_MATERIAL_UNITS = [5, 10, 15, 20, 25, 30]
THESIS_FORCE_ONLY_ACCURACY = 50.0
THESIS_RECALL = {"foam": 63.6, "rubber": 77.8, "silicone": 78.6, "steel": 92.9}  # Fig. 3.13

THESIS_TABLE_4_3 = {  # MAE (σ), MSE (σ) on the test trials, non-zero force only
    "tdnn": (0.398, 0.410, 0.345, 0.713),
    "lstm": (0.301, 0.234, 0.160, 0.261),
    "cnnlstm": (0.291, 0.234, 0.157, 0.259),
    "convlstm": (0.278, 0.225, 0.145, 0.237),
}
THESIS_TABLE_4_4 = {  # per phase: MSE, σ for grasping, holding, releasing
    "tdnn": (0.309, 0.572, 0.190, 0.426, 0.490, 0.425),
    "lstm": (0.065, 0.053, 0.092, 0.065, 0.537, 0.407),
    "cnnlstm": (0.063, 0.051, 0.088, 0.064, 0.527, 0.386),
    "convlstm": (0.064, 0.055, 0.082, 0.063, 0.485, 0.372),
}
THESIS_TABLE_4_5 = {  # per phase: Bhattacharyya D_B, DTW D_W for grasping, holding, releasing
    "lstm": (0.102, 1.711, 2.278, 3.811, 0.622, 2.282),
    "cnnlstm": (0.009, 1.642, 2.483, 3.588, 0.061, 2.204),
    "convlstm": (0.009, 1.678, 1.175, 3.258, 0.055, 2.346),
}
THESIS_HELD_OUT = (0.159, 0.385)  # ConvLSTM trained on 8 and 16 mm bolts, tested on 12 mm: MSE, MAE

THESIS_CH5 = {  # method: (mean MSE over 10 seeds, σ) on the medium bolt; None where only described
    "none": (7.89, 2.09),
    "rot45": None,  # "a slight improvement"
    "resize": (6.05, 1.04),
    "noise": None,  # "a slight improvement of 10% in MSE and standard deviation"
    "fs-1": (5.51, 0.41),
    "tes-2(0.50)": (5.98, 0.53),
    "independent": (5.71, 1.06),
    "hybrid": (7.20, 1.22),
}
PHASES = ("grasping", "holding", "releasing")


# ------------------------------------------------------------------------------------------------
# Reading metrics tables


def read_metrics(path) -> dict:
    """{scope: {metric: value}} of one metrics table."""
    table = pq.read_table(path)
    figures: dict = {}
    for scope, metric, value in zip(*(table.column(c).to_pylist() for c in ("scope", "metric", "value"))):
        figures.setdefault(scope, {})[metric] = value
    return figures


def studies(folder) -> dict:
    """{(name, ((key, value), ...)): figures} for every metrics file in folder. A grid point comes
    from the file name (`NAME@k=v,...`) or, for a table holding a whole grid, from its extra columns
    (one column per grid parameter beside scope, metric, value, model)."""
    found = {}
    for path in sorted(pathlib.Path(folder).glob("*.metrics.parquet")):
        stem = path.name[: -len(".metrics.parquet")]
        name, _, point = stem.partition("@")
        params = tuple((k, _number(v)) for k, _, v in (part.partition("=") for part in point.split(",") if part))
        table = pq.read_table(path)
        extra = [c for c in table.schema.names if c not in ("scope", "metric", "value", "model")]
        if not extra:
            found[(name, params)] = read_metrics(path)
            continue
        columns = {c: table.column(c).to_pylist() for c in (*extra, "scope", "metric", "value")}
        for i in range(table.num_rows):
            key = (name, params + tuple((c, columns[c][i]) for c in extra))
            found.setdefault(key, {}).setdefault(columns["scope"][i], {})[columns["metric"][i]] = columns["value"][i]
    return found


def _number(text):
    try:
        return int(text)
    except ValueError:
        try:
            return float(text)
        except ValueError:
            return text


def get(figures, scope, metric, default=math.nan):
    return (figures or {}).get(scope, {}).get(metric, default)


def fmt(value, digits=3):
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    return f"{value:.{digits}f}"


def md_table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def grid(found, name, row_key="layers", col_key="units"):
    """{(row, col): figures} of a grid study."""
    points = {}
    for (study, params), figures in found.items():
        if study == name:
            values = dict(params)
            if row_key in values and col_key in values:
                points[(values[row_key], values[col_key])] = figures
    return points


def grid_table(points, metric, scale=1.0, digits=3, thesis=None, thesis_cols=None, mark=None) -> str:
    """A k x n table; each cell `ours (thesis)` where the thesis has that cell. `mark`: "lowest" or
    "highest" puts our best cell in bold and the thesis's best (over the cells shown) in italics."""
    rows_k = sorted({k for k, _ in points})
    cols_n = sorted({n for _, n in points})

    def thesis_value(k, n):
        if thesis and k in thesis and thesis_cols and n in thesis_cols:
            return thesis[k][thesis_cols.index(n)]
        return None

    pick = {"lowest": min, "highest": max}.get(mark)
    ours_best = theirs_best = None
    if pick:
        ours = {key: get(figures, "all", metric) for key, figures in points.items()}
        ours = {key: value for key, value in ours.items() if not math.isnan(value)}
        ours_best = pick(ours, key=ours.get) if ours else None
        theirs = {(k, n): thesis_value(k, n) for k in rows_k for n in cols_n if thesis_value(k, n) is not None}
        theirs_best = pick(theirs.values()) if theirs else None
    body = []
    for k in rows_k:
        cells = [f"k={k}"]
        for n in cols_n:
            cell = fmt(get(points.get((k, n)), "all", metric) * scale, digits)
            if ours_best == (k, n):
                cell = f"**{cell}**"
            theirs = thesis_value(k, n)
            if theirs is not None:
                shown = f"{theirs:.{digits}f}"
                cell += f" (*{shown}*)" if theirs == theirs_best else f" ({shown})"
            cells.append(cell)
        body.append(cells)
    return md_table(["k \\ n"] + [f"n={n}" for n in cols_n], body)


def best_point(points, metric, lowest=True):
    scored = [(get(f, "all", metric), key) for key, f in points.items() if not math.isnan(get(f, "all", metric))]
    if not scored:
        return None, math.nan
    value, key = (min if lowest else max)(scored)
    return key, value


def first_frame_note(folder, shifts=False) -> str:
    """A sentence when the first frame of the grasps holds a large share of all events (the LED
    switch-off's OFF spike lands in frame 0 when sync puts t0 at the switch-off), measured on the
    chapter's frames."""
    path = pathlib.Path(folder) / "frames.parquet"
    if not path.is_file():
        return ""
    import numpy as np

    from neurotac_cli import schema as sch

    table = pq.read_table(path, columns=["frame", "counts"])
    counts = sch.counts_numpy(table.column("counts")).reshape(table.num_rows, -1).sum(axis=1, dtype=np.int64)
    first = counts[table.column("frame").to_numpy() == 0].sum()
    share = first / max(int(counts.sum()), 1)
    if share < 0.2:
        return ""
    note = (f" Frame 0 of the grasps holds {100 * share:.0f}% of all their events: the LED switch-off's OFF "
            "spike just after t0 kept in the trials (`sync --keep-led`), which frame counts; in the thesis the blink only marks the start of a recording (3.6.1)")
    if shifts:
        note += ", and here frame shifts to the left push the spike out of the sequence, which changes what those methods do"
    return note + "."


def ratio(ours, theirs) -> str:
    if ours != ours or not theirs:
        return "–"
    share = ours / theirs
    return f"{share:.2f}×" if share < 0.1 else f"{share:.1f}×"


def figure_link(page, figures_dir, name, caption) -> str | None:
    """A linked PNG with its caption; None when the chapter's script did not draw it."""
    path = pathlib.Path(figures_dir) / name
    if not path.is_file():
        return None
    relative = os.path.relpath(path, pathlib.Path(page).parent)
    return f"![{caption}]({relative})\n\n*{caption}*\n"


def section_text(parts) -> str:
    """A chapter's lines, figures that were not drawn left out."""
    return "\n".join(part for part in parts if part is not None)


def stamp_tables(body: str, protocol: str) -> str:
    """The protocol line under every table's heading, so a table copied on its own still says how it
    was made (where it departs from the thesis, its seeds, the wall time)."""
    if not protocol:
        return body
    lines = []
    for line in body.split("\n"):
        lines.append(line)
        if line.startswith("#### "):
            lines += ["", f"*{protocol}*"]
    return "\n".join(lines)


def per_seed(figures, metric) -> list:
    """The metric of each seed (repeat) of a study, from its per-fold rows: a fold's value weighted by
    its number of test trials (`n`; one per fold when absent)."""
    seeds: dict = {}
    for scope, values in (figures or {}).items():
        if scope.startswith("fold:") and metric in values:
            repeat = scope[len("fold:"):].split("/")[0]
            weight = values.get("n", 1.0)
            total = seeds.setdefault(repeat, [0.0, 0.0])
            total[0] += weight * values[metric]
            total[1] += weight
    return [value / weight for value, weight in seeds.values() if weight]


def mean_sd(values, scale=1.0, digits=3) -> str:
    """`mean ± σ` over seeds; the mean alone with one seed."""
    import statistics

    if not values:
        return "–"
    mean = statistics.fmean(values) * scale
    if len(values) < 2:
        return fmt(mean, digits)
    return f"{fmt(mean, digits)} ± {fmt(statistics.stdev(values) * scale, digits)}"


def verdict(said, why) -> list:
    """A chapter's closing paragraphs: what we found against the thesis (when anything was), then
    where and why the numbers differ."""
    compared = ["**Compared with the thesis:** " + "; ".join(said) + ".", ""] if said else []
    return compared + ["**Where and why the numbers differ.** " + why, ""]


# ------------------------------------------------------------------------------------------------
# Chapter 3


def chapter3(folder, page, figures_dir, run) -> str:
    found = studies(folder)
    parts = [run, ""]
    tdnn = grid(found, "tdnn")
    if tdnn and best_point(tdnn, "val_mse_fold_mean")[0] is not None:
        key, value = best_point(tdnn, "val_mse_fold_mean")
        parts += [
            "#### TDNN validation error, k layers × n units (thesis Table 3.1)",
            "",
            "Mean over the leave-one-out folds of the MSE (N²) on each fold's validation grasps (drawn per "
            "material from the training grasps; the early-stopping set), with the weights early stopping "
            "restored; the thesis's number in brackets. The thesis selects its architecture on this table. "
            "Lowest in bold (ours) and italics (the thesis's, among the cells shown).",
            "",
            grid_table(tdnn, "val_mse_fold_mean", thesis=THESIS_TDNN_VAL, thesis_cols=THESIS_TDNN_UNITS, mark="lowest"),
            "",
            f"Lowest validation error: k={key[0]}, n={key[1]}: {fmt(value)} N² (thesis: k=4, n=40, 0.15); "
            f"that network's test error: {fmt(get(tdnn[key], 'all', 'mse_fold_mean'))} N².",
            "",
        ]
    if tdnn:
        key, value = best_point(tdnn, "mse_fold_mean")
        parts += [
            "#### TDNN force estimation, k layers × n units (thesis Table 3.2)",
            "",
            "Mean over leave-one-out folds of the MSE (N²) on the left-out grasp; the thesis's number in "
            "brackets. Lowest in bold (ours) and italics (the thesis's, among the cells shown); the "
            "thesis reports the network it chose on Table 3.1 (k=4, n=40: 0.16).",
            "",
            grid_table(tdnn, "mse_fold_mean", thesis=THESIS_TDNN_TEST, thesis_cols=THESIS_TDNN_UNITS, mark="lowest"),
            "",
            f"Lowest: k={key[0]}, n={key[1]}: {fmt(value)} N² (thesis: k=4, n=40, 0.16; lowest cell 0.15).",
            "",
        ]
    gp = found.get(("gp", ()))
    if gp or tdnn:
        rows = []
        for name, figures in (("tdnn (k=4, n=40)", tdnn.get((4, 40))), ("gp", gp), ("deform-gru (ours)", found.get(("deform-gru", ())))):
            if figures:
                thesis = {"tdnn": 0.16, "gp": THESIS_GP_MSE}.get(name.split()[0])
                thesis = "–" if thesis is None else f"{thesis:.2f}"
                rows.append([name, fmt(get(figures, "all", "mse_fold_mean")), fmt(get(figures, "all", "mse_fold_sd")),
                             *(fmt(get(figures, f"phase:{p}", "mse")) for p in PHASES), thesis])
        if rows:
            parts += [
                "#### TDNN and GP (thesis 3.7.1: 0.16 and 0.17)",
                "",
                md_table(["model", "MSE fold mean (N²)", "σ over folds", "MSE grasping", "MSE holding",
                          "MSE releasing", "thesis MSE"], rows),
                "",
            ]
    parts.append(figure_link(page, figures_dir, "ch3-tdnn.png", "TDNN: measured and estimated force, left-out grasps (thesis Fig. 3.9)"))
    parts.append(figure_link(page, figures_dir, "ch3-gp.png", "GP: measured and estimated force, left-out grasps (thesis Fig. 3.10)"))
    material = grid(found, "material-dnn")
    if material and best_point(material, "val_accuracy_fold_mean", lowest=False)[0] is not None:
        key, value = best_point(material, "val_accuracy_fold_mean", lowest=False)
        parts += [
            "#### Material DNN validation accuracy, k layers × n units (thesis Table 3.3)",
            "",
            "Mean over the folds (the protocol line names them) of the accuracy (%) on each fold's validation grasps, the "
            "thesis's number in brackets; highest in bold (ours) and italics (the thesis's).",
            "",
            grid_table(material, "val_accuracy_fold_mean", scale=100, digits=1, thesis=THESIS_MATERIAL_VAL,
                       thesis_cols=THESIS_MATERIAL_UNITS, mark="highest"),
            "",
            f"Highest: k={key[0]}, n={key[1]}: {fmt(100 * value, 1)}% (thesis: k=2 and k=5, n=30, 90.10%).",
            "",
        ]
    if material:
        key, value = best_point(material, "accuracy", lowest=False)
        parts += [
            "#### Material DNN, k layers × n units (thesis Table 3.4)",
            "",
            "Accuracy (%) on the left-out grasps over the folds; the thesis's number in brackets.",
            "",
            grid_table(material, "accuracy", scale=100, digits=1, thesis=THESIS_MATERIAL_TEST,
                       thesis_cols=THESIS_MATERIAL_UNITS, mark="highest"),
            "",
            f"Best: k={key[0]}, n={key[1]}: {fmt(100 * value, 1)}% (thesis: k=2, n=30, 79.17%).",
            "",
        ]
    chosen = found.get(("material-dnn-k2-n30", ())) or (material.get((2, 30)) if material else None)
    force_only = found.get(("material-force", ()))
    rows = []
    for name, figures, thesis in (("material-dnn (k=2, n=30), events", chosen, "79.17"),
                                  ("material-force (force only)", force_only, f"{THESIS_FORCE_ONLY_ACCURACY:.2f}"),
                                  ("material-curves (ours), events", found.get(("material-curves", ())), "–"),
                                  ("material-timing (ours), events", found.get(("material-timing", ())), "–")):
        if figures:
            recalls = [fmt(100 * get(figures, f"class:{c}", "recall"), 1) for c in THESIS_RECALL]
            rows.append([name, fmt(100 * get(figures, "all", "accuracy"), 1), mean_sd(per_seed(figures, "accuracy"), 100, 1),
                         thesis, *recalls])
    if rows:
        parts += [
            "#### Events against the force sensor alone (thesis 3.7.2)",
            "",
            "Accuracy pooled over every seed's out-of-fold predictions, and its mean ± σ over seeds.",
            "",
            md_table(["classifier", "accuracy (%)", "per seed (%)", "thesis (%)", *(f"recall {c}" for c in THESIS_RECALL)], rows),
            "",
            "Thesis recall (Fig. 3.13): " + ", ".join(f"{c} {v}%" for c, v in THESIS_RECALL.items()) + ".",
            "",
        ]
    parts.append(figure_link(page, figures_dir, "ch3-confusion.png", "Material DNN confusion matrix over all folds (thesis Fig. 3.13)"))
    said = []
    if tdnn and best_point(tdnn, "val_mse_fold_mean")[0] is not None:
        key, value = best_point(tdnn, "val_mse_fold_mean")
        said.append(f"our lowest TDNN validation error is at k={key[0]}, n={key[1]}, {fmt(value)} N² "
                    f"(thesis: k=4, n=40, 0.15)")
    if tdnn:
        key, value = best_point(tdnn, "mse_fold_mean")
        said.append(f"our lowest TDNN error is {fmt(value)} N² ({ratio(value, 0.15)} the thesis's lowest, 0.15)")
        if gp:
            ours_gp = get(gp, "all", "mse_fold_mean")
            order = "below" if ours_gp < value else "above"
            said.append(f"the GP's {fmt(ours_gp)} N² lies {order} it (thesis: GP 0.17 just above TDNN 0.16)")
    if material:
        key, value = best_point(material, "accuracy", lowest=False)
        said.append(f"the best material DNN reaches {fmt(100 * value, 1)}% (thesis 79.17%)")
        if force_only:
            gap = 100 * (value - get(force_only, "all", "accuracy"))
            said.append(f"{abs(gap):.1f} points {'above' if gap >= 0 else 'below'} the force-only classifier (thesis: 29.17 above)")
    for name in ("material-curves", "material-timing"):
        if found.get((name, ())):
            figures = found[(name, ())]
            worst = min(THESIS_RECALL, key=lambda c: get(figures, f"class:{c}", "recall", 1.0))
            said.append(f"our {name} reaches {fmt(100 * get(figures, 'all', 'accuracy'), 1)}%, its lowest recall "
                        f"{worst} {fmt(100 * get(figures, f'class:{worst}', 'recall'), 1)}% (thesis DNN 79.17%, lowest recall foam 63.6%)")
    parts += verdict(said, "\n".join([
        "The grasps are simulated (`neurotac simulate --preset ch3`):",
        "the simulator's membrane, DVS thresholds and noise are physical models with handbook parameters,",
        "not the thesis's rig, so event counts per newton and the spread between materials differ, and",
        "no FlexiForce hysteresis beyond the modelled one delays the reference. The thesis trained in",
        "MATLAB (scaled conjugate gradient, Levenberg-Marquardt, Bayesian-optimised GP) in double precision;",
        "we train with Adam in float32 and fit the GP by marginal likelihood with restarts. The thesis",
        "reports MSE with unit N; it is N² here." + first_frame_note(folder),
    ]))
    return section_text(parts)


# ------------------------------------------------------------------------------------------------
# Chapter 4

CH4_MODELS = ("tdnn", "lstm", "cnnlstm", "convlstm", "deform-gru")


SWEEP_MODELS = ("convlstm", "lstm", "cnnlstm")
THESIS_SWEEP_BEST = {"convlstm": 4, "lstm": 6, "cnnlstm": 4}  # Fig. 4.4(a): depth of the lowest validation MSE
SWEEP_COLOURS = {"convlstm": "#1f77b4", "lstm": "#d62728", "cnnlstm": "#ff7f0e"}  # the thesis's blue, red, orange


def layer_sweep(found) -> dict:
    """{model: {layers: figures}} of the `sweep-MODEL` grids."""
    sweep = {}
    for (name, params), figures in found.items():
        if name.startswith("sweep-") and "layers" in dict(params):
            sweep.setdefault(name[len("sweep-"):], {})[dict(params)["layers"]] = figures
    return sweep


def sweep_section(sweep, page, figures_dir) -> list:
    models = [m for m in SWEEP_MODELS if m in sweep] + sorted(set(sweep) - set(SWEEP_MODELS))
    depths = sorted({k for m in models for k in sweep[m]})
    best = {}
    for model in models:
        values = {k: get(f, "all", "val_mse_fold_mean") for k, f in sweep[model].items()}
        values = {k: v for k, v in values.items() if not math.isnan(v)}
        best[model] = min(values, key=values.get) if values else None
    rows = []
    for depth in depths:
        cells = [str(depth)]
        for model in models:
            figures = sweep[model].get(depth)
            value = get(figures, "all", "val_mse_fold_mean")
            cell = f"{fmt(value)} ± {fmt(get(figures, 'all', 'val_mse_fold_sd'))}" if figures else "–"
            cells.append(f"**{cell}**" if best[model] == depth else cell)
            cells.append(fmt(get(figures, "all", "mse")) if figures else "–")
        rows.append(cells)
    header = ["layers"]
    for model in models:
        header += [f"{model} validation MSE (N²)", f"{model} test MSE"]
    draw_sweep(sweep, models, figures_dir)
    chosen = ", ".join(f"{m} {best[m]} layer{'s' if best[m] != 1 else ''} (thesis {THESIS_SWEEP_BEST.get(m, '–')})"
                       for m in models)
    return [
        "#### Validation error against the number of hidden layers (thesis Fig. 4.4(a))",
        "",
        "Mean ± σ over the folds of the MSE on each fold's validation grasps (one per bolt "
        "size, the early-stopping set; every frame with a measured force), at the weights early stopping "
        "restored; the lowest per model in bold. Beside it, the pooled test MSE on the left-out grasps "
        "(non-zero force). The thesis gives this figure as a plot only; it names the depths of its "
        "minima: 4 layers for ConvLSTM and CNNLSTM, 6 for LSTM.",
        "",
        md_table(header, rows),
        "",
        f"Lowest validation error: {chosen}.",
        "",
        figure_link(page, figures_dir, "ch4-layers.png",
                    "Mean validation MSE over folds against hidden layers: ConvLSTM (blue), LSTM (red), CNNLSTM (orange), as thesis Fig. 4.4(a)"),
    ]


def draw_sweep(sweep, models, figures_dir):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(figures_dir, exist_ok=True)
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for index, model in enumerate(models):
        depths = sorted(sweep[model])
        shift = (index - (len(models) - 1) / 2) * 0.06  # side by side, so the error bars stay readable
        means = [get(sweep[model][d], "all", "val_mse_fold_mean") for d in depths]
        sds = [get(sweep[model][d], "all", "val_mse_fold_sd") for d in depths]
        colour = SWEEP_COLOURS.get(model)
        ax.errorbar([d + shift for d in depths], means, yerr=[0 if math.isnan(v) else v for v in sds], marker="o", capsize=3,
                    color=colour, label=model, alpha=0.9)
    ax.set_xlabel("hidden layers")
    ax.set_title("validation error by depth (thesis Fig. 4.4(a))", fontsize=10)
    ax.set_ylabel("validation MSE (N²), mean ± σ over folds")
    ax.set_xticks(sorted({d for m in models for d in sweep[m]}))
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(pathlib.Path(figures_dir) / "ch4-layers.png", dpi=110)
    plt.close(fig)


def chapter4(folder, page, figures_dir, run) -> str:
    found = studies(folder)
    parts = [run, ""]
    sweep = layer_sweep(found)
    if sweep:
        parts += sweep_section(sweep, page, figures_dir)
    models = {name: found[(name, ())] for name in CH4_MODELS if found.get((name, ()))}  # the leave-one-out studies run
    rows = []
    for name, figures in models.items():
        thesis = THESIS_TABLE_4_3.get(name)
        rows.append([
            name, f"{fmt(get(figures, 'all', 'mae'))} ({fmt(get(figures, 'all', 'mae_sd'))})",
            f"{fmt(get(figures, 'all', 'mse'))} ({fmt(get(figures, 'all', 'mse_sd'))})",
            f"{thesis[0]:.3f} ({thesis[1]:.3f})" if thesis else "–", f"{thesis[2]:.3f} ({thesis[3]:.3f})" if thesis else "–",
        ])
    if rows:
        parts += [
            "#### Force estimation on left-out grasps, all phases (thesis Table 4.3)",
            "",
            "Pooled over the out-of-fold predictions of every left-out grasp, non-zero force only (as the "
            "thesis); σ is the standard deviation of the absolute (MAE) and squared (MSE) errors.",
            "",
            md_table(["model", "MAE (σ), N", "MSE (σ), N²", "thesis MAE (σ)", "thesis MSE (σ)"], rows),
            "",
        ]
    rows = []
    for name, figures in models.items():
        thesis = THESIS_TABLE_4_4.get(name)
        cells = [name]
        for i, phase in enumerate(PHASES):
            cells.append(f"{fmt(get(figures, f'phase:{phase}', 'mse'))} ({fmt(get(figures, f'phase:{phase}', 'mse_sd'))})")
            cells.append(f"{thesis[2 * i]:.3f} ({thesis[2 * i + 1]:.3f})" if thesis else "–")
        rows.append(cells)
    if rows:
        header = ["model"]
        for phase in PHASES:
            header += [f"{phase} MSE (σ)", "thesis"]
        parts += ["#### MSE per phase (thesis Table 4.4)", "", md_table(header, rows), ""]
    rows = []
    for name, figures in models.items():
        if name == "tdnn":
            continue
        thesis = THESIS_TABLE_4_5.get(name)
        cells = [name]
        for i, phase in enumerate(PHASES):
            cells.append(fmt(get(figures, f"phase:{phase}", "bhattacharyya_fold_mean", get(figures, f"phase:{phase}", "bhattacharyya"))))
            cells.append(fmt(get(figures, f"phase:{phase}", "dtw_fold_mean", get(figures, f"phase:{phase}", "dtw"))))
            cells.append(f"{thesis[2 * i]:.3f} / {thesis[2 * i + 1]:.3f}" if thesis else "–")
        rows.append(cells)
    if rows:
        header = ["model"]
        for phase in PHASES:
            header += [f"{phase} D_B", f"{phase} D_W", "thesis D_B / D_W"]
        parts += [
            "#### Dynamic time warping and Bhattacharyya distances per phase (thesis Table 4.5)",
            "",
            "Mean over folds; definitions in docs/commands/eval.md.",
            "",
            md_table(header, rows),
            "",
        ]
    held_out = {name: found.get((f"heldout-{name}", ())) for name in CH4_MODELS}
    held_out = {name: figures for name, figures in held_out.items() if figures}
    held = held_out.get("convlstm") or found.get(("heldout", ()))
    if held_out:
        rows = [[name, fmt(get(figures, "all", "mse")), mean_sd(per_seed(figures, "mse")), fmt(get(figures, "all", "mae")),
                 fmt(get(figures, "all", "rmse_pct_range"), 1),
                 *((f"{THESIS_HELD_OUT[0]:.3f}", f"{THESIS_HELD_OUT[1]:.3f}") if name == "convlstm" else ("–", "–"))]
                for name, figures in held_out.items()]
        parts += [
            "#### Held-out object size (thesis 4.6: ConvLSTM trained on 8 and 16 mm, tested on 12 mm)",
            "",
            "Every model trained on the 8 and 16 mm bolts and tested on every 12 mm grasp (non-zero force); "
            "MSE pooled over the seeds' predictions and its mean ± σ over seeds.",
            "",
            md_table(["model", "MSE (N²)", "per seed (N²)", "MAE (N)", "RMSE % of range", "thesis MSE", "thesis MAE"], rows),
            "",
        ]
    parts.append(figure_link(page, figures_dir, "ch4-convlstm.png", "ConvLSTM: measured and estimated force, and per-phase scatter (thesis Fig. 4.5)"))
    ours = {name: get(models[name], "all", "mse") for name in THESIS_TABLE_4_3 if name in models}
    said = []
    if ours:
        ranking = " < ".join(sorted(ours, key=ours.get))
        thesis_ranking = " < ".join(n for n in sorted(THESIS_TABLE_4_3, key=lambda n: THESIS_TABLE_4_3[n][2]) if n in ours)
        said.append(f"by overall MSE our models rank {ranking} (thesis: {thesis_ranking})")
        if "convlstm" in ours:
            said.append(f"our ConvLSTM's {fmt(ours['convlstm'])} N² is {ratio(ours['convlstm'], 0.145)} the thesis's 0.145")
        if "deform-gru" in models:
            mine = get(models["deform-gru"], "all", "mse")
            best = min(ours, key=ours.get)
            said.append(f"ours (deform-gru) scores {fmt(mine)} N², {ratio(mine, ours[best])} the best of the thesis's models here ({best})")
        if held and "convlstm" in ours:
            said.append(f"on the unseen 12 mm bolt it scores {fmt(get(held, 'all', 'mse'))} N², "
                        f"{ratio(get(held, 'all', 'mse'), ours['convlstm'])} its leave-one-out error (thesis: 0.159 against 0.145)")
    parts += verdict(said, "\n".join([
        "Simulated grasps of 8, 12 and 16 mm bolts",
        "(`simulate --preset ch4`) replace the Baxter recordings: the simulated Nano17 reference carries",
        "only the vibration and membrane relaxation the simulator models, and its event counts per",
        "newton follow the simulator's DVS model, not the thesis's camera settings. The networks are the",
        "thesis's architectures in PyTorch (float32, on a CPU unless the run line names a GPU) rather than",
        "Keras; MSE is in N² (the thesis writes N)." + first_frame_note(folder),
    ]))
    return section_text(parts)


# ------------------------------------------------------------------------------------------------
# Chapter 5

CH5_LABELS = {"none": "No augmentation", "rot45": "Rotation 0–45°", "resize": "Resize (1.25 small, 0.83 large)",
              "noise": "Background noise", "independent": "Resize + FS-1, independent",
              "hybrid": "Resize + FS-1, hybrid"}


def ch5_method(name: str) -> str:
    """File stem -> the thesis's method name: fs-1, tes-2(0.50), ..."""
    match = re.fullmatch(r"fs(-?\d+)", name)
    if match:
        return f"fs{int(match.group(1)):+d}"
    match = re.fullmatch(r"tes(-?\d+)_([\d.]+)", name)
    if match:
        return f"tes{int(match.group(1)):+d}({float(match.group(2)):.2f})"
    return name


def chapter5(folder, page, figures_dir, run) -> str:
    found = studies(folder)
    parts = [run, ""]
    results, ours = {}, {}  # the ConvLSTM's studies by training set; deform-gru's (deform-gru@set=NAME)
    for (name, params), figures in found.items():
        mean = get(figures, "all", "mse_fold_mean", get(figures, "all", "mse"))
        sd = get(figures, "all", "mse_fold_sd", math.nan)
        folds = sum(1 for scope in figures if scope.startswith("fold:"))
        if name == "deform-gru":
            ours[dict(params).get("set")] = (mean, sd, folds)
        else:
            results[name] = (mean, sd, folds)
    if not results:
        return "\n".join(parts + ["(no results yet)"])
    order = [n for n in ("none", "rot45", "resize", "noise") if n in results]
    order += sorted((n for n in results if n.startswith("fs")), key=lambda n: int(n[2:]))
    order += sorted((n for n in results if n.startswith("tes")), key=lambda n: (int(n[3:].split("_")[0]), n))
    order += [n for n in ("independent", "hybrid") if n in results]
    baseline = results.get("none", (math.nan,))[0]
    ours_baseline = ours.get("none", (math.nan,))[0]

    def change(mean, base):
        return "–" if not (mean == mean and base == base and base) else f"{(mean / base - 1) * 100:+.0f}%"

    rows = []
    for name in order:
        mean, sd, folds = results[name]
        thesis = THESIS_CH5.get(ch5_method(name))
        row = [CH5_LABELS.get(name, ch5_method(name).upper()), fmt(mean), fmt(sd), folds, change(mean, baseline),
               f"{thesis[0]:.2f} ({thesis[1]:.2f})" if thesis else "–"]
        if ours:
            mine = ours.get(name, (math.nan, math.nan, 0))
            row += [fmt(mine[0]), fmt(mine[1]), change(mine[0], ours_baseline)]
        rows.append(row)
    header = ["method", "ConvLSTM MSE mean (N²)", "σ over seeds", "seeds", "vs none", "thesis mean (σ)"]
    if ours:
        header += ["deform-gru MSE mean (N²)", "σ over seeds", "vs none"]
    parts += [
        "#### Augmentation on the medium bolt (thesis Figs. 5.6–5.8 and 5.11)",
        "",
        "Training on the small and large bolts plus one augmented copy of each grasp per method",
        "validation drawn from the training trials, testing on the medium bolt; mean and σ of the MSE",
        "(N²) over the seeds (one training per seed); the thesis's ConvLSTM and ours (deform-gru) on the same",
        "training sets.",
        "",
        md_table(header, rows),
        "",
    ]
    draw_ch5(results, order, figures_dir)
    parts.append(figure_link(page, figures_dir, "ch5-methods.png", "MSE per augmentation method, mean ± σ over seeds (thesis Figs. 5.6, 5.7, 5.11)"))
    parts.append(figure_link(page, figures_dir, "ch5-tes.png", "Temporal event shifting: MSE by shift j and share ζ (thesis Fig. 5.8)"))
    augmented_only = [n for n in order if n != "none"]
    said = []
    if augmented_only and baseline == baseline:
        best = min(augmented_only, key=lambda n: results[n][0])
        better = [n for n in augmented_only if results[n][0] < baseline]
        said += [f"our best method is {CH5_LABELS.get(best, ch5_method(best).upper())} at {fmt(results[best][0])} N², "
                f"{(results[best][0] / baseline - 1) * 100:+.0f}% against no augmentation (thesis: FS-1, 5.51 against 7.89, -30%)",
                f"{len(better)} of {len(augmented_only)} methods lower the error (thesis: every method it reports, the hybrid least, 7.20 against 7.89)"]
        if "independent" in results and "hybrid" in results:
            ind, hyb = results["independent"][0], results["hybrid"][0]
            said.append(f"independent combination {'beats' if ind < hyb else 'does not beat'} hybrid, "
                        f"{fmt(ind)} against {fmt(hyb)} (thesis: 5.71 against 7.20)")
    helped = [n for n in ours if n != "none" and ours[n][0] < ours_baseline]
    if ours and ours_baseline == ours_baseline:
        best = min(ours, key=lambda n: ours[n][0])
        said.append(f"deform-gru without augmentation scores {fmt(ours_baseline)} N² against the ConvLSTM's {fmt(baseline)}; "
                    f"{len(helped)} of {len(ours) - 1} methods lower its error, its best being "
                    f"{CH5_LABELS.get(best, ch5_method(best).upper())} at {fmt(ours[best][0])} N²")
    parts += verdict(said, "\n".join([
        "The 60 grasps are simulated (`simulate --preset ch5`:",
        "bolts of 12, 15 and 18 mm, 8–25 N, two gripper settings, an 8 mm shore-50A membrane). The",
        "thesis attributes its 5.5–7.9 error over 0–25 N to the elastomer's elasticity and the DVS",
        "threshold; the simulator models its membrane's saturation (set at 30 N for this preset) and",
        "its DVS pixels with their own parameters, so absolute errors differ and the ranking of the",
        "methods is the comparable part. MSE is in N² (the thesis writes N)." + first_frame_note(folder, shifts=True),
    ]))
    return section_text(parts)


def draw_ch5(results, order, figures_dir):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(figures_dir, exist_ok=True)
    names = [ch5_method(n) for n in order]
    means = [results[n][0] for n in order]
    sds = [0 if math.isnan(results[n][1]) else results[n][1] for n in order]
    fig, ax = plt.subplots(figsize=(max(6, 0.45 * len(order)), 3.6))
    ax.bar(range(len(order)), means, color="#4c72b0")
    ax.errorbar(range(len(order)), means, yerr=sds, fmt="none", ecolor="#c44e52", capsize=3)
    ax.set_xticks(range(len(order)), names, rotation=60, ha="right", fontsize=8)
    ax.set_ylabel("MSE (N²) on the medium bolt")
    fig.tight_layout()
    fig.savefig(pathlib.Path(figures_dir) / "ch5-methods.png", dpi=110)
    plt.close(fig)
    tes = {n: results[n] for n in order if n.startswith("tes")}
    if len(tes) >= 2:
        shifts = sorted({int(n[3:].split("_")[0]) for n in tes})
        zetas = sorted({float(n.split("_")[1]) for n in tes})
        import numpy as np

        grid = np.full((len(zetas), len(shifts)), np.nan)
        for n, (mean, _, _) in tes.items():
            grid[zetas.index(float(n.split("_")[1])), shifts.index(int(n[3:].split("_")[0]))] = mean
        fig, ax = plt.subplots(figsize=(5, 2.8))
        image = ax.imshow(grid, cmap="viridis_r", aspect="auto")
        ax.set_xticks(range(len(shifts)), [str(s) for s in shifts])
        ax.set_yticks(range(len(zetas)), [f"{z:.2f}" for z in zetas])
        ax.set_xlabel("shift j (frames)")
        ax.set_ylabel("share ζ")
        for (i, j), value in np.ndenumerate(grid):
            if value == value:
                ax.text(j, i, f"{value:.2f}", ha="center", va="center", fontsize=7, color="w")
        fig.colorbar(image, ax=ax, label="MSE (N²)")
        fig.tight_layout()
        fig.savefig(pathlib.Path(figures_dir) / "ch5-tes.png", dpi=110)
        plt.close(fig)


# ------------------------------------------------------------------------------------------------
# The page

CHAPTERS = {"ch3": chapter3, "ch4": chapter4, "ch5": chapter5}
TITLES = {
    "ch3": "Chapter 3: force from accumulated events (TDNN, GP) and materials (DNN)",
    "ch4": "Chapter 4: spatio-temporal force estimation (LSTM, CNNLSTM, ConvLSTM)",
    "ch5": "Chapter 5: data augmentation for an unseen object size",
}


RESULTS_PAGE = pathlib.Path(__file__).resolve().parent.parent / "docs" / "results.md"


def keep_section(path: pathlib.Path, title: str, body: str, publish, full: bool):
    """A script's section written to `path` in its work folder, and through `publish` (onto
    docs/results.md) only by a full run: a quick or resized run's stays in its folder."""
    path.write_text(f"## {title}\n\n{body}\n")
    if full:
        publish(body)


def publish_section(section: str, body: str, title: str, page=RESULTS_PAGE):
    """`body` into the page between its `results:SECTION` markers (appended under `title` when missing)."""
    page = pathlib.Path(page)
    page.write_text(replace_section(page.read_text(), section, body, title=title))
    print(f"wrote {page}", file=sys.stderr)


def section_body(text: str, chapter: str) -> str | None:
    """What the page holds between its `results:CHAPTER` markers (stripped), None without them."""
    start, end = f"<!-- results:{chapter}:start -->", f"<!-- results:{chapter}:end -->"
    if start not in text or end not in text:
        return None
    return text.split(start, 1)[1].split(end, 1)[0].strip()


def replace_section(text: str, chapter: str, body: str, title: str | None = None) -> str:
    start, end = f"<!-- results:{chapter}:start -->", f"<!-- results:{chapter}:end -->"
    block = f"{start}\n{body.strip()}\n{end}"
    if start in text and end in text:
        before, rest = text.split(start, 1)
        _, after = rest.split(end, 1)
        return before + block + after
    return text.rstrip() + f"\n\n## {title or TITLES[chapter]}\n\n{block}\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("chapter", choices=sorted(CHAPTERS))
    parser.add_argument("folder", help="the chapter script's output folder with *.metrics.parquet")
    parser.add_argument("page", help="the markdown page to update (created when missing)")
    parser.add_argument("--figures", default=None, help="folder of the chapter's PNGs (default: beside the page)")
    parser.add_argument("--run", default="", help="one line saying how the numbers were made (default: FOLDER/run.md)")
    parser.add_argument("--protocol", default="",
                        help="one line under every table: where the run departs from the thesis, its seeds and wall time")
    parser.add_argument("--section", default=None,
                        help="the page's section to write, between <!-- results:SECTION:start/end --> (default: the chapter)")
    args = parser.parse_args(argv)
    page = pathlib.Path(args.page)
    figures = args.figures or str(page.parent)
    run = args.run
    if not run and (pathlib.Path(args.folder) / "run.md").is_file():
        run = (pathlib.Path(args.folder) / "run.md").read_text().strip()
    body = stamp_tables(CHAPTERS[args.chapter](args.folder, page, figures, run), args.protocol)
    text = page.read_text() if page.exists() else "# Reproduced results\n"
    page.parent.mkdir(parents=True, exist_ok=True)
    temporary = page.with_name(page.name + ".tmp")
    temporary.write_text(replace_section(text, args.section or args.chapter, body, title=TITLES[args.chapter]))
    os.replace(temporary, page)
    print(f"{page}: {TITLES[args.chapter]} updated (section {args.section or args.chapter})", file=sys.stderr)


if __name__ == "__main__":
    main()
