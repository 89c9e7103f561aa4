"""Figures: measured vs estimated force over time and per-phase scatter (thesis Figs 3.9, 4.5),
confusion matrix (Fig. 3.13), training curve. matplotlib with the Agg backend (no display needed)."""

import numpy as np

PHASE_COLOURS = {"grasping": "tab:blue", "holding": "tab:red", "releasing": "tab:green"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def force_figure(predictions, path: str, trials=None, title: str = ""):
    """Left: force traces of chosen trials (default: the first three); right: estimate vs measured, per phase."""
    plt = _pyplot()
    trial = np.asarray(predictions.column("trial").to_pylist(), dtype=object)
    t = predictions.column("t").to_numpy() / 1000.0
    true = predictions.column("force").to_numpy(zero_copy_only=False).astype(float)
    pred = predictions.column("force_pred").to_numpy(zero_copy_only=False).astype(float)
    phase = np.asarray(predictions.column("phase").to_pylist(), dtype=object)
    chosen = list(trials) if trials else list(dict.fromkeys(trial))[:3]
    # cross-validation repeats hold every frame once per seed: traces show the first seed's run
    first_run = predictions.column("repeat").to_numpy() == 0 if "repeat" in predictions.column_names else np.ones(len(trial), bool)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    for n, name in enumerate(chosen):
        mask = (trial == name) & first_run
        colour = f"C{n}"
        left.plot(t[mask], true[mask], color=colour, lw=1.5, label=f"{name} measured")
        left.plot(t[mask], pred[mask], color=colour, lw=1.2, ls="--", label=f"{name} estimated")
    left.set_xlabel("time since sync (ms)")
    left.set_ylabel("force (N)")
    left.legend(fontsize=7)
    left.set_title("measured vs estimated force" + (" (first seed)" if not first_run.all() else ""))
    for name, colour in PHASE_COLOURS.items():
        mask = phase == name
        if mask.any():
            right.scatter(true[mask], pred[mask], s=4, alpha=0.5, color=colour, label=name)
    finite = np.isfinite(true)
    if finite.any():
        low, high = np.nanmin(true), np.nanmax(true)
        right.plot([low, high], [low, high], color="black", lw=1)
    right.set_xlabel("measured force (N)")
    right.set_ylabel("estimated force (N)")
    right.legend(fontsize=7)
    right.set_title("per phase")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def confusion_figure(matrix: np.ndarray, classes, path: str, title: str = ""):
    plt = _pyplot()
    fig, axis = plt.subplots(figsize=(4.8, 4.2))
    axis.imshow(matrix, cmap="Blues")
    totals = matrix.sum(axis=1, keepdims=True).clip(min=1)
    for i in range(len(classes)):
        for j in range(len(classes)):
            axis.text(j, i, f"{matrix[i, j]}\n{100 * matrix[i, j] / totals[i, 0]:.0f}%", ha="center", va="center",
                      color="white" if matrix[i, j] > matrix.max() / 2 else "black", fontsize=8)
    axis.set_xticks(range(len(classes)), classes, rotation=30)
    axis.set_yticks(range(len(classes)), classes)
    axis.set_xlabel("predicted class")
    axis.set_ylabel("true class")
    accuracy = np.trace(matrix) / max(matrix.sum(), 1)
    axis.set_title(title or f"accuracy {100 * accuracy:.1f}%")
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def evaluation_figure(predictions, path: str, *, name: str, label: str = "material", trials=None):
    """`neurotac eval --plot`: force traces and per-phase scatter of a force model's predictions
    (`trials`: ids drawn, default the first three), or a classifier's confusion matrix."""
    if "force_pred" in predictions.schema.names:
        force_figure(predictions, path, trials, title=name)
        return
    from neurotac_cli.metrics import confusion

    classes = sorted(n[len("prob_"):] for n in predictions.schema.names if n.startswith("prob_"))
    matrix = np.asarray(confusion(predictions.column(label).to_pylist(), predictions.column(f"{label}_pred").to_pylist(), classes))
    confusion_figure(matrix, classes, path, title=f"{name}: accuracy {100 * np.trace(matrix) / max(matrix.sum(), 1):.1f}%")


def curve_figure(curve: list, path: str, title: str = "", loss: str = "loss"):
    plt = _pyplot()
    fig, axis = plt.subplots(figsize=(5.5, 3.6))
    epochs = [row["epoch"] for row in curve]
    axis.plot(epochs, [row["train_loss"] for row in curve], label="training")
    val = [row["val_loss"] for row in curve]
    if np.isfinite(val).any():
        axis.plot(epochs, val, label="validation")
    axis.set_yscale("log")
    axis.set_xlabel("epoch")
    axis.set_ylabel(loss)
    axis.legend()
    axis.set_title(title)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def _save(fig, path: str):
    """Through a temporary file, so a full disk leaves no half-drawn image (the format comes from
    the path's suffix, which the temporary file lacks)."""
    import os

    from neurotac_cli.tables import atomic_file

    with atomic_file(path) as temporary:
        fig.savefig(temporary, dpi=110, format=os.path.splitext(path)[1].lstrip(".").lower())
