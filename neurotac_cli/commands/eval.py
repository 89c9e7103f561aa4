import click

from neurotac_cli.commands.study import GRID_HELP, fold_options
from neurotac_cli.commands.train import FORCE, MATERIAL, hyperparameter_options, hyperparameters, progress_printer
from neurotac_cli.options import input_paths, output_option, seed_option, study_options


@click.command()
@input_paths
@output_option
@click.option("--model", "model_path", type=click.Path(dir_okay=False), default=None, help="A model file from `neurotac train`.")
@click.option("--cv", default=None, metavar="loo|kfold:K|group:LABEL[=VALUE]",
              help="Cross-validate instead: retrain --model-spec per fold (leave one trial out, K folds, or one fold per "
              "label value; group:object=bolt12 holds out that object only) and score the out-of-fold predictions.")
@click.option("--model-spec", type=click.Choice(FORCE + MATERIAL), default=None, help="With --cv: the model to train per fold (hyperparameters as in train).")
@hyperparameter_options
@click.option("--grid", "grid", multiple=True, metavar="NAME=VALUES",
              help="With --cv: cross-validate --model-spec at every point of this grid, as `neurotac study` does "
              "(metrics get one column per grid parameter; stderr one line per point). " + GRID_HELP)
@fold_options(prefix="With --cv: ")
@click.option("--metrics", "metrics_path", type=click.Path(dir_okay=False), default=None, help="Write the metrics table (scope, metric, value, model) to this file.")
@click.option("--nonzero", is_flag=True, help="Score only frames whose measured force is not zero (thesis 4.6).")
@click.option("--per-trial/--no-per-trial", default=True, show_default=True, help="Add one metrics scope per trial.")
@click.option("--plot", type=click.Path(dir_okay=False), default=None,
              help="PNG: force traces and per-phase scatter (force models), or the confusion matrix (classifiers).")
@click.option("--plot-trials", default=None, metavar="ID,ID,...", help="Trials drawn in the force traces (default: the first three).")
@click.option("--threads", type=int, default=2, show_default=True, help="CPU threads for torch.")
@study_options
@seed_option
def command(paths, output, model_path, cv, model_spec, grid, repeats, val_fraction, val_per, label, metrics_path, nonzero,
            per_trial, plot, plot_trials, threads, jobs, scheduler, cache, seed, **options):
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
    from neurotac_cli import model as models
    from neurotac_cli import tables
    from neurotac_cli.errors import NeurotacError
    from neurotac_cli.metrics import metrics_table

    if grid and not cv:
        raise click.UsageError("--grid needs --cv and --model-spec (a grid of cross-validated models)")
    if (model_path is None) == (cv is None):
        raise click.UsageError("give either --model FILE, or --cv with --model-spec NAME")
    if cv and not model_spec:
        raise click.UsageError("--cv needs --model-spec NAME (the model trained per fold)")
    if grid and plot:
        raise click.UsageError("--plot draws one model; drop --grid, or plot the chosen point with its options (--layers 4 ...)")
    if grid:
        from neurotac_cli.commands.study import run_grid

        return run_grid(paths, output, model_spec, grid, hyperparameters(options), cv, repeats, val_fraction, val_per,
                        label, nonzero, per_trial, metrics_path, jobs, scheduler, cache, seed, command="eval")
    tables.check_folder(*(path for path in (output, metrics_path, plot) if path not in (None, "-")))
    table = tables.read(paths, kind="frames")  # an empty input fails before torch's seconds of import
    import torch

    from neurotac_cli.model import evaluate

    torch.set_num_threads(max(1, threads))
    if cv:
        spec = models.make_spec(model_spec, **hyperparameters(options))
        predictions, rows = evaluate.cross_validate(
            table, spec, cv, repeats=repeats, seed=seed, val_fraction=val_fraction, per=val_per, label=label,
            nonzero=nonzero, per_trial=per_trial, jobs=jobs, scheduler=scheduler, cache=cache, progress=progress_printer())
        name, step = model_spec, ("eval", {"cv": cv, "spec": spec, "repeats": repeats, "seed": seed, "nonzero": nonzero})
    else:
        if any(value is not None for value in hyperparameters(options).values()):
            raise NeurotacError("hyperparameter options apply to --cv --model-spec only; a model file carries its own")
        model = models.load(model_path)
        predictions, rows = evaluate.evaluate_model(model, table, nonzero=nonzero, per_trial=per_trial)
        name, step = model.name, ("eval", {"model": model_path, "nonzero": nonzero})
    click.echo(evaluate.summary(rows, title=f"{name} on {len(set(predictions.column('trial').to_pylist()))} trials"
                                + (" (non-zero force only)" if nonzero else "")), err=True)
    if metrics_path:
        tables.write(metrics_path, metrics_table(rows, name), step=step)
    if plot:
        from neurotac_cli.model import plots

        if "force_pred" in predictions.schema.names:
            trials = [t.strip() for t in plot_trials.split(",")] if plot_trials else None
            plots.force_figure(predictions, plot, trials, title=name)
        else:
            import numpy as np

            from neurotac_cli.metrics import confusion

            classes = sorted(n[len("prob_"):] for n in predictions.schema.names if n.startswith("prob_"))
            matrix = confusion(predictions.column(label).to_pylist(), predictions.column(f"{label}_pred").to_pylist(), classes)
            plots.confusion_figure(np.asarray(matrix), classes, plot, title=f"{name}: accuracy {100 * np.trace(matrix) / max(matrix.sum(), 1):.1f}%")
    tables.write(output, predictions, step=step)
