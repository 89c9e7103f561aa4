"""`neurotac export`: an events table back into a camera file."""

import click

from neurotac_cli.options import input_paths


@click.command()
@input_paths
@click.option("-o", "--output", type=click.Path(dir_okay=False, writable=True), required=True,
              help="The camera file to write: .raw (Prophesee EVT 3.0), .aedat4 (iniVation AEDAT 4.0), .aedat (jAER AEDAT 2.0) "
              "or .h5/.hdf5 (HDF5, DSEC's layout).")
@click.option("--trial", default=None, help="Recordings: the trial to write (on the camera's clock, its t0 added back).")
def command(paths, output, trial):
    """Write events (imported, cropped, selected, simulated) as a camera file the vendors' tools
    read: EVT 3.0 (.raw, as OpenEB decodes it), AEDAT 4.0 (.aedat4, one uncompressed events stream,
    as dv reads it), AEDAT 2.0 (.aedat, DAVIS addresses, as jAER writes) or HDF5 (.h5, DSEC's layout:
    events/x, y, t, p with t_offset and ms_to_idx, gzip-compressed, for Python tools).
    Timestamps are written as in the table; EVT 3.0 keeps them when the first event lies within
    10 minutes of 0, and otherwise drops whole 2^24 µs loops (said on stderr).

    \b
        neurotac import rec.raw | neurotac crop --box 100,50,320,240 | neurotac export -o crop.raw
        neurotac simulate --preset ch4 --trials 1 --synced | neurotac export -o grasp.aedat4
    """
    from neurotac_cli import tables
    from neurotac_cli.export import export, export_format

    export_format(output)
    done = export(tables.read(paths, kind=("events", "recordings")), output, trial=trial)
    click.echo(f"neurotac export: wrote {done['events']:,} events to {output} ({done['format']}, {done['bytes']:,} bytes)", err=True)
    if done.get("unindexed"):
        click.echo("neurotac export: warning: the events are not in time order, so no ms_to_idx index was written "
                   "(tools that seek by millisecond need it: sort the events by t first)", err=True)
    if done["shift_us"]:
        click.echo(f"neurotac export: warning: times written {done['shift_us']:,} µs earlier (whole EVT 3.0 loops: "
                   "the recording starts after 10 minutes)", err=True)
