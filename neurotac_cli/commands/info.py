"""`neurotac info`: what a table or camera file holds, for a person."""

import click

from neurotac_cli.options import Size, one_stdin


@click.command()
@click.argument("paths", nargs=-1, metavar="FILE|-", callback=one_stdin)
@click.option("--json", "as_json", is_flag=True, help="Print the description as JSON (for scripts) instead of text.")
@click.option("--all", "everything", is_flag=True, help="Show every trial and every metric row (the text shows the first 20 "
              "trials and 50 metric rows, --json the first 200 metric rows).")
@click.option("--sensor", type=Size(), default=None, help="For camera files that do not say their sensor size (DAT, text).")
def command(paths, as_json, everything, sensor):
    """Describe a table or camera file: kind, rows, trials, sensor, time span, event rate, ON share,
    labels per trial, frames per trial and window, and the history of commands that made it.

    Works on every table kind and, directly, on camera files (decoded, not written) and on CSV text
    that holds no events (a force log, with its samples, period and range as `sync` reads it; a
    manifest; a table written as CSV: its rows and columns). Several tables
    are described as one, as every command reads them. A model file from `neurotac train` is
    described from its header: the network, the frames it takes, its classes, how it was trained,
    and the commands that made its training frames.

    \b
        neurotac import recording.aedat | neurotac info -
        neurotac info frames.parquet --json | jq .frames_per_trial
        neurotac info force.model
    """
    import json

    from neurotac_cli.describe import describe_paths, format_text

    info = describe_paths(paths, sensor=sensor, everything=everything)
    if as_json:
        from neurotac_cli.textout import jsonable  # NaN as null: strict JSON parsers (jq) refuse a bare NaN

        click.echo(json.dumps(jsonable(info), indent=2, sort_keys=True, ensure_ascii=False))
    else:
        click.echo(format_text(info, everything), nl=False)

