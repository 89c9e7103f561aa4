"""`neurotac study`: cross-validate a model over a hyperparameter grid, every training a task.

`neurotac eval --cv ... --grid ...` is the same study: both commands run `run_grid` below."""

import click

from neurotac_cli.commands.train import FORCE, MATERIAL, hyperparameter_options, hyperparameters
from neurotac_cli.options import TablePath, input_paths, output_option, seed_option, study_options

GRID_HELP = ("Hyperparameters to vary, as train's option names with _ for -: layers=1..5, units=5,10,...,40, "
             "lr=1e-3,1e-2 (A..B inclusive, A..B:STEP, A,B,...,Z continues the step). Repeat it or put several "
             "in one quoted argument; a single value fixes a parameter (epochs=30), as does its option (--epochs 30).")


def fold_options(prefix: str = ""):
    """--repeats, --val-fraction, --val-per, --label: how `neurotac study` and `eval --cv` train each fold
    (`prefix` starts the help of those that apply to --cv only, e.g. "With --cv: ")."""

    def text(words: str) -> str:
        return prefix + words if prefix else words[0].upper() + words[1:]

    def decorate(function):
        for option in reversed([
            click.option("--repeats", type=click.IntRange(min=1), default=1, show_default=True,
                         help=text("train every fold with this many seeds (thesis 10).")),
            click.option("--val-fraction", type=click.FloatRange(0, 1, max_open=True), default=0.1, show_default=True,
                         help=text("validation share of each fold's training trials, drawn per --val-per value "
                                   "(thesis: one per size).")),
            click.option("--val-per", default=None, metavar="LABEL",
                         help=text("label whose values each get validation trials [default: object for force models, "
                                   "the class label for classifiers].")),
            click.option("--label", default="material", show_default=True, help="Classifiers: the label column."),
        ]):
            function = option(function)
        return function

    return decorate


def run_grid(paths, output, model, grid, fixed, cv, repeats, val_fraction, val_per, label, nonzero, per_trial,
             metrics_path, jobs, scheduler, cache, seed, command="study"):
    """Read frames, cross-validate `model` at every grid point, write the out-of-fold predictions to
    `output` and the grid's metrics to `metrics_path`; one line per point on stderr."""
    from neurotac_cli import tables
    from neurotac_cli.study import cross_validate_grid, grid_lines, grid_metrics_table, grid_points

    points = grid_points(grid, fixed)
    frames = tables.read(paths, kind="frames")
    predictions, rows = cross_validate_grid(
        frames, model, cv, points, repeats=repeats, seed=seed, val_fraction=val_fraction, per=val_per, label=label,
        nonzero=nonzero, per_trial=per_trial, jobs=jobs, scheduler=scheduler, cache_dir=cache)
    for line in grid_lines(rows, model):
        click.echo(line, err=True)
    step = (command, {"model": model, "grid": list(grid), "fixed": {k: v for k, v in fixed.items() if v is not None},
                      "cv": cv, "repeats": repeats, "seed": seed, "val_fraction": val_fraction, "val_per": val_per,
                      "nonzero": nonzero})
    if metrics_path:
        tables.write(metrics_path, grid_metrics_table(rows, model), step=step)
    tables.write(output, predictions, step=step)


@click.command()
@input_paths
@output_option
@click.option("--model-spec", "model", type=click.Choice(FORCE + MATERIAL), required=True,
              help="The model trained at every grid point and fold (as `neurotac train --model`).")
@click.option("--grid", "grid", multiple=True, metavar="NAME=VALUES", help=GRID_HELP)
@hyperparameter_options
@click.option("--cv", default="loo", show_default=True, metavar="loo|kfold:K|group:LABEL[=VALUE]",
              help="Folds, as in `neurotac eval --cv`.")
@fold_options()
@click.option("--nonzero", is_flag=True, help="Score only frames whose measured force is not zero (thesis 4.6).")
@click.option("--per-trial/--no-per-trial", default=False, show_default=True, help="Add one metrics scope per trial and point.")
@click.option("--metrics", "metrics_path", type=TablePath(), default=None,
              help="Write the metrics of every grid point to this file: scope, metric, value, model, and one column "
              "per grid parameter.")
@study_options
@seed_option
def command(paths, output, model, grid, cv, repeats, val_fraction, val_per, label, nonzero, per_trial, metrics_path,
            jobs, scheduler, cache, seed, **options):
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
    run_grid(paths, output, model, grid, hyperparameters(options), cv, repeats, val_fraction, val_per, label, nonzero,
             per_trial, metrics_path, jobs, scheduler, cache, seed)
