import click

from neurotac_cli.options import history, input_paths, output_option, threads_option


@click.command()
@input_paths
@output_option
@click.option("--model", "model_path", type=click.Path(dir_okay=False), required=True, help="A force model file from `neurotac train`.")
@threads_option(1, "CPU threads for torch (1 gives the lowest latency per frame).")
def command(paths, output, model_path, threads):
    """Stream force estimates: read frames as they arrive, write each one's force as soon as it is computed.

    Each trial's recurrent state is carried from frame to frame (nothing is re-run), so a controller
    can read estimates through a pipe while the sensor records. The output equals `eval` on the same
    frames.

    \b
        neurotac frame --window 10ms < live.arrows | neurotac predict --model force.model | controller
    """
    import torch

    from neurotac_cli import model as models
    from neurotac_cli import tables

    torch.set_num_threads(max(1, threads))
    model = models.load(model_path)
    source = tables.open_input(paths, kind="frames")
    schema, batches = models.stream(model, source.schema, source.batches)
    tables.write(output, batches, step=history(), schema=schema, flush_each=True)
