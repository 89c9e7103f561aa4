import click

from neurotac_cli.options import FiniteRange, Size, crop_box_options, echo_lines, history, input_paths, output_option


@click.command()
@input_paths
@output_option
@crop_box_options()
@click.option("--warn-above", type=FiniteRange(0, 1), default=0.9, show_default=True,
              help="Warn on stderr when the crop cuts away more than this share of the events or counts (a crop to the "
              "contact area normally cuts the background and the LED flash at t0, often over half).")
@click.option("--sensor", type=Size(), default=None, help="Sensor WxH, for events or recordings tables that do not carry it.")
def command(paths, output, box, size, center, pool, warn_above, sensor):
    """Crop and sum-pool frames, recordings or events to the contact area.

    The output is the kind that came in, with neurotac:sensor set to the new size. With a fixed box
    (--box, --size with --center X,Y, or --pool alone) each batch is written, and flushed on stdout,
    as soon as it arrives (a live pipe flows through, memory stays flat), pooled uint16 counts are
    written as uint32, and what the box cuts away (events, or frame counts) is counted on stderr at
    the end; with --center auto the whole input is read first and the count goes to history. Above
    --warn-above, a warning on stderr.

    \b
        neurotac frame --window 10ms < rec.arrows | neurotac crop --size 115x115 --center auto > f.arrows
        neurotac crop --size 140x150 --center auto --pool 2x2 < frames.arrows > small.arrows
        neurotac frame --window 7ms --accumulate < rec.arrows | neurotac crop --pool all > ch3.arrows
    """
    from neurotac_cli import tables
    from neurotac_cli.ops import crop

    spec = crop.CropSpec(box=box, size=size, center=center, pool=pool)
    source = tables.open_input(paths, kind=("frames", "recordings", "events"))
    schema, cropped, report = crop.crop(source.schema, source.batches, spec, sensor=sensor)
    tables.write(output, cropped, step=history(report=report.history()), schema=schema, flush_each=True)
    echo_lines("crop", report.messages(warn_above))
