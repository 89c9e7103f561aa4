"""`neurotac import`: camera files in, one events table out."""

import click

from neurotac_cli.options import Size, output_option

FORMAT_CHOICES = ["aedat2", "aedat4", "evt2", "evt3", "dat", "es", "csv", "text"]


@click.command("import")
@click.argument("paths", nargs=-1, required=True, metavar="FILE...")
@output_option
@click.option("--sensor", type=Size(), default=None, help="Sensor WxH where the file does not say (DAT, text), or to override it.")
@click.option(
    "--format",
    "fmt",
    type=click.Choice(FORMAT_CHOICES),
    default=None,
    help="Read the files as this format instead of telling it from their first bytes.",
)
@click.option("--one-stream", is_flag=True, help="Several files: read them in order as one events table instead of one "
              "trial per file.")
def command(paths, output, sensor, fmt, one_stream):
    """Read camera files into an events table (t µs, x, y, p; origin top-left; 1 = ON).

    Formats, told from the first bytes: AEDAT 2.0 (jAER; DAVIS chips, y flipped to image rows,
    APS/IMU words skipped), AEDAT 4.0, Prophesee EVT 2.0 and EVT 3.0 .raw and .dat, Event Stream .es, CSV with a `t,x,y,p` header (t in µs, or t_ms, t_s) and
    whitespace `t x y p` text with t in seconds. Timestamps are kept as the camera wrote them; external
    trigger events (AEDAT 4.0, EVT 2.0/3.0) go into the metadata for `sync --method trigger`; `-`
    reads a file from stdin. Several files, a directory or a glob give a recordings table with one
    trial per file, named after it, each starting at its first event (--one-stream: one events table).

    \b
        neurotac import recording.aedat -o events.parquet
        neurotac import events.txt --sensor 240x180 | neurotac info -
        neurotac import recordings/ | neurotac frame --window 10ms > frames.arrows
    """
    from neurotac_cli import tables
    from neurotac_cli.io import import_files

    args = {"files": list(paths), "sensor": f"{sensor[0]}x{sensor[1]}" if sensor else None, "format": fmt}
    from neurotac_cli import datasets  # several files, a directory or a glob: one trial per file

    files = datasets.expand(paths)
    if len(files) > 1 and not one_stream:
        return tables.write(output, datasets.recordings_per_file(files, sensor, fmt), step=("import", dict(args, files=files)))
    schema, batches = import_files(files, sensor=sensor, fmt=fmt)
    rows = [0]

    def counted():
        for batch in batches:
            rows[0] += batch.num_rows
            yield batch

    tables.write(output, counted(), schema=schema, step=("import", args))
    if not rows[0]:
        click.echo(f"neurotac import: warning: {', '.join(paths)}: no events in the file (an empty table was written)", err=True)
