"""Figures: measured vs estimated force over time and per-phase scatter (thesis Figs 3.9, 4.5),
confusion matrix (Fig. 3.13), training curve. matplotlib with the Agg backend (no display needed).

One style for every figure of the project (`STYLE`, also used by `neurotac render`): each title says
what is shown and how well (RMSE and MAE in newtons, accuracy), each axis its unit, each reference
line its meaning in the legend.
"""

import numpy as np

from neurotac_cli.model.curve import best_epoch, watched
from neurotac_cli.units import counted

PHASE_COLOURS = {"grasping": "tab:blue", "holding": "tab:red", "releasing": "tab:green"}
STYLE = {"font.size": 8, "axes.titlesize": 9, "axes.labelsize": 8, "legend.fontsize": 7, "xtick.labelsize": 7,
         "ytick.labelsize": 7, "axes.grid": True, "grid.color": "#dddddd", "grid.linewidth": 0.5,
         "axes.spines.top": False, "axes.spines.right": False, "savefig.dpi": 110}


def pyplot():
    """pyplot on the Agg backend. Where matplotlib's config folder cannot be written (a read-only
    HOME, a bad MPLCONFIGDIR) it works on in a temporary one, and says so in two paragraphs on
    stderr at import: quieted, so stderr holds our lines alone."""
    import logging

    said = logging.getLogger("matplotlib")
    level = said.level
    said.setLevel(logging.ERROR)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    finally:
        said.setLevel(level)
    return plt


def drawable(text: str) -> str:
    """`text` with each character the figures' font cannot draw written as its code (\\u4e2d): the
    font has no glyph for it, and matplotlib would draw an empty box and warn on stderr."""
    glyphs = _glyphs()
    return "".join(c if ord(c) in glyphs or not c.isprintable() else c.encode("unicode_escape").decode() for c in str(text))


_GLYPHS = []


def _glyphs() -> set:
    """The code points the default font draws (read once)."""
    if not _GLYPHS:
        from matplotlib import font_manager, ft2font

        _GLYPHS.append(set(ft2font.FT2Font(font_manager.findfont(font_manager.FontProperties())).get_charmap()))
    return _GLYPHS[0]


def force_errors(true: np.ndarray, pred: np.ndarray) -> tuple[float, float, int]:
    """(RMSE, MAE, frames) over the frames where both are known."""
    known = np.isfinite(true) & np.isfinite(pred)
    if not known.any():
        return float("nan"), float("nan"), 0
    error = pred[known] - true[known]
    return float(np.sqrt(np.mean(error ** 2))), float(np.mean(np.abs(error))), int(known.sum())


def force_figure(predictions, path: str, trials=None, title: str = "", nonzero: bool = False):
    """Left: force traces of chosen trials (default: the first three); right: estimate vs measured, per
    phase. `nonzero`: the scatter and the errors of the frames `eval --nonzero` scores (the traces whole)."""
    from neurotac_cli.metrics import nonzero_frames

    plt = pyplot()
    trial = np.asarray(predictions.column("trial").to_pylist(), dtype=object)
    t = predictions.column("t").to_numpy() / 1000.0
    true = predictions.column("force").to_numpy(zero_copy_only=False).astype(float)
    pred = predictions.column("force_pred").to_numpy(zero_copy_only=False).astype(float)
    phase = np.asarray(predictions.column("phase").to_pylist(), dtype=object)
    chosen = list(trials) if trials else list(dict.fromkeys(trial))[:3]
    # cross-validation repeats hold every frame once per seed: traces show the first seed's run
    first_run = predictions.column("repeat").to_numpy() == 0 if "repeat" in predictions.column_names else np.ones(len(trial), bool)
    scored = nonzero_frames(true) if nonzero else np.ones(len(true), bool)
    rmse, mae, frames = force_errors(true[scored], pred[scored])
    count = len(set(trial.tolist()))
    with plt.rc_context(STYLE):
        fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.4))
        for n, name in enumerate(chosen):
            mask = (trial == name) & first_run
            trial_rmse = force_errors(true[mask], pred[mask])[0]
            # one trace (a session): measured and estimated in two colours, which overlap for minutes;
            # several: one colour per trial, so each estimate is read against its own measurement
            measured, estimated = ("0.3", "C3") if len(chosen) == 1 else (f"C{n}", f"C{n}")
            marker = "o" if mask.sum() < 2 else None  # a trace of one frame is a point, which a line alone does not draw
            left.plot(t[mask], true[mask], color=measured, lw=1.5, marker=marker, label=f"{drawable(name)} measured")
            left.plot(t[mask], pred[mask], color=estimated, lw=1.2, ls="--", marker=marker,
                      label=f"{drawable(name)} estimated (RMSE {trial_rmse:.3f} N)")
        left.set_xlabel("time since sync t0 (ms)")
        left.set_ylabel("force (N)")
        left.legend(loc="best", framealpha=0.85)
        shown = f" ({len(chosen)} of {count} trials)" if len(chosen) < count else ""
        left.set_title("force over time" + shown + (" (first seed)" if not first_run.all() else ""))
        _scatter(right, true[scored], pred[scored], phase[scored])
        what = f"{drawable(title)}: " if title else ""
        seeds = ", every seed" if not first_run.all() else ""
        fig.suptitle(f"{what}estimated vs measured force, RMSE {rmse:.3f} N, MAE {mae:.3f} N "
                     f"({counted(frames, ('non-zero force frame' if nonzero else 'frame'))} of {counted(count, 'trial')}{seeds})")
        fig.tight_layout()
        _save(fig, path)
        plt.close(fig)


