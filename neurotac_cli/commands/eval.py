import click

from neurotac_cli.errors import UsageError
from neurotac_cli.model.names import FORCE_MODELS, MATERIAL_MODELS
from neurotac_cli.options import (GRID_HELP, NONZERO_HELP, checked_grid, label_given, refuse_label_for_force, PlotPath, TablePath, device_option, echo_lines, fold_options, history, hyperparameter_options, hyperparameters, input_paths,
                                  output_option, progress_printer, seed_option, study_options, threads_option, typed_options, use_device)


@click.command()
@input_paths
@output_option
@click.option("--model", "model_path", type=click.Path(dir_okay=False), default=None, help="A model file from `neurotac train`.")
@click.option("--cv", default=None, metavar="loo|kfold:K|group:LABEL[=VALUE]",
              help="Cross-validate instead: retrain --model-spec per fold (leave one trial out, K folds, or one fold per "
              "label value; group:object=bolt12 holds out that object only) and score the out-of-fold predictions.")
@click.option("--model-spec", type=click.Choice(FORCE_MODELS + MATERIAL_MODELS), default=None, help="With --cv: the model to train per fold (hyperparameters as in train).")
@hyperparameter_options
@click.option("--grid", "grid", multiple=True, callback=checked_grid, metavar="NAME=VALUES",
              help="With --cv: cross-validate --model-spec at every point of this grid, as `neurotac study` does "
              "(metrics get one column per grid parameter; stderr one line per point). " + GRID_HELP)
@fold_options(prefix="With --cv: ")
@click.option("--metrics", "metrics_path", type=TablePath(), default=None, help="Write the metrics table (scope, metric, value, model) to this file.")
@click.option("--nonzero", is_flag=True, help=NONZERO_HELP)
@click.option("--per-trial/--no-per-trial", default=True, show_default=True, help="Add one metrics scope per trial.")
@click.option("--plot", type=PlotPath(), default=None,
              help="An image (PNG; PDF, SVG or JPEG by the suffix): force traces and per-phase scatter (force models), "
              "or the confusion matrix (classifiers).")
@click.option("--plot-trials", default=None, metavar="ID,ID,...", help="Trials drawn in the force traces (default: the first three).")
@threads_option(2)
@study_options
@device_option
@seed_option
def command(paths, output, model_path, cv, model_spec, grid, repeats, val_fraction, val_per, label, metrics_path, nonzero,
            per_trial, plot, plot_trials, threads, jobs, scheduler, cache, device, seed, **options):
    """Score a model on frames: predictions on stdout, metrics with --metrics, a summary on stderr.

    Force models: MSE (N²), RMSE, MAE, RMSE as % of the force range, σ, R², overall and per phase,
    with DTW and Bhattacharyya distances per phase (definitions in docs/commands/eval.md).
    Classifiers: accuracy, per-class recall and the confusion matrix. Model-spec defaults:
    "(thesis X)" is the thesis's setting and the default; "(default X)" is ours where it gives none.

    \b
        neurotac eval --model force.model --metrics m.parquet --plot force.png < test.arrows > pred.arrows
        neurotac eval --cv group:object=bolt12 --model-spec deform-gru --repeats 3 < frames.arrows > oof.arrows
        neurotac eval --cv loo --model-spec tdnn --grid layers=1..5 --grid units=5,10,...,40 \\
          --metrics grid.parquet --jobs 0 < ch3-frames.arrows > oof.arrows
    """
    from neurotac_cli import tables
    from neurotac_cli.model.request import check_request

    chosen = hyperparameters(options)
    check_request(model_path=model_path, cv=cv, model_spec=model_spec, grid=grid, plot=plot, hyperparameters=chosen)
    tables.check_folder(*(path for path in (output, metrics_path, plot) if path not in (None, "-")))
    tables.check_not_inputs(paths, metrics=metrics_path, plot=plot)
    cv_only = typed_options("repeats", "val_fraction", "val_per", "seed", "jobs", "scheduler", "cache") if model_path else []
    if cv_only:
        raise UsageError(f"{', '.join(cv_only)} apply to --cv only: a model file is scored as it is, with no training")
    if plot_trials is not None and not plot:
        raise UsageError("--plot-trials chooses the trials --plot draws; give --plot FILE.png too")
    from neurotac_cli.metrics import check_nonzero

    check_nonzero(nonzero, _classifier(model_path, model_spec))
    table = tables.read(paths, kind="frames")  # an empty input fails before torch's seconds of import
    trials = _plotted_trials(table, plot_trials)
    label = _checked_model(table, model_path, model_spec, label)
    import torch

    from neurotac_cli.model import evaluate, plots

    torch.set_num_threads(max(1, threads))
    use_device(device)
    folds = evaluate.Folds(cv, repeats, seed, val_fraction, val_per, label) if cv else None
    result = evaluate.evaluate(
        table, model_path=model_path, model_spec=model_spec, hyperparameters=chosen, grid=grid,
        folds=folds, nonzero=nonzero, per_trial=per_trial, runner=evaluate.Runner(jobs, scheduler, cache),
        progress=progress_printer("eval"))
    click.echo(result.summary, err=True)
    # what did not apply: the folds' settings when a model file is scored, the label when it estimates force
    unused = (() if cv else ("repeats", "val_fraction", "val_per", "seed")) + (
        ("label",) if "force_pred" in result.predictions.column_names else ())
    step = history(spec=result.spec, unused=unused)
    with tables.together():  # a run's metrics, plot and predictions replace the last run's all, or none
        if metrics_path:
            tables.write(metrics_path, result.metrics, step=step)
        if plot:
            plots.evaluation_figure(result.predictions, plot, name=result.name, label=label, trials=trials, nonzero=nonzero)
        tables.write(output, result.predictions, step=step)


