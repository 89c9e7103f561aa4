import sys

import click

from neurotac_cli.options import input_paths, seed_option

FORCE = ("tdnn", "gp", "lstm", "cnnlstm", "convlstm", "deform-gru")
MATERIAL = ("material-dnn", "material-force", "material-curves", "material-timing")

# (option, parameter, type, help); None defaults take each model's thesis value.
HYPERPARAMETERS = [
    ("--layers", "layers", int, "Hidden layers: tdnn k (thesis 4), lstm (6), cnnlstm conv layers (4), convlstm (4), deform-gru GRU layers (1), material-dnn k (2)."),
    ("--units", "units", int, "Units per layer: tdnn n (thesis 40), lstm (32), cnnlstm LSTM units (32), material-dnn n (30)."),
    ("--delays", "delays", int, "tdnn: previous frames fed with the current one (thesis 3)."),
    ("--filters", "filters", int, "cnnlstm, convlstm: filters per convolutional layer (thesis 3)."),
    ("--kernel", "kernel", int, "cnnlstm, convlstm: square kernel size (thesis 3, i.e. 3x3)."),
    ("--dropout", "dropout", float, "Dropout rate: cnnlstm, convlstm after the first three layers (thesis 0.4); deform-gru, material-curves."),
    ("--dense", "dense", int, "convlstm: hidden units of the dense head (0: one linear layer; default 0)."),
    ("--hidden", "hidden", int, "deform-gru: GRU units (default 32)."),
    ("--layout-grid", "layout_grid", int, "deform-gru: side of an optional coarse spatial layout grid of its features (default 0 = none; 4 fits seen sizes better, unseen sizes worse)."),
    ("--restarts", "restarts", int, "gp: random restarts of the marginal-likelihood optimiser (default 3)."),
    ("--max-points", "max_points", int, "gp: training frames kept, a random subset (default 1500; cost grows as n^3)."),
    ("--points", "points", int, "material models: samples each accumulation curve is resampled to (thesis 30)."),
    ("--lr", "lr", float, "Adam learning rate (thesis 0.001)."),
    ("--beta1", "beta1", float, "Adam beta1 (thesis 0.9)."),
    ("--beta2", "beta2", float, "Adam beta2 (thesis 0.999)."),
    ("--batch-size", "batch_size", int, "Trials per minibatch (default 8)."),
    ("--epochs", "epochs", int, "Most epochs (default 500); early stopping usually ends sooner."),
    ("--patience", "patience", int, "Stop after this many epochs without validation improvement, restoring the best weights (thesis 20)."),
    ("--weight-decay", "weight_decay", float, "Adam weight decay (default 0)."),
]


def hyperparameter_options(function):
    for option, name, kind, text in reversed(HYPERPARAMETERS):
        function = click.option(option, name, type=kind, default=None, help=text)(function)
    return function


def hyperparameters(values: dict) -> dict:
    return {name: values.get(name) for _, name, _, _ in HYPERPARAMETERS}


def validation_options(function):
    function = click.option("--val-per", default=None, metavar="LABEL",
                            help="With --val-fraction: draw validation trials per value of this label [default: object "
                            "(the thesis: one per size) for force models, the class label for classifiers].")(function)
    function = click.option("--val-where", default=None, metavar="LABEL=VALUE",
                            help="Validate on the trials with this label value, e.g. object=bolt15.")(function)
    function = click.option("--val-fraction", type=click.FloatRange(0, 1, max_open=True), default=None,
                            help="Validate on this fraction of source trials, drawn per --val-per value (default 0.1 when no other choice is given).")(function)
    function = click.option("--val-trials", default=None, metavar="ID,ID,...",
                            help="Validate on these trials (comma-separated ids).")(function)
    return function


