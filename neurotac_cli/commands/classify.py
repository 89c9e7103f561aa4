import click

from neurotac_cli.options import echo_lines, history, input_paths, output_option


@click.command()
@input_paths
@output_option
@click.option("--model", "model_path", type=click.Path(dir_okay=False), required=True, help="A classifier file from `neurotac train --model material-...`.")
def command(paths, output, model_path):
    """Predict each trial's material: one row per trial with the predicted class and every class's probability.

    A model trained with --adapt-by LABEL standardises its features within each value of LABEL in the
    input that has at least 8 trials (over all trials where the input has no LABEL column): give the
    grasps of a new object size or sensor together, about balanced across the classes. A smaller
    one takes the training's figures for it (or the training's pooled ones), and is named on stderr.

    \b
        neurotac classify --model material.model < frames.arrows | neurotac info -
    """
    from neurotac_cli import model as models
    from neurotac_cli import tables
    from neurotac_cli.model.store import read_header

    read_header(model_path)  # a wrong model file fails at once, an empty input next, before torch's import
    table = tables.read(paths, kind="frames")
    model = models.load(model_path)
    notes = models.input_notes(model.input_spec, (model.training or {}).get("data_history"), table.schema)
    predicted = models.classify_table(model, table, notes)
    echo_lines("classify", notes, "warning: ")
    tables.write(output, predicted, step=history())
