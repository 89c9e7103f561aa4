import click

from neurotac_cli.options import history, input_paths, output_option


@click.command()
@input_paths
@output_option
@click.option("--model", "model_path", type=click.Path(dir_okay=False), required=True, help="A classifier file from `neurotac train --model material-...`.")
def command(paths, output, model_path):
    """Predict each trial's material: one row per trial with the predicted class and every class's probability.

    \b
        neurotac classify --model material.model < frames.arrows | neurotac info -
    """
    from neurotac_cli import model as models
    from neurotac_cli import tables

    model = models.load(model_path)
    table = tables.read(paths, kind="frames")
    tables.write(output, models.classify_table(model, table), step=history())
