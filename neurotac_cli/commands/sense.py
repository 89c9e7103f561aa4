"""`neurotac sense`: the sensor in one process, camera in, force out."""

import click

from neurotac_cli.options import (Duration, Size, camera_input_options, crop_box_options, echo_lines, history,
                                  idle_timeout_needs_follow, output_option, replay_speed, threads_option)


@click.command()
@click.argument("path", metavar="CAMERA", type=click.Path(dir_okay=False, allow_dash=True))
@output_option
@click.option("--model", "model_path", type=click.Path(dir_okay=False), required=True,
              help="A force model file from `neurotac train`, trained on frames of the --window, box and pool given here.")
@click.option("--material-model", "material_path", type=click.Path(dir_okay=False), default=None,
              help="With a force model trained with --contacts: a material classifier that names each contact's material "
              "in `material_pred` on the frame where the contact ends (as `predict --material-model`; a contact still open "
              "when the input ends: on stderr).")
@click.option("--window", type=Duration(positive=True), default="10ms", show_default=True,
              help="Frame length, with its unit, as `frame --window`.")
@crop_box_options(streaming=True)
@click.option("--sensor", type=Size(), default=None, help="Sensor WxH where the camera file does not say (DAT, text), or to override it.")
@camera_input_options
@threads_option(1, "CPU threads for torch (1 gives the lowest latency per frame).")
def command(path, output, model_path, material_path, window, box, size, center, pool, sensor, fmt, follow, idle_timeout,
            realtime, speed, threads):
    """The sensor in one process: read a camera, and write each window's force as soon as it has closed.

    The same rows as `neurotac import CAMERA | neurotac frame --window W | neurotac crop ... |
    neurotac predict --model M`, made in one process on one thread, so a window's force does not wait
    for three other processes to be scheduled: the lowest latency from a window's close to its force
    row. CAMERA is a camera file (any format `import` reads), `-` for stdin, a FIFO, a file still being
    written (--follow) or a recording replayed at its recorded pace (--realtime). The box must be fixed
    (--box, or --size with --center X,Y): a live stream has no whole input to find the contact in;
    without a box or --pool the whole frames go to the model (one trained on uncropped frames).
    Ctrl-C (or SIGTERM) ends it with the output complete, exit 0. Frames and estimates outside the
    model's training data, and the slip bars the stream followed, are told on stderr as `predict`
    tells them.

    \b
        neurotac sense --follow cam.raw --model m.model --size 115x115 --center 120,90 | controller
        neurotac sense --realtime session.aedat4 --model m.model --pool 6x6 > force.arrows
    """
    from neurotac_cli.held import HeldSignals

    with HeldSignals() as signals:  # from here to the model's load, as `predict` (a Ctrl-C inside numpy's import was lost)
        from neurotac_cli import tables
        from neurotac_cli.errors import InputError, NeurotacError, NoEventsError
        from neurotac_cli.io import events, live
        from neurotac_cli.io.camera import camera_file_stem
        from neurotac_cli.model import sense
        from neurotac_cli.model.store import load_in_background, read_header
        from neurotac_cli.ops.crop import CropSpec
        from neurotac_cli.ops.frame import Framing

        pace = replay_speed(realtime, speed)
        idle_timeout_needs_follow(follow)
        if size is not None and center is None:  # the crop's own advice offers `auto`, which a stream cannot take
            raise click.UsageError("--size needs --center X,Y (sense streams, so the centre cannot be found from the whole input)")
        read_header(model_path)  # a wrong model file fails at once
        if material_path:
            read_header(material_path)
    # torch and the models load while the camera's header is read
    loaded = load_in_background(model_path, threads, signals)
    material = load_in_background(material_path, threads) if material_path else lambda: None
    stream = events.import_events([path], sensor=sensor, fmt=fmt, follow=follow, idle_timeout=idle_timeout / 1e6,
                                  speed=pace, stop=live.stop_on_signals())
    framing = Framing(window_us=window, trial=camera_file_stem(stream.schema) or "events", frame_options=False)
    box_spec = CropSpec(box=box, size=size, center=center, pool=pool) if (box, size, center, pool) != (None, None, None, None) else None
    schema, batches, report = sense.sense(stream, loaded(), framing, box_spec,
                                          material=material(), sensor=sensor,
                                          say=lambda line: echo_lines("sense", [line], "warning: "))
    try:
        tables.write(output, batches, step=history(), schema=schema, flush_each=True)
    except NoEventsError:  # with what the reader left out (a record cut short), which says why
        why = "".join(f" ({note})" for note in stream.notes)
        raise InputError(f"{path}: no events in the camera input, so no window to sense{why}") from None
    except NeurotacError:
        echo_lines("sense", [f"warning: {note}" for note in stream.notes])
        raise
    echo_lines("sense", [f"warning: {note}" for note in stream.notes] + report.messages())
