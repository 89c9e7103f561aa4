"""Options shared by commands, as decorators, and the click parameter types for units."""

import click

from neurotac_cli.errors import NeurotacError
from neurotac_cli.units import parse_duration_us, parse_size


class Duration(click.ParamType):
    """A duration with its unit (`10ms`, `500us`, `1.5s`), as integer microseconds."""

    name = "DURATION"

    def convert(self, value, param, ctx):
        if isinstance(value, int):
            return value
        try:
            return parse_duration_us(value)
        except NeurotacError as error:
            self.fail(str(error), param, ctx)


class Size(click.ParamType):
    """`WIDTHxHEIGHT`, as a (width, height) tuple."""

    name = "WxH"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            return parse_size(value)
        except NeurotacError as error:
            self.fail(str(error), param, ctx)


class KeyValue(click.ParamType):
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