def _scatter(axis, true, pred, phase):
    """Estimate against measurement per phase, with the 1:1 line of a perfect estimate."""
    for name, colour in PHASE_COLOURS.items():
        mask = phase == name
        if mask.any():
            axis.scatter(true[mask], pred[mask], s=4, alpha=0.5, color=colour, label=name)
    other = ~np.isin(phase, list(PHASE_COLOURS))
    if other.any():
        axis.scatter(true[other], pred[other], s=4, alpha=0.4, color="grey", label="no phase")
    known = np.isfinite(true) & np.isfinite(pred)
    if known.any():
        low = min(true[known].min(), pred[known].min())
        high = max(true[known].max(), pred[known].max())
        margin = 0.03 * max(high - low, 1e-6)  # points at the extremes drawn whole, not cut by the frame
        low, high = low - margin, high + margin
        axis.plot([low, high], [low, high], color="black", lw=1, label="1:1 (estimate = measured)")
        axis.set_xlim(low, high)
        axis.set_ylim(low, high)
        axis.set_aspect("equal", adjustable="box")
    axis.set_xlabel("measured force (N)")
    axis.set_ylabel("estimated force (N)")
    axis.legend(markerscale=3)
    axis.set_title("per frame, by phase")


def confusion_figure(matrix: np.ndarray, classes, path: str, title: str = ""):
    plt = pyplot()
    accuracy = np.trace(matrix) / max(matrix.sum(), 1)
    with plt.rc_context({**STYLE, "axes.grid": False}):
        fig, axis = plt.subplots(figsize=(4.8, 4.4))
        axis.imshow(matrix, cmap="Blues")
        totals = matrix.sum(axis=1, keepdims=True).clip(min=1)
        for i in range(len(classes)):
            for j in range(len(classes)):
                axis.text(j, i, f"{matrix[i, j]}\n{100 * matrix[i, j] / totals[i, 0]:.0f}%", ha="center", va="center",
                          color="white" if matrix[i, j] > matrix.max() / 2 else "black", fontsize=8)
        axis.set_xticks(range(len(classes)), [drawable(c) for c in classes], rotation=30)
        axis.set_yticks(range(len(classes)), [drawable(c) for c in classes])
        axis.set_xlabel("predicted class")
        axis.set_ylabel("true class (row: trials, share of the row)")
        axis.set_title(drawable(title) or f"confusion matrix: accuracy {100 * accuracy:.1f}% of {int(matrix.sum())} trials")
        fig.tight_layout()
        _save(fig, path)
        plt.close(fig)


