import click

from neurotac_cli.options import echo_lines, history, input_paths, output_option, threads_option


@click.command()
@input_paths
@output_option
@click.option("--model", "model_path", type=click.Path(dir_okay=False), required=True, help="A force model file from `neurotac train`.")
@click.option("--material-model", "material_path", type=click.Path(dir_okay=False), default=None,
              help="With a force model trained with --contacts: a material classifier (trained on frames pooled to one "
              "pixel, `crop --pool all`, at the same window) that names each contact's material in `material_pred` on "
              "the frame where the contact ends (a contact still open when the input ends: on stderr).")
@threads_option(1, "CPU threads for torch (1 gives the lowest latency per frame).")
def command(paths, output, model_path, material_path, threads):
    """Stream force estimates: read frames as they arrive, write each one's force as soon as it is computed.

    Each trial's recurrent state is carried from frame to frame (nothing is re-run), so a controller
    can read estimates through a pipe while the sensor records. The output equals `eval` on the same
    frames. A frame busier than 1.5 times any training frame, an estimate beyond 1.2 times the
    largest training force, or (deform-gru) frames whose features lie far from
    every training frame's, are named on stderr when they first occur and counted at the end: the
    model is reading a scene outside what it learnt. A model trained with --contacts flags slips at
    bars that follow each trial's own presses; stderr gives them once the input ends.

    \b
        neurotac frame --window 10ms < live.arrows | neurotac crop --size 115x115 --center 120,90 \
            | neurotac predict --model force.model | controller
    """
    import itertools

    from neurotac_cli.held import HeldSignals

    with HeldSignals() as signals:  # from here to the model's load: a Ctrl-C inside numpy's import was lost
        from neurotac_cli import model as models
        from neurotac_cli import tables
        from neurotac_cli.model import session
        from neurotac_cli.model.store import load_in_background, read_header

        read_header(model_path)  # a wrong model file fails at once
        if material_path:
            read_header(material_path)
    # torch takes seconds to import: torch and the model are loaded beside the wait for the first
    # frame (in a pipe, while the verbs upstream start), so that frame's force is not delayed by
    # them, and an empty input is refused without waiting for them
    loaded = load_in_background(model_path, threads, signals)
    material = load_in_background(material_path, threads) if material_path else lambda: None
    source = tables.open_input(paths, kind="frames")
    frames = iter(source.batches)
    first = next(frames)  # an empty input fails here
    model = loaded()
    whole = model.task == "force" and not session.is_session_model(model)
    doubts = models.input_notes(model.input_spec, (model.training or {}).get("data_history"), source.schema)
    echo_lines("predict", filter(None, [*doubts, whole and session.whole_trials_note(source.schema, "a model trained without --contacts")]),
               "warning: ")
    outside = models.Outside.of(model, say=lambda line: echo_lines("predict", [line], "warning: "))
    notes = []
    schema, batches = models.stream(model, source.schema, itertools.chain([first], frames), material=material(), outside=outside,
                                    notes=notes)
    tables.write(output, batches, step=history(), schema=schema, flush_each=True)
    echo_lines("predict", outside.messages(), "warning: ")
    echo_lines("predict", notes)
