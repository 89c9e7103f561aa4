"""`neurotac import`: camera files in, one events table out; live from a file being written, a pipe, or a replay."""

import click

from neurotac_cli.options import (Size, camera_input_options, one_stdin, echo_lines, history, idle_timeout_needs_follow, output_option,
                                  replay_speed)


@click.command("import")
@click.argument("paths", nargs=-1, required=True, metavar="FILE...", callback=one_stdin)
@output_option
@click.option("--sensor", type=Size(), default=None, help="Sensor WxH where the file does not say (DAT, HDF5, text), or to override it.")
@camera_input_options
@click.option("--one-stream", is_flag=True, help="Several files: read them in order as one events table instead of one "
              "trial per file.")
def command(paths, output, sensor, fmt, follow, idle_timeout, realtime, speed, one_stream):
    """Read camera files into an events table (t µs, x, y, p; origin top-left; 1 = ON).

    Formats, told from the first bytes: AEDAT 2.0 (jAER; DAVIS chips, y flipped to image rows,
    APS/IMU words skipped), AEDAT 3.1 (cAER; polarity events), AEDAT 4.0, Prophesee EVT 2.0, 2.1 and 3.0 .raw and .dat, Event Stream .es, HDF5 (.h5/.hdf5: Metavision's CD/events, DSEC's events/x,y,t,p,
    e2vid's events/xs,ys,ts,ps), CSV with a `t,x,y,p` header (t in µs, or t_ms, t_s) and
    whitespace `t x y p` text with t in seconds. Timestamps are kept as the camera wrote them; external
    trigger events (AEDAT 3.1/4.0, EVT 2.0/2.1/3.0) go into the metadata for `sync --method trigger`; `-`
    reads a file from stdin. Several files, a directory or a glob give a recordings table with one
    trial per file, named after it, each starting at its first event (--one-stream: one events table).

    Live input: AEDAT 4.0, EVT 3.0, 2.1 and 2.0, AEDAT 2.0/3.1, Event Stream and DAT from stdin, a FIFO or a
    process substitution (`<(...)`) are decoded as their bytes arrive, and so is a file still being
    written with --follow; each read's whole records go on as one batch at once (a record cut
    mid-write waits for its rest). A stream's external triggers cannot go into the metadata, which is
    written before they arrive: they are counted in a warning. Text, HDF5, and DAT without a sensor
    size are read whole. Ctrl-C (or SIGTERM) ends a followed file, a pipe or a replay with the output
    complete, exit 0.

    \b
        neurotac import recording.aedat -o events.parquet
        neurotac import events.txt --sensor 240x180 | neurotac info -
        neurotac import recordings/ | neurotac frame --window 10ms > frames.arrows
        neurotac import --follow cam.raw | neurotac frame --window 10ms | ...
        neurotac import --realtime --speed 2 session.aedat4 | neurotac frame --window 10ms | ...
    """
    from neurotac_cli import datasets, tables
    from neurotac_cli.io import events, live

    pace = replay_speed(realtime, speed)
    idle_timeout_needs_follow(follow)
    files = datasets.expand(paths)
    if len(files) > 1 and not one_stream and not (follow or realtime):
        recordings = datasets.recordings_per_file(files, sensor, fmt)
        tables.write(output, recordings, step=history(paths=files, unused=("idle_timeout",)))
        echo_lines("import", events.source_notes(recordings.schema), prefix="warning: ")
        return
    paths = files
    is_live = follow or realtime or any(live.is_stream(p) for p in paths)
    stop = live.stop_on_signals() if is_live else (lambda: False)
    stream = events.import_events(paths, sensor=sensor, fmt=fmt, follow=follow, idle_timeout=idle_timeout / 1e6,
                                speed=pace, stop=stop)
    tables.write(output, stream.batches, schema=stream.schema, step=history(paths=paths, unused=() if follow else ("idle_timeout",)),
                 flush_each=is_live)
    echo_lines("import", stream.notes, prefix="warning: ")
    if not stream.rows:
        # stopped before the first event was passed on, the file need not be empty
        why = "stopped before any event was passed on" if stop() else "no events in the file"
        click.echo(f"neurotac import: warning: {', '.join(paths)}: {why} (an empty table was written)", err=True)