def progress_printer(every: int = 25, quiet_s: float = 30.0):
    """Progress on stderr: every message on a terminal (overwriting epoch lines); otherwise the first
    epoch, every 25th, and any epoch that ends 30 s or more after the last line shown (a slow model
    shows it is alive), besides every message that is not an epoch line."""
    import re
    import time

    from neurotac_cli.tables import is_terminal

    interactive = is_terminal(sys.stderr)
    shown = [time.monotonic()]

    def show(message: str):
        line = re.match(r"\S+: epoch (\d+) ", message)  # `fit`'s per-epoch line
        if line:
            epoch = int(line.group(1))
            if interactive:
                click.echo("\r" + message[:150].ljust(150), err=True, nl=False)
                return
            if epoch != 1 and epoch % every and time.monotonic() - shown[0] < quiet_s:
                return
        elif interactive:
            click.echo("", err=True)
        click.echo(message, err=True)
        shown[0] = time.monotonic()

    return show


@click.command()
@input_paths
@click.option("--model", "model_name", type=click.Choice(FORCE + MATERIAL), required=True,
              help="Force models: tdnn, gp (thesis ch. 3), lstm, cnnlstm, convlstm (ch. 4), deform-gru (ours); "
              "material classifiers: material-dnn (thesis), material-force (force-only baseline), material-curves, material-timing (loading and release timing, linear discriminant).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="The model file to write (safetensors with a JSON header).")
@hyperparameter_options
@validation_options
@click.option("--label", default="material", show_default=True, help="Classifiers: the label column to predict.")
@click.option("--curve", type=click.Path(dir_okay=False), default=None, help="Write the training curve (loss per epoch) as a metrics table to this file.")
@click.option("--plot", type=click.Path(dir_okay=False), default=None, help="Draw the training curve to this PNG.")
@click.option("--threads", type=int, default=2, show_default=True, help="CPU threads for torch.")
@seed_option
def command(paths, model_name, output, val_trials, val_fraction, val_where, val_per, label, curve, plot, threads, seed, **options):
    """Train a force or material model on frames; write one model file.

    Validation trials (for early stopping) are chosen by id, by label value, or as a fraction per
    object; a trial and its augmented copies always stay on one side (a split that separates them is
    refused). Normalisation is fitted on the training trials only.

    Defaults: "(thesis X)" is the thesis's setting and the default; "(default X)" is ours where the
    thesis gives none.

    \b
        neurotac simulate --preset ch4 --seed 1 --synced | neurotac frame --window 10ms \\
          | neurotac crop --size 115x115 --center auto | neurotac train --model deform-gru -o force.model
    """
    import torch

    from neurotac_cli import model as models
    from neurotac_cli import tables

    tables.check_folder(*(path for path in (output, curve, plot) if path))
    torch.set_num_threads(max(1, threads))
    table = tables.read(paths, kind="frames")
    spec = models.make_spec(model_name, **hyperparameters(options))
    if val_trials is None and val_where is None and val_fraction is None:
        val_fraction = 0.1
    trials = [t.strip() for t in val_trials.split(",") if t.strip()] if val_trials else None
    model = models.train(table, spec, val_trials=trials, val_fraction=val_fraction, val_where=val_where,
                         per=val_per, seed=seed, progress=progress_printer(), label=label)
    models.save(model, output)
    history = model.training.get("curve", [])
    if history:
        best = min(history, key=lambda row: row["val_loss"] if row["val_loss"] == row["val_loss"] else row["train_loss"])
        click.echo(f"{model_name}: {len(history)} epochs, best epoch {best['epoch']} "
                   f"(train {best['train_loss']:.4g}, validation {best['val_loss']:.4g}); wrote {output}", err=True)
    if curve:
        from neurotac_cli.metrics import metrics_table

        rows = [(f"epoch:{row['epoch']}", key, row[key]) for row in history for key in ("train_loss", "val_loss")]
        tables.write(curve, metrics_table(rows, model_name), step=("train", {"model": model_name, "curve": True}))
    if plot:
        from neurotac_cli.model.plots import curve_figure

        loss = ("cross-entropy" if model.task == "material"
                else "MSE of force / training max (dimensionless)")
        curve_figure(history, plot, title=f"{model_name} training curve", loss=loss)
