import click

from neurotac_cli.options import ParamType, Size, input_paths, output_option


class IntTuple(ParamType):
    def __init__(self, count: int, example: str, name: str):
        self.count, self.example, self.name = count, example, name

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        if self.name == "X,Y|auto" and value == "auto":
            return "auto"
        try:
            parts = tuple(int(v) for v in str(value).split(","))
        except ValueError:
            parts = ()
        if len(parts) != self.count or min(parts) < 0:
            self.fail(f"expected {self.name}, e.g. {self.example}, got {value!r}", param, ctx)
        return parts


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
@click.option("--center", type=IntTuple(2, "120,90", "X,Y|auto"), default=None,
              help="Centre of the --size box: X,Y, or `auto` = the contact area's centre from the whole input (recorded in history).")
@click.option("--pool", type=Pool(), default=None, help="Sum KxL neighbouring pixels (2x2: 140x150 -> 70x75), or `all`: one pixel per channel.")
@click.option("--warn-above", type=click.FloatRange(0, 1), default=0.9, show_default=True,
              help="Warn on stderr when the crop cuts away more than this share of the events or counts (a crop to the "
              "contact area normally cuts the background and the LED flash at t0, often over half).")
@click.option("--sensor", type=Size(), default=None, help="Sensor WxH, for events or recordings tables that do not carry it.")
def command(paths, output, box, size, center, pool, warn_above, sensor):
    """Crop and sum-pool frames, recordings or events to the contact area.

    The output is the kind that came in, with neurotac:sensor set to the new size. What the box
    cuts away is counted (events, or frame counts) in history and, above --warn-above, on stderr.

    \b
        neurotac frame --window 10ms < rec.arrows | neurotac crop --size 115x115 --center auto > f.arrows
        neurotac crop --size 140x150 --center auto --pool 2x2 < frames.arrows > small.arrows
        neurotac frame --window 7ms --accumulate < rec.arrows | neurotac crop --pool all > ch3.arrows
    """
    from neurotac_cli import tables
    from neurotac_cli.errors import NeurotacError, OutsideSensorError
    from neurotac_cli.ops import crop as cr

    spec = cr.CropSpec(box=box, size=size, center=center, pool=pool)
    report = cr.CropReport()
    source = tables.open_input(paths, kind=("frames", "recordings", "events"))
    args = {"box": list(box) if box else None, "size": list(size) if size else None,
            "center": center if center in (None, "auto") else list(center),
            "pool": pool if pool in (None, "all") else list(pool)}
    try:
        if source.kind == "events" and center != "auto":  # a plain events stream: cropped batch by batch
            schema = source.schema
            crop_box = cr.resolve_box(spec, sensor or cr._sensor(schema))
            report.box = list(crop_box) if crop_box else None
            schema, batches = cr.crop_events_batches(schema, source.batches, crop_box, pool, report, sensor=sensor)
            args["report"] = "streamed: the count of cut events is written to stderr"
            tables.write(output, batches, step=("crop", args), schema=schema)
            click.echo(f"neurotac crop: cut {report.cut} of {report.kept + report.cut} events", err=True)
        else:
            table = cr.crop_table(source.read_all(), spec, report, sensor=sensor)
            args["report"] = report.as_dict()
            tables.write(output, table, step=("crop", args))
    except OutsideSensorError as error:
        if sensor is None and _size_guessed(source.schema):
            raise NeurotacError(f"{error} (that size is the events' extent, the camera file does not give it: "
                                "give the sensor's size to `neurotac import --sensor WxH`)") from None
        raise
    for line in report.warnings(warn_above):
        click.echo(f"neurotac crop: warning: {line}", err=True)


def _size_guessed(schema) -> bool:
    """Whether the input's sensor size was read off the events' extent (a camera file that lacks it)."""
    from neurotac_cli import schema as sch

    return sch.camera_source(schema).get("sensor_from") == "events"
