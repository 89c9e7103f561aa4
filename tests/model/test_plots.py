"""Figures say how well: the restored epoch, RMSE in the title, ticks that read on a log axis."""

import math

import numpy as np
import pyarrow as pa
from PIL import Image

from neurotac_cli.model import plots
from neurotac_cli.model.curve import best_epoch


def test_restored_epoch_is_the_first_lowest_validation_loss():
    curve = [{"epoch": e, "train_loss": 1.0 / e, "val_loss": v} for e, v in enumerate([0.5, 0.3, 0.3, 0.4], start=1)]
    assert best_epoch(curve)["epoch"] == 2
    no_validation = [{"epoch": e, "train_loss": t, "val_loss": math.nan} for e, t in enumerate([3.0, 1.0, 2.0], start=1)]
    assert best_epoch(no_validation)["epoch"] == 2


def test_a_log_axis_within_one_decade_has_several_labelled_ticks(tmp_path):
    plt = plots.pyplot()
    figure, axis = plt.subplots()
    values = [0.071, 0.09, 0.2, 0.31]
    axis.plot(range(4), values)
    axis.set_yscale("log")
    plots.log_ticks(axis, values)
    figure.canvas.draw()
    low, high = axis.get_ylim()
    labelled = [tick for tick in axis.get_yticks() if low <= tick <= high]
    assert len(labelled) >= 4 and all(label.get_text() for label in axis.get_yticklabels() if low <= label.get_position()[1] <= high)
    plt.close(figure)


def test_force_errors_skip_unknown_frames():
    rmse, mae, frames = plots.force_errors(np.array([1.0, 2.0, np.nan]), np.array([2.0, 2.0, 5.0]))
    assert (round(rmse, 6), mae, frames) == (round(math.sqrt(0.5), 6), 0.5, 2)


def test_figures_are_written(tmp_path):
    predictions = pa.table({"trial": ["a"] * 4 + ["b"] * 4, "t": [0, 10_000, 20_000, 30_000] * 2,
                            "force": np.linspace(0, 2, 8), "force_pred": np.linspace(0.1, 2.1, 8),
                            "phase": ["grasping", "holding", "holding", None] * 2})
    plots.force_figure(predictions, str(tmp_path / "f.png"), title="tdnn")
    curve = [{"epoch": e, "train_loss": 1.0 / e, "val_loss": 0.5 + abs(e - 3) / 10} for e in range(1, 8)]
    plots.curve_figure(curve, str(tmp_path / "c.png"), title="tdnn training curve")
    plots.confusion_figure(np.array([[3, 1], [0, 4]]), ["foam", "steel"], str(tmp_path / "m.png"))
    for name in ("f", "c", "m"):
        with Image.open(tmp_path / f"{name}.png") as image:
            assert image.format == "PNG" and min(image.size) > 300


def test_trial_ids_and_classes_the_font_cannot_draw_are_written_as_codes_without_a_warning(tmp_path):
    import warnings

    predictions = pa.table({"trial": ["试验-1"] * 3 + ["α-2"] * 3, "t": [0, 10_000, 20_000] * 2,
                            "force": np.linspace(0, 2, 6), "force_pred": np.linspace(0.1, 2.1, 6), "phase": ["holding"] * 6})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plots.force_figure(predictions, str(tmp_path / "f.png"), title="tdnn")
        plots.confusion_figure(np.array([[1, 0], [0, 1]]), ["钢", "foam"], str(tmp_path / "m.png"))
    assert plots.drawable("试验-1 α") == "\\u8bd5\\u9a8c-1 α"


def test_the_force_figure_of_nonzero_frames_scores_and_scatters_those_only(tmp_path, monkeypatch):
    figures = []
    monkeypatch.setattr(plots, "_save", lambda figure, path: figures.append(figure))
    # the last frame's 1e-12 N is a log's zero, as `eval --nonzero`'s metrics read it
    predictions = pa.table({"trial": ["a"] * 4, "t": [0, 10_000, 20_000, 30_000], "force": [0.0, 1.0, 2.0, 1e-12],
                            "force_pred": [0.5, 1.0, 2.0, 0.5], "phase": ["grasping", "holding", "holding", None]})
    plots.evaluation_figure(predictions, str(tmp_path / "f.png"), name="tdnn", nonzero=True)
    plots.evaluation_figure(predictions, str(tmp_path / "g.png"), name="tdnn")
    nonzero, every = (figure._suptitle.get_text() for figure in figures)
    assert "RMSE 0.000 N" in nonzero and "(2 non-zero force frames of 1 trial)" in nonzero
    assert "RMSE 0.354 N" in every and "(4 frames of 1 trial)" in every
    assert sum(len(c.get_offsets()) for c in figures[0].axes[1].collections) == 2


def test_the_confusion_figures_accuracy_is_the_metrics_one(tmp_path, monkeypatch):
    """A trial of a class the model cannot name lies outside the matrix, and the metrics count it as
    wrong: the title's accuracy is 2 of 3 trials, not the matrix's 2 of 2."""
    titles = []
    monkeypatch.setattr(plots, "confusion_figure", lambda matrix, classes, path, title="": titles.append(title))
    predictions = pa.table({"trial": ["a", "b", "c"], "material": ["foam", "steel", "glass"],
                            "material_pred": ["foam", "steel", "foam"], "prob_foam": [1.0, 0.0, 1.0], "prob_steel": [0.0, 1.0, 0.0]})
    plots.evaluation_figure(predictions, str(tmp_path / "m.png"), name="material-timing")
    assert titles == ["material-timing: accuracy 66.7% of 3 trials"]
