import click

from neurotac_cli.options import Duration, ParamType, Size, input_paths, output_option


class PadTo(ParamType):
    name = "N|longest"

    def convert(self, value, param, ctx):
        if value is None or isinstance(value, int) or value == "longest":
            return value
        try:
            number = int(value)
        except ValueError:
            self.fail(f"expected a number of frames or `longest`, got {value!r}", param, ctx)
        if number <= 0:
            self.fail(f"expected a positive number of frames, got {value!r}", param, ctx)
        return number


@click.command()
@input_paths
@output_option
@click.option("--window", type=Duration(), required=True, help="Frame length, with its unit: 10ms (thesis ch. 4-5), 7ms (ch. 3).")
@click.option(
    "--last-partial",
    type=click.Choice(["keep", "drop"]),
    default="keep",
    show_default=True,
    help="Keep or drop each trial's last window when it is shorter than --window (dropped events are counted).",
)
@click.option("--pad-to", type=PadTo(), default=None, help="Pad every trial with zero frames to N frames, or to the `longest` trial (thesis ch. 4); longer trials are cut at N.")
@click.option(
    "--force-at",
    type=click.Choice(["end", "mean", "median"]),
    default="end",
    show_default=True,
    help="Force per frame: the latest sample at the window's end, or the mean or median of the samples inside it.",
)
@click.option(
    "--phases",
    default="auto",
    show_default=True,
    help="Phase per frame: `auto` (from the force: rise, plateau, fall), `session` (many grasps per trial: phases per "
    "grasp, and an int32 `grasp` column, -1 between grasps), `none`, or three inclusive frame ranges "
    "for grasping, holding, releasing, e.g. 0-21,22-121,122-143 (thesis ch. 3).",
)
@click.option("--accumulate", is_flag=True, help="Counts cumulated from the trial's start (thesis ch. 3 inputs; with `crop --pool all`).")
@click.option(
    "--dtype",
    type=click.Choice(["uint16", "float32"]),
    default="uint16",
    show_default=True,
    help="uint16 counts (saturation at 65535 is reported), or float32 counts divided by each channel's largest count "
    "in the whole output (or by --scale).",
)
@click.option("--scale", default=None, metavar="N[,M]", help="With --dtype float32: divide OFF and ON counts by these, instead of their maxima.")
@click.option("--start", type=Duration(), default=None, help="Plain events tables: frame from this camera time (e.g. 1500ms) instead of the first event.")
@click.option(
    "--trial",
    default=None,
    help="Plain events tables: the trial id of the frames.  [default: the camera file's name without its suffix (`rec.evt3.raw`: `rec`), "
    "as `import` recorded it, else `events`]",
)
@click.option("--sensor", type=Size(), default=None, help="Sensor WxH, for tables that do not carry neurotac:sensor metadata.")
def command(paths, output, window, last_partial, pad_to, force_at, phases, accumulate, dtype, scale, start, trial, sensor):
    """Bin each trial's events into two-channel count frames, with force and phase per frame.

    Windows are half-open, [t0 + k*T, t0 + (k+1)*T) from each trial's sync instant t0; empty windows
    are zero frames. Channel 0 counts OFF events, channel 1 ON events. A plain events table (from
    `neurotac import`) is framed as one unlabelled trial from its first event, streamed batch by
    batch so memory does not grow with its length.

    \b
        neurotac sync --manifest d/manifest.csv | neurotac frame --window 10ms --pad-to longest > f.arrows
        neurotac import rec.aedat | neurotac frame --window 10ms -o frames.parquet
    """
    from neurotac_cli import schema as sch, tables
    from neurotac_cli.errors import NeurotacError
    from neurotac_cli.ops import frame as fr
    from neurotac_cli.ops.phases import parse_ranges

    if phases not in ("auto", "none", "session"):
        phases = tuple(parse_ranges(phases))
    if scale is not None:
        try:
            values = tuple(float(v) for v in scale.split(","))
        except ValueError:
            raise NeurotacError(f"cannot read --scale {scale!r} (one or two positive counts, e.g. 40 or 40,55)") from None
        scale = values * 2 if len(values) == 1 else values
    source = tables.open_input(paths, kind=("recordings", "events"))
    if trial is None:
        trial = camera_file_stem(source.schema) or "events"
    framing = fr.Framing(
        window_us=window, partial=last_partial, pad_to=pad_to, force_at=force_at, phases=phases,
        accumulate=accumulate, dtype=dtype, scale=scale, start_us=start, trial=trial,
    )
    report = fr.FramingReport()
    args = framing.args()
    if source.kind == "recordings":
        table = source.read_all()
        if sensor is not None:
            table = table.replace_schema_metadata(sch.set_meta(table.schema, sensor=sch.sensor_meta(*sensor)).metadata)
        schema, batches = fr.frame_recordings_batches(table, framing, report)
        args["report"] = report.as_dict()
    else:
        schema, batches = fr.frame_events(source.schema, source.batches, framing, report, sensor=sensor)
        args["trial"] = trial
        if dtype == "float32" and scale is None:  # the scale is known only at the end: hold the frames
            batches = list(batches)
            schema = sch.set_meta(schema, scale=report.scale)
            args["report"] = report.as_dict()
        else:
            args["report"] = "streamed: counts of dropped events are written to stderr"
    tables.write(output, batches, step=("frame", args), schema=schema)
    for line in report.warnings(lead_in_expected=source.kind == "recordings") + report.notes:
        click.echo(f"neurotac frame: warning: {line}", err=True)
    if source.kind == "events" and report.dropped and not report.warnings():
        click.echo(
            f"neurotac frame: {report.dropped} of {report.events} events lie outside the frames "
            f"(before start {report.before_start}, after end {report.after_end}, out of time order {report.late})",
            err=True,
        )


def camera_file_stem(schema) -> str | None:
    """The trial id of the single camera file `import` recorded (`rec.evt3.raw` -> `rec`), if any."""
    from neurotac_cli import schema as sch
    from neurotac_cli.io.camera import trial_name

    name = sch.camera_source(schema).get("file")
    return trial_name(name) if name else None
