"""`neurotac split`: training and test tables, whole trials, seeded."""

import click

from neurotac_cli.options import FiniteRange, TablePath, input_paths, seed_option


@click.command()
@input_paths
@click.option("--train", "train_path", type=TablePath(), required=True,
              help="Where the training trials go (a file by suffix, or - for stdout).")
@click.option("--test", "test_path", type=TablePath(), required=True,
              help="Where the test trials go (a file by suffix, or - for stdout).")
@click.option("--fraction", type=FiniteRange(0, 1, min_open=True, max_open=True), default=None, help="This share of the trials (drawn with --seed) goes to test.")
@click.option("--per", "per", metavar="LABEL", default=None, help="With --fraction: draw that share within each value of this label.")
@click.option("--where", "expression", metavar="SQL", default=None,
              help="The trials with a row for which this SQL condition holds go to test (e.g. object = 'bolt12').")
@seed_option
def command(paths, train_path, test_path, fraction, per, expression, seed):
    """Split a table into training and test tables by whole trials: a seeded share (--fraction,
    optionally per label value) or a condition (--where). An augmented copy goes where its source
    goes. The test trials are listed in both tables' history.

    \b
        neurotac split --fraction 0.2 --per object --seed 1 --train train.arrows --test test.arrows < frames.arrows
        neurotac split --where "object = 'bolt16'" --train seen.parquet --test unseen.parquet frames.parquet
    """
    from neurotac_cli import tables
    from neurotac_cli.errors import UsageError
    from neurotac_cli.ops.rows import split

    if train_path == test_path:
        raise UsageError("--train and --test must differ (give - to one of them for stdout)")
    tables.check_folder(*(path for path in (train_path, test_path) if path != "-"))
    tables.check_not_inputs(paths, train=train_path, test=test_path)
    table = tables.read(paths)
    train, test, report = split(table, fraction=fraction, where=expression, per=per, seed=seed)
    args = {"fraction": fraction, "per": per, "where": expression, "seed": seed, **report}
    parts = [(train_path, train, "train"), (test_path, test, "test")]
    # the file before stdout: a reader that stops early (`| head`) must not cost the other table;
    # both or neither replaced, so no trial is on both sides of an old and a new split
    with tables.together():
        for path, part, name in sorted(parts, key=lambda item: item[0] == "-"):
            tables.write(path, part, step=("split", dict(args, part=name)))
    click.echo(f"neurotac split: {report['train_trials']} trials ({report['train_rows']:,} rows) to {train_path}, "
               f"{report['test_trials']} ({report['test_rows']:,} rows) to {test_path}", err=True)
