"""Durations and sizes as written on the command line: `10ms`, `500us`, `1.5s`, `115x115`."""

import math
import re

from neurotac_cli.errors import NeurotacError

_UNIT_US = {"us": 1, "µs": 1, "ms": 1_000, "s": 1_000_000, "min": 60_000_000, "h": 3_600_000_000}
_DURATION = re.compile(r"^\s*([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*(us|µs|ms|s|min|h)\s*$")
_UNIT_AT_END = re.compile(r"\d\s*(us|µs|ms|s|min|h)\s*$")


def parse_duration_us(text: str) -> int:
    """`10ms` -> 10000. A bare number is refused: peer tools disagree on its unit."""
    match = _DURATION.match(str(text))
    if not match:
        why = ("its number is not one" if _UNIT_AT_END.search(str(text)) else "a duration carries its unit")
        raise NeurotacError(f"cannot read duration {text!r} ({why}; write e.g. 10ms, 500us, 1.5s or 2e-3s)")
    value = float(match.group(1)) * _UNIT_US[match.group(2)]
    if not math.isfinite(value):
        raise NeurotacError(f"duration {text!r} is beyond any clock")
    if abs(value - round(value)) > 1e-6:
        raise NeurotacError(f"duration {text!r} is not a whole number of microseconds (use a finer unit)")
    return int(round(value))


def parse_size(text: str) -> tuple[int, int]:
    """`115x115` -> (width, height)."""
    match = re.match(r"^\s*(\d+)\s*[xX×]\s*(\d+)\s*$", str(text))
    width, height = (int(match.group(1)), int(match.group(2))) if match else (0, 0)
    if not width or not height:
        raise NeurotacError(f"cannot read size {text!r} (write WIDTHxHEIGHT, e.g. 240x180)")
    if max(width, height) > MAX_SIDE:
        raise NeurotacError(f"size {text!r} is beyond {MAX_SIDE} pixels a side (event coordinates are 16-bit)")
    return width, height


MAX_SIDE = 65535  # x and y of an event are uint16


def parse_ints(text: str, count: int) -> tuple[int, ...]:
    """`60,30,115,115` -> (60, 30, 115, 115): `count` comma-separated whole numbers >= 0."""
    try:
        parts = tuple(int(v) for v in str(text).split(","))
    except ValueError:
        parts = ()
    if len(parts) != count or min(parts) < 0:
        raise NeurotacError(f"expected {count} comma-separated whole numbers >= 0, got {text!r}")
    return parts


def is_whole(value) -> bool:
    """Whether `value` is a whole number (Python's or numpy's), not a bool, which Python counts as one."""
    import numbers

    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def first_few(names, most: int = 3) -> str:
    """`a, b, c, ...`: the first `most` of `names`, and an ellipsis where there are more."""
    names = list(names)
    return ", ".join(map(str, names[:most])) + (", ..." if len(names) > most else "")


def counted(n: int, noun: str) -> str:
    """`1 trial`, `3 trials`: a count and its noun, plural where it is not one."""
    return f"{n:,} {noun}{'' if n == 1 else 's'}"
