"""Options shared by commands, as decorators, and the click parameter types for units."""

import click

from neurotac_cli.errors import NeurotacError
from neurotac_cli.units import parse_duration_us, parse_size


class ParamType(click.ParamType):
    """A parameter type whose name is shown in help as written: click upper-cases a type's name
    (`WxH` -> `WXH`, `N|longest` -> `N|LONGEST`), which then reads as a value the type refuses."""

    def get_metavar(self, param, ctx=None):
        return self.name


class Duration(ParamType):
    """A duration with its unit (`10ms`, `500us`, `1.5s`), as integer microseconds."""

    name = "DURATION"

    def __init__(self, positive: bool = False):
        self.positive = positive

    def convert(self, value, param, ctx):
        try:
            us = value if isinstance(value, int) else parse_duration_us(value)
        except NeurotacError as error:
            self.fail(str(error), param, ctx)
        if self.positive and us <= 0:
            self.fail(f"expected a positive duration, got {value!r}", param, ctx)
        return us


class Size(ParamType):
    """`WIDTHxHEIGHT`, as a (width, height) tuple."""

    name = "WxH"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            return parse_size(value)
        except NeurotacError as error:
            self.fail(str(error), param, ctx)


class KeyValue(ParamType):
    """`name=value`, as a (name, value) tuple."""

    name = "NAME=VALUE"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        name, sep, text = str(value).partition("=")
        if not sep or not name:
            self.fail(f"expected NAME=VALUE, got {value!r}", param, ctx)
        return name.strip(), text.strip()


def input_paths(function):
    return click.argument("paths", nargs=-1, type=click.Path(dir_okay=False, allow_dash=True))(function)


def output_option(function):
    return click.option(
        "-o",
        "--output",
        type=click.Path(dir_okay=False, writable=True),
        default=None,
        help="Write to this file (.parquet, .arrow, .feather or .arrows by suffix) instead of stdout.",
    )(function)


def seed_option(function):
    return click.option(
        "--seed", type=int, default=0, show_default=True, help="Seed of every random draw: same seed, same bytes."
    )(function)


def study_options(function):
    """`--jobs`, `--scheduler`, `--cache`: how a command runs many independent tasks (folds, grid
    points, seeds) through `neurotac_cli.study.run_tasks`. Adds the parameters `jobs`, `scheduler`, `cache`."""
    function = click.option(
        "--cache",
        type=click.Path(file_okay=False),
        default=None,
        envvar="NEUROTAC_CACHE",
        help="Keep each finished task's result in this folder, so a re-run of an interrupted study "
        "runs only the tasks still missing [env NEUROTAC_CACHE].",
    )(function)
    function = click.option(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        envvar="NEUROTAC_SCHEDULER",
        help="Run the tasks on a Dask distributed cluster, e.g. tcp://10.0.0.5:8786 (see docs/studies.md; "
        "SLURM/PBS through dask-jobqueue) [env NEUROTAC_SCHEDULER].",
    )(function)
    function = click.option(
        "--jobs",
        "-j",
        type=int,
        default=1,
        show_default=True,
        envvar="NEUROTAC_JOBS",
        help="Run this many tasks at once in local processes (0: one per CPU). Results do not depend on it "
        "[env NEUROTAC_JOBS].",
    )(function)
    return function
