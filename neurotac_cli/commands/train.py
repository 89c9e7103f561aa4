import contextlib
import os

import click

from neurotac_cli.errors import UsageError
from neurotac_cli.model.names import FORCE_MODELS, MATERIAL_MODELS
from neurotac_cli.options import (PlotPath, TablePath, refuse_label_for_force, device_option, echo_lines, history, hyperparameter_options, hyperparameters, input_paths, progress_printer,
                                  seed_option, threads_option, use_device, validation_options)


def _model_file(path: str) -> str:
    """A model is written to a file of its own: `-` (stdout) or a table's suffix would pass it off as a table."""
    from neurotac_cli.tables import SUFFIXES

    if path == "-":
        raise UsageError("-o: a model is written to a file, not stdout: give its path, e.g. -o force.model")
    suffix = os.path.splitext(path)[1].lower()
    if suffix in SUFFIXES:
        raise UsageError(f"-o {path}: {suffix} names a table; name the model file otherwise, e.g. force.model")
    return path


@click.command()
@input_paths
@click.option("--model", "model_name", type=click.Choice(FORCE_MODELS + MATERIAL_MODELS), required=True,
              help="Force models: tdnn, gp (thesis ch. 3), lstm, cnnlstm, convlstm (ch. 4), deform-gru (ours); "
              "material classifiers: material-dnn (thesis), material-force (force-only baseline), material-curves, material-timing (loading timing, linear discriminant), material-rises (its rise times alone: other object sizes, force-controlled grippers).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, callback=lambda ctx, param, value: _model_file(value),
              help="The model file to write (safetensors with a JSON header), e.g. force.model.")
@hyperparameter_options
@validation_options
@click.option("--contacts", is_flag=True,
              help="Force models: train on the contacts the event-driven contact detector finds (in sessions of many "
              "grasps, or in trials); the model then runs on unbounded streams, from a fresh state at each contact and "
              "reading zero between contacts; the detector keeps its durations and event rates at the frames' window, "
              "and, where the frames have phases, reads presses in the polarity the training presses make most of (or, "
              "where a fifth or more press clearly ON and a fifth clearly OFF, each contact in the polarity its own press "
              "makes: a sensor of dark and bright objects) and is run on the training sessions first, with a warning where "
              "it finds their contacts or slips poorly; without phases, presses are taken to darken the membrane "
              "(docs/design.md, \"Sessions\").")
@click.option("--label", default="material", show_default=True, help="Classifiers: the label column to predict.")
@click.option("--curve", type=TablePath(), default=None, help="Write the training curve (loss per epoch) as a metrics table to this file; a model of several members writes each one's, named in the model column.")
@click.option("--plot", type=PlotPath(), default=None, help="Draw the training curve to this PNG (every member's, the first drawn full).")
@threads_option(2)
@device_option
@seed_option
def command(paths, model_name, output, val_trials, val_fraction, val_where, val_per, contacts, label, curve, plot, threads, device, seed,
            **options):
    """Train a force or material model on frames; write one model file.

    Validation trials (for early stopping) are chosen by id, by label value, or as a fraction per
    object; a trial and its augmented copies always stay on one side (a split that separates them is
    refused). Normalisation is fitted on the training trials only. Each further member of a
    deform-gru (--members) draws validation trials of its own and trains on the rest; its
    normalisation is the first member's.

    Ctrl-C (or SIGTERM) after the first epoch stops the training as early stopping would: the model
    of the best epoch so far is written, and the command exits as interrupted (130; 143 for SIGTERM).
    A deform-gru of several members writes no model where a member is left untrained.

    Defaults: "(thesis X)" is the thesis's setting and the default; "(default X)" is ours where the
    thesis gives none.

    \b
        neurotac simulate --preset ch4 --seed 1 --synced | neurotac frame --window 10ms \\
          | neurotac crop --size 115x115 --center auto | neurotac train --model deform-gru -o force.model
    """
    from neurotac_cli import model as models
    from neurotac_cli import tables
    from neurotac_cli.model.curve import member_curves
    from neurotac_cli.model.plots import curve_figure

    if contacts and model_name in MATERIAL_MODELS:
        raise UsageError("--contacts trains force models; a material classifier takes whole trials")
    refuse_label_for_force(model_name)
    tables.check_folder(*(path for path in (output, curve, plot) if path is not None))
    tables.check_not_inputs(paths, output=output, curve=curve, plot=plot)
    table = tables.read(paths, kind="frames")  # an empty input fails before torch's seconds of import
    import torch

    from neurotac_cli.model import session
    from neurotac_cli.model.fit import kept_on_interrupt
    from neurotac_cli.model.training import train_model

    torch.set_num_threads(max(1, threads))
    use_device(device)
    echo_lines("train", session.training_input_notes(table, model_name in FORCE_MODELS, contacts))
    with kept_on_interrupt() as stops, _said_when_lost(stops):
        trained = train_model(table, model_name, hyperparameters(options), val_trials=val_trials,
                              val_fraction=val_fraction, val_where=val_where, per=val_per, seed=seed, label=label,
                              progress=progress_printer("train"), contacts=contacts)
    if contacts:
        found = trained.model.training.get("contacts", {})
        notes = [session.one_contact_note(found), session.polarity_note(found), session.detection_note(found)]
        echo_lines("train", filter(None, notes), "warning: ")
    with tables.together():  # the model, its curve and its plot are one training's, or the last one's
        models.save(trained.model, output)
        if curve:
            tables.write(curve, trained.curve, step=history())
        if plot:
            curve_figure(member_curves(trained.model.training), plot, title=f"{model_name} training curve", loss=trained.loss)
    if trained.summary:
        click.echo(f"{trained.summary}; wrote {output}", err=True)
    _end_if_interrupted(stops, output)


@contextlib.contextmanager
def _said_when_lost(stops: list):
    """An interrupt that ends the training with a member stopped early and another not begun: no
    model is written, and the line says why (the exit alone would say "interrupted")."""
    try:
        yield
    except KeyboardInterrupt as again:
        if stops:
            who, epochs, stop = stops[0]
            why = ("before the members after it began: no model written (a model of untrained members is none)" if again is stop
                   else "and again before its model was written: none written")
            click.echo(f"{who}: stopped by the interrupt after {epochs} epoch{'s' if epochs != 1 else ''}, {why}", err=True)
        raise


def _end_if_interrupted(stops: list, output: str):
    """After the model of the best epoch before an interrupt is written (`kept_on_interrupt`), the
    run still ends as interrupted: a script or make sees it did not finish as asked."""
    if stops:
        who, epochs, stop = stops[0]
        click.echo(f"{who}: stopped by the interrupt after {epochs} epoch{'s' if epochs != 1 else ''}: {output} holds its best epoch's "
                   "weights", err=True)
        raise stop