def log_ticks(axis, values) -> None:
    """Log-scale ticks that read: 1, 2, 5 per decade over a few decades, every digit within one."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    values = np.asarray([v for v in values if np.isfinite(v) and v > 0])
    if not values.size:
        return
    decades = np.log10(values.max() / values.min())
    subs = tuple(range(1, 10)) if decades < 1 else (1.0, 2.0, 5.0) if decades < 3 else (1.0,)
    axis.yaxis.set_major_locator(LogLocator(base=10, subs=subs))
    axis.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:.3g}"))
    axis.yaxis.set_minor_formatter(NullFormatter())


def evaluation_figure(predictions, path: str, *, name: str, label: str = "material", trials=None, nonzero: bool = False):
    """`neurotac eval --plot`: force traces and per-phase scatter of a force model's predictions
    (`trials`: ids drawn, default the first three; `nonzero`: as `--nonzero` scores them), or a
    classifier's confusion matrix."""
    if "force_pred" in predictions.schema.names:
        force_figure(predictions, path, trials, title=name, nonzero=nonzero)
        return
    from neurotac_cli.metrics import confusion

    classes = sorted(n[len("prob_"):] for n in predictions.schema.names if n.startswith("prob_"))
    true, pred = predictions.column(label).to_pylist(), predictions.column(f"{label}_pred").to_pylist()
    matrix = np.asarray(confusion(true, pred, classes))
    # the accuracy the metrics give: trials of a class the model cannot name (outside the matrix) count as wrong
    accuracy = np.mean([a == b for a, b in zip(true, pred)]) if true else float("nan")
    confusion_figure(matrix, classes, path, title=f"{name}: accuracy {100 * accuracy:.1f}% of {len(true)} trials")


def curve_figure(curves, path: str, title: str = "", loss: str = "loss"):
    """Training and validation loss by epoch, and the epoch whose weights were kept. `curves`: one
    curve, or {member label: curve} for a model of several members (each drawn, the title the first's)."""
    plt = pyplot()
    curves = curves if isinstance(curves, dict) else {"": curves}
    first = next(iter(curves.values()), [])
    kept = best_epoch(first)
    many = len(curves) > 1
    with plt.rc_context(STYLE):
        fig, axis = plt.subplots(figsize=(5.8, 3.8))
        values = []
        # with several members: the first drawn full and named, the others dashed under one name
        others = f", members 2-{len(curves)}" if len(curves) > 2 else ", member 2"
        for i, curve in enumerate(curves.values()):
            epochs = [row["epoch"] for row in curve]
            train = [row["train_loss"] for row in curve]
            val = [row["val_loss"] for row in curve]
            values += train + val
            style = dict(alpha=1.0, lw=1.5, ls="-") if i == 0 else dict(alpha=0.55, lw=1.0, ls="--")
            suffix = "" if not many else ", member 1" if i == 0 else others
            named = i < 2
            axis.plot(epochs, train, color="C0", label=f"training{suffix}" if named else None, **style)
            if np.isfinite(val).any():
                axis.plot(epochs, val, color="C1", label=f"validation{suffix}" if named else None, **style)
            member_kept = best_epoch(curve)
            if member_kept is not None and i > 0:
                axis.plot([member_kept["epoch"]], [watched(member_kept)], "o", color="0.4", ms=3)
        axis.set_yscale("log")
        log_ticks(axis, values)
        if kept is not None:
            axis.axvline(kept["epoch"], color="black", lw=0.8, ls="--", label=f"restored: epoch {kept['epoch']}" + (" (member 1)" if many else ""))
            axis.plot([kept["epoch"]], [watched(kept)], "ko", ms=4)
        axis.set_xlabel("epoch")
        axis.xaxis.set_major_locator(plt.MaxNLocator(integer=True))  # no epoch 2.5
        axis.set_ylabel(loss)
        axis.legend(fontsize="small")
        how = ""
        if kept is not None:
            which = "validation" if np.isfinite(kept["val_loss"]) else "training"
            how = f"best {which} loss {watched(kept):.4g} at epoch {kept['epoch']} of {len(first)}"
        if many:  # grey dots: the epochs the other members kept
            axis.set_title(f"{title or 'training curve'}, {len(curves)} members\nmember 1: {how}", fontsize="medium")
        else:
            axis.set_title(f"{title}: {how}" if title and how else title or how)
        fig.tight_layout()
        _save(fig, path)
        plt.close(fig)


def _save(fig, path: str):
    """Through a temporary file, so a full disk leaves no half-drawn image (the format comes from
    the path's suffix, which the temporary file lacks)."""
    import os

    from neurotac_cli.tables import atomic_file

    with atomic_file(path) as temporary:
        fig.savefig(temporary, format=os.path.splitext(path)[1].lstrip(".").lower())
