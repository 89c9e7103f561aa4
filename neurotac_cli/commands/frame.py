import click

from neurotac_cli.options import Duration, ParamType, Size, echo_lines, input_paths, output_option


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


class Scale(ParamType):
    name = "N[,M]"

    def convert(self, value, param, ctx):
        if value is None or isinstance(value, tuple):
            return value
        import math

        try:
            values = tuple(float(v) for v in str(value).split(","))
        except ValueError:
            self.fail(f"expected one or two positive counts (OFF,ON), e.g. 40 or 40,55, got {value!r}", param, ctx)
        if len(values) not in (1, 2) or not all(math.isfinite(v) and v > 0 for v in values):
            self.fail(f"expected one or two positive, finite counts (OFF,ON), e.g. 40 or 40,55, got {value!r}", param, ctx)
        return values * 2 if len(values) == 1 else values


@click.command()
@input_paths
@output_option
@click.option("--window", type=Duration(positive=True, longest_us=2**31 - 1), required=True, help="Frame length, with its unit: 10ms (thesis ch. 4-5), 7ms (ch. 3).")
@click.option(
    "--last-partial",
    type=click.Choice(["keep", "drop"]),
    default="keep",
    show_default=True,
    help="Keep or drop each trial's last window when it is shorter than --window (dropped events are counted).",
)
@click.option("--pad-to", type=PadTo(), default=None, help="Pad every trial with zero frames to N frames, or to the `longest` trial (thesis ch. 4); longer trials are cut at N. "
                   "With --accumulate the padding frames hold the trial's last accumulated counts (they add no events).")
@click.option(
    "--force-at",
    type=click.Choice(["end", "mean", "median"]),
    default="end",
    show_default=True,
    help="Force per frame: the latest sample at the window's end, or the mean or median of the samples inside it.",
)
@click.option(
    "--zero",
    type=click.Choice(["log", "rest"]),
    default="log",
    show_default=True,
    help="Force per frame from the log's own zero, or from its `rest` level where the frame is (the median force "
    "between the grasps --phases session finds, per 10 s of frames): a force sensor whose zero drifts then gives "
    "frames at zero between grasps. Recordings with a force log only.",
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
@click.option("--scale", type=Scale(), default=None, help="With --dtype float32: divide OFF and ON counts by these, instead of their maxima.")
@click.option("--start", type=Duration(), default=None, help="Plain events tables: frame from this camera time (e.g. 1500ms) instead of the first event.")
@click.option(
    "--trial",
    default=None,
    help="Plain events tables: the trial id of the frames.  [default: the camera file's name without its suffix (`rec.evt3.raw`: `rec`), "
    "as `import` recorded it, else `events`]",
)
@click.option("--sensor", type=Size(), default=None, help="Sensor WxH, for tables that do not carry neurotac:sensor metadata.")
@click.option(
    "--max-frames",
    type=click.IntRange(min=1),
    default=1_000_000,
    show_default=True,
    help="Refuse to write more frames than this (a clock jump or a tiny --window would otherwise write without end); "
    "the error says where the frames come from. A plain events stream is refused more than this many frames at once "
    "(a clock jump), and otherwise runs for as long as it lasts (a live camera).",
)
@click.option(
    "--sort",
    is_flag=True,
    help="Plain events tables: sort the events by time first (held in memory, at most 20 million), instead of "
    "refusing events more than one window out of time order.",
)
@click.option(
    "--slips",
    "slips_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="CSV of true slips (columns trial or session, slip_start_ms, slip_end_ms on the synced clock, as "
    "`simulate --session` writes grasps.csv): adds a bool `slip` column, true where a frame's window ends inside "
    "a slip, that `eval` scores the slip flag against. Synced recordings only.",
)
def command(paths, output, window, last_partial, pad_to, force_at, zero, phases, accumulate, dtype, scale, start, trial, sensor, max_frames, sort,
            slips_path):
    """Bin each trial's events into two-channel count frames, with force and phase per frame.

    Windows are half-open, [t0 + k*T, t0 + (k+1)*T) from each trial's sync instant t0; empty windows
    are zero frames. Channel 0 counts OFF events, channel 1 ON events. A plain events table (from
    `neurotac import`) is framed as one unlabelled trial from its first event, streamed batch by
    batch so memory does not grow with its length; each frame is written as soon as an event at or
    after its window's end has arrived.

    \b
        neurotac sync --manifest d/manifest.csv | neurotac frame --window 10ms --pad-to longest > f.arrows
        neurotac import rec.aedat | neurotac frame --window 10ms -o frames.parquet
        neurotac sync --manifest s/manifest.csv | neurotac crop --pool 6x6 \
            | neurotac frame --window 10ms --phases session --slips s/grasps.csv
    """
    from neurotac_cli import tables
    from neurotac_cli.io.camera import camera_file_stem
    from neurotac_cli.io.slips import read_slips
    from neurotac_cli.ops import frame as fr
    from neurotac_cli.ops.phases import parse_ranges

    if phases not in ("auto", "none", "session"):
        phases = tuple(parse_ranges(phases))
    source = tables.open_input(paths, kind=("recordings", "events"))
    events_only = [flag for flag, given in (("--start", start is not None), ("--trial", trial is not None), ("--sort", sort)) if given]
    fr.check_for_kind(source.kind, events_only, phases, zero)
    framing = fr.Framing(
        window_us=window, partial=last_partial, pad_to=pad_to, force_at=force_at, zero=zero, phases=phases, accumulate=accumulate,
        dtype=dtype, scale=scale, start_us=start, trial=(camera_file_stem(source.schema) or "events") if trial is None else trial,
        max_frames=max_frames, sort=sort, slips=None if slips_path is None else read_slips(slips_path),
    )
    schema, batches, report, args = fr.frame(source, framing, sensor)
    echo_lines("frame", filter(None, [fr.size_note(schema, report.frames)]), "warning: ")  # now, before the writing starts
    tables.write(output, batches, step=("frame", args), schema=schema, flush_each=True)
    echo_lines("frame", report.messages(lead_in_expected=source.kind == "recordings"))

