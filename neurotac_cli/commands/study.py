"""`neurotac study`: cross-validate a model over a hyperparameter grid, every training a task.

`neurotac eval --cv ... --grid ...` is the same study: both run `model.evaluate.study`."""

import click

from neurotac_cli.model.names import FORCE_MODELS, MATERIAL_MODELS
from neurotac_cli.options import (GRID_HELP, NONZERO_HELP, checked_grid, refuse_label_for_force, TablePath, device_option, fold_options, history, hyperparameter_options, hyperparameters, input_paths,
                                  output_option, progress_printer, seed_option, study_options, use_device)


@click.command()
@input_paths
@output_option
@click.option("--model-spec", "model", type=click.Choice(FORCE_MODELS + MATERIAL_MODELS), required=True,
              help="The model trained at every grid point and fold (as `neurotac train --model`).")
@click.option("--grid", "grid", multiple=True, callback=checked_grid, metavar="NAME=VALUES", help=GRID_HELP)
@hyperparameter_options
@click.option("--cv", default="loo", show_default=True, metavar="loo|kfold:K|group:LABEL[=VALUE]",
              help="Folds, as in `neurotac eval --cv`.")
@fold_options()
@click.option("--nonzero", is_flag=True, help=NONZERO_HELP)
@click.option("--per-trial/--no-per-trial", default=False, show_default=True, help="Add one metrics scope per trial and point.")
@click.option("--metrics", "metrics_path", type=TablePath(), default=None,
              help="Write the metrics of every grid point to this file: scope, metric, value, model, and one column "
              "per grid parameter.")
@study_options
@device_option
@seed_option
def command(paths, output, model, grid, cv, repeats, val_fraction, val_per, label, nonzero, per_trial, metrics_path,
            jobs, scheduler, cache, device, seed, **options):
    """Cross-validate a model at every point of a hyperparameter grid (thesis Tables 3.1-3.4).

    The same study as `neurotac eval --cv CV --model-spec M --grid ...` (defaults here: --cv loo,
    no per-trial scopes). Every training (grid point x fold x repeat) is one task, run here, on
    --jobs local processes or on a Dask cluster (--scheduler), cached with --cache so an interrupted
    study resumes; results do not depend on where they ran. Each point is scored as `neurotac eval
    --cv` scores it, with each fold's validation error (val_mse, thesis Table 3.1). Writes the
    out-of-fold predictions of every point (with the grid columns) to stdout, the metrics to
    --metrics, and one line per point on stderr.

    \b
        neurotac study --model-spec tdnn --grid layers=1..5 --grid units=5,10,...,40 --cv loo \\
          --metrics grid.parquet --jobs 0 < ch3-frames.parquet > oof.arrows
        neurotac study --model-spec convlstm --grid layers=2..4 --epochs 50 --cv group:object=bolt15 \\
          --repeats 10 --scheduler tcp://10.0.0.5:8786 --cache study-cache frames.parquet -o oof.parquet
    """
    from neurotac_cli import tables
    from neurotac_cli.model import evaluate

    from neurotac_cli.metrics import check_nonzero

    refuse_label_for_force(model)
    check_nonzero(nonzero, model in MATERIAL_MODELS)
    tables.check_folder(*(path for path in (output, metrics_path) if path not in (None, "-")))  # before hours of training
    tables.check_not_inputs(paths, metrics=metrics_path)
    table = tables.read(paths, kind="frames")
    use_device(device)
    result = evaluate.study(
        table, model, grid, hyperparameters(options),
        evaluate.Folds(cv, repeats, seed, val_fraction, val_per, label), nonzero=nonzero, per_trial=per_trial,
        runner=evaluate.Runner(jobs, scheduler, cache), progress=progress_printer("study"))
    click.echo(result.summary, err=True)
    step = history()
    with tables.together():  # metrics and predictions of one study, never of two
        if metrics_path:
            tables.write(metrics_path, result.metrics, step=step)
        tables.write(output, result.predictions, step=step)