def _checked_model(table, model_path: str | None, model_spec: str | None, label: str) -> str:
    """The label scored (a model file's classifier's own), with a warning on stderr for each way the
    frames do not fit the model: a window they do not state, sessions given to a model of whole trials."""
    from neurotac_cli.model.session import whole_trials_note

    if model_spec:
        refuse_label_for_force(model_spec)
        echo_lines("eval", filter(None, [model_spec in FORCE_MODELS and whole_trials_note(table.schema, "cross-validation")]), "warning: ")
        return label
    from neurotac_cli.model.session import scoring_input_notes
    from neurotac_cli.model.store import read_header

    header = read_header(model_path)
    label = _model_label(header, label)
    echo_lines("eval", scoring_input_notes(header["input"], header.get("training"), header["task"], table))
    return label


def _classifier(model_path, model_spec) -> bool:
    from neurotac_cli.model.store import read_header

    return model_spec in MATERIAL_MODELS if model_spec else read_header(model_path)["task"] == "material"


def _plotted_trials(table, plot_trials: str | None) -> list | None:
    """The trial ids of --plot-trials, each one the input holds (None: the plot's default)."""
    if plot_trials is None:
        return None
    from neurotac_cli.rendering import pick_trial

    chosen = list(dict.fromkeys(name.strip() for name in plot_trials.split(",") if name.strip()))  # a trial drawn once
    if not chosen:
        raise UsageError(f"--plot-trials {plot_trials!r} names no trial")
    return [pick_trial(table, name) for name in chosen]


def _model_label(header: dict, label: str) -> str:
    """The label a model file classifies by (its training's): a classifier predicts only that one, so
    a --label that differs would score it under another label's name; a force model has none."""
    refuse_label_for_force(header["model"])
    if header["task"] != "material":
        return label
    trained = (header.get("training") or {}).get("label") or "material"
    if label_given() and label != trained:
        raise UsageError(f"--label {label}: model {header['model']!r} classifies by {trained!r}, the label it was trained on "
                         f"(give --label {trained} or leave it out, or train a classifier with --label {label})")
    return trained
