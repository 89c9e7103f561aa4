import click

from neurotac_cli.options import input_paths, output_option


@click.command()
@input_paths
@output_option
@click.option("--model", "model_path", type=click.Path(dir_okay=False), required=True, help="A force model file from `neurotac train`.")
@click.option("--material-model", "material_path", type=click.Path(dir_okay=False), default=None,
              help="With a force model trained with --contacts: a material classifier (trained on frames pooled to one "
              "pixel, `crop --pool all`, at the same window) that names each contact's material in `material_pred` on "
              "the frame where the contact ends.")
@click.option("--threads", type=int, default=1, show_default=True, help="CPU threads for torch (1 gives the lowest latency per frame).")
def command(paths, output, model_path, material_path, threads):
    """Stream force estimates: read frames as they arrive, write each one's force as soon as it is computed.

    Each trial's recurrent state is carried from frame to frame (nothing is re-run), so a controller
    can read estimates through a pipe while the sensor records. The output equals `eval` on the same
    frames. A model trained with `train --contacts` runs on unbounded streams (sessions of many
    grasps) and also writes, per frame, whether it is in contact (`contact_pred`), the phase
    (`phase_pred`) and a slip flag (`slip_pred`), all from the events alone.

    \b
        neurotac frame --window 10ms < live.arrows | neurotac predict --model force.model | controller
    """
    import sys

    import torch

    from neurotac_cli import model as models
    from neurotac_cli import tables

    torch.set_num_threads(max(1, threads))
    model = models.load(model_path)
    source = tables.open_input(paths, kind="frames")
    if material_path:
        from neurotac_cli.model import session

        schema, batches = session.stream(model, source.schema, source.batches, material=models.load(material_path))
    else:
        schema, batches = models.stream(model, source.schema, source.batches)

    def flushed(batches):
        for batch in batches:
            yield batch
            if output in (None, "-"):
                sys.stdout.buffer.flush()

    step = ("predict", {"model": model_path, **({"material_model": material_path} if material_path else {})})
    tables.write(output, flushed(batches), step=step, schema=schema)
