import click

from neurotac_cli.options import IntTuple, ParamType, Size, echo_lines, history, input_paths, output_option


class Pool(ParamType):
    name = "KxL|all"

    def convert(self, value, param, ctx):
        if value in (None, "all") or isinstance(value, tuple):
            return value
        return Size().convert(value, param, ctx)


@click.command()
@input_paths
@output_option
@click.option("--box", type=IntTuple(4, "60,30,115,115", "X,Y,W,H"), default=None, help="Keep this box: left, top, width, height in pixels.")
@click.option("--size", type=Size(), default=None, help="Keep a WxH box centred at --center (thesis: 115x115 in ch. 4, 140x150 in ch. 5).")
@click.option("--center", type=IntTuple(2, "120,90", "X,Y|auto", words=("auto",)), default=None,
              help="Centre of the --size box: X,Y, or `auto` = the contact area's centre from the whole input (recorded in history; "
              "`auto` reads the whole input before writing a frame, so on a live stream give X,Y).")
@click.option("--pool", type=Pool(), default=None, help="Sum KxL neighbouring pixels (2x2: 140x150 -> 70x75), or `all`: one pixel per channel.")
@click.option("--warn-above", type=click.FloatRange(0, 1), default=0.9, show_default=True,
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
    tables.write(output, cropped, step=history(report=report.history()), schema=schema, flush_each=output in (None, "-"))
    echo_lines("crop", report.messages(warn_above))
