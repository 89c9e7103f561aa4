"""`neurotac select`: keep the rows of a table that a condition holds for."""

import click

from neurotac_cli.options import input_paths, output_option


@click.command()
@input_paths
@output_option
@click.option("--where", "expression", required=True, metavar="SQL",
              help="The condition, in SQL over the plain columns (DuckDB): material = 'steel' AND frame < 30; "
              "phase IN ('holding'); t BETWEEN 0 AND 200000 (µs). Rows where it is NULL are dropped.")
def command(paths, output, expression):
    """Keep the rows of any table (events, recordings, frames, predictions, metrics) for which a
    condition holds: trials, labels, phases, time spans. Tensors, lists and metadata pass unchanged;
    how many rows were kept and dropped goes to stderr and into the history.

    \b
        neurotac select --where "object = 'bolt12' AND phase = 'holding'" < frames.arrows > held.arrows
        neurotac select --where "t < 300000" events.parquet -o first-300ms.parquet
        neurotac select --where "scope LIKE 'trial:%' AND metric = 'rmse'" metrics.parquet -o per-trial.csv
    """
    from neurotac_cli import tables
    from neurotac_cli.ops.rows import select

    table = tables.read(paths)
    kept, report = select(table, expression)
    tables.write(output, kept, step=("select", {"where": expression, **report}))
    click.echo(f"neurotac select: kept {report['kept']:,} of {report['kept'] + report['dropped']:,} rows", err=True)
