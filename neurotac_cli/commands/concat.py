"""`neurotac concat`: one table of several, checked alike."""

import click

from neurotac_cli.options import one_stdin, output_option


@click.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(dir_okay=False, allow_dash=True), callback=one_stdin)
@output_option
@click.option("--rename", is_flag=True, help="Give a trial already seen in an earlier input the suffix ~2 (~3, ...) "
              "instead of refusing it, with a warning.")
def command(paths, output, rename):
    """Concatenate tables of one kind, sensor size and frame window, refusing a trial id that two
    inputs share (it would be trained on twice) unless --rename is given. Events tables are one
    recording each, on one clock, and are not joined: recordings tables (one trial per file) are.

    \b
        neurotac concat steel.arrows foam.arrows -o both.parquet
        neurotac sync --manifest day2/manifest.csv | neurotac concat day1.parquet - --rename > all.arrows
    """
    from neurotac_cli import tables
    from neurotac_cli.ops.rows import concat

    parts = [(path, tables.read([path])) for path in paths]
    table, notes = concat(parts, rename=rename)
    tables.write(output, table, step=("concat", {"inputs": list(paths), "rename": rename, "renamed": notes}))
    for note in notes:
        click.echo(f"neurotac concat: warning: {note}", err=True)
