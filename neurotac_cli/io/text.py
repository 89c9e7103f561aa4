"""Events as text: CSV with a header (`t,x,y,p`), or whitespace `t x y p` with t in float seconds.

CSV time unit comes from the header: `t`, `t_us` or `timestamp` = µs, `t_ms` = ms, `t_s` = s. In a
whitespace file (the public event-camera datasets' `events.txt`) a plain `t` is in seconds and the
header is optional. Polarity 0/1 or -1/1 (-1 = OFF). Leading `#` or `%` comment lines are skipped.
Parsing is one compiled pass over the bytes (kernels.parse_text), block by block of whole lines;
times are scaled to µs from their decimal digits, exactly (no float rounding; finer than µs is
rounded half away from zero). The first bad row stops the read with its line number.
"""

import os
import re

import numpy as np

from neurotac_cli.errors import FormatError
from neurotac_cli.io import reader
from neurotac_cli.io.reader import Decoded

TIME_NAMES = {"t": None, "t_us": 1, "timestamp": 1, "ts": 1, "time": None, "t_ms": 1_000, "t_s": 1_000_000}
POLARITY_NAMES = ("p", "polarity", "pol", "on")  # faery's CSV: `t,x@W,y@H,on`, the sensor size after the @


BOM = b"\xef\xbb\xbf"  # a spreadsheet's "CSV UTF-8" export starts with this byte-order mark: no part of the first column


def column_names(fields: list[str]) -> tuple[list[str], dict]:
    """The header's column names (unquoted, lower case, without a `@SIZE`) and the sizes given that way."""
    names = [f.strip().strip("\"'").lower() for f in fields]
    sizes = dict(name.split("@", 1) for name in names if "@" in name)
    return [name.split("@", 1)[0] for name in names], sizes


def names_events(names: list[str]) -> bool:
    """Whether header column names (`column_names`) name events: a time, x, y and a polarity."""
    return any(n in TIME_NAMES for n in names) and "x" in names and "y" in names and any(n in POLARITY_NAMES for n in names)


def open_text(path: str, head: bytes, sensor) -> Decoded:
    lines = head.removeprefix(BOM).decode("ascii", "replace").splitlines()
    skip = 0
    while skip < len(lines) and (not lines[skip].strip() or lines[skip].lstrip()[:1] in ("#", "%")):
        skip += 1
    if skip >= len(lines):
        raise FormatError("no rows after the comment lines")
    first = lines[skip]
    delimiter = "," if "," in first else ("\t" if "\t" in first else " ")
    fields = [f.strip() for f in (first.split(",") if delimiter == "," else first.split())]
    has_header = any(re.search(r"[a-zA-Z_]", f) and not _is_number(f) for f in fields)
    declared = None
    if has_header:
        names, sizes = column_names(fields)
        if sizes.get("x", "").isdigit() and sizes.get("y", "").isdigit():
            declared = (int(sizes["x"]), int(sizes["y"]))
    elif delimiter == ",":
        raise FormatError(
            "a CSV file needs a header naming its columns, e.g. `t,x,y,p` (t in µs; or t_ms, t_s); add one as the first line"
        )
    else:
        if len(fields) != 4:
            raise FormatError(f"line {skip + 1} has {len(fields)} fields, expected 4 (t x y p, t in seconds)")
        names = ["t_s", "x", "y", "p"]
    time_name = next((n for n in names if n in TIME_NAMES), None)
    polarity_name = next((n for n in names if n in POLARITY_NAMES), None)
    missing = [label for label, found in (("t", time_name), ("x", "x" in names), ("y", "y" in names), ("p", polarity_name)) if not found]
    if missing:
        raise FormatError(f"header {first.strip()!r} has no {', '.join(missing)} column (expected t,x,y,p; t may be t_us, t_ms or t_s)")
    repeated = next((n for n in (time_name, "x", "y", polarity_name) if names.count(n) > 1), None)
    if repeated:  # which of the two columns holds the events cannot be told
        raise FormatError(f"header {first.strip()!r} names column {repeated!r} more than once; give each column its own name")
    factor = TIME_NAMES[time_name] or (1 if delimiter == "," else 1_000_000)
    if TIME_NAMES[time_name] is None and delimiter != "," and has_header:
        _refuse_whole_seconds(lines[skip + 1:], names.index(time_name), time_name)
    data_line = skip + 1 + (1 if has_header else 0)  # 1-based line number of the first data row
    roles = np.array([{time_name: 0, "x": 1, "y": 2, polarity_name: 3}.get(name, -1) for name in names], dtype=np.int64)
    time_digits = {1: 0, 1_000: 3, 1_000_000: 6}[factor]

    def chunks():
        from neurotac_cli.io import kernels

        line = data_line
        for block in _line_blocks(path, data_line):
            data = np.frombuffer(block, dtype=np.uint8)
            t, x, y, p, rows, status, offset, newlines = kernels.parse_text(data, roles, delimiter == ",", time_digits)
            if status != kernels.TEXT_OK:
                raw = bytes(block)
                number = line + raw.count(b"\n", 0, offset)
                start = raw.rfind(b"\n", 0, offset) + 1
                end = raw.find(b"\n", offset)
                text = raw[start : end if end >= 0 else len(raw)].decode("utf-8", "replace").rstrip("\r")
                culprit = _culprit(text, roles, delimiter == ",", status)
                raise FormatError(f"line {number}: {kernels.TEXT_PROBLEMS[status]}: {culprit[:80]!r} (fix or delete that row)")
            line += newlines
            yield t, x, y, p

    return Decoded(sensor=declared, chunks=chunks)


def _line_blocks(path: str, first_line: int):
    """The file from line `first_line` on, in blocks of whole lines of about CHUNK_BYTES (memoryviews:
    no copies; a block's last line continues into the next read when it is cut)."""
    with open(path, "rb") as handle:
        if handle.read(len(BOM)) != BOM:
            handle.seek(0)
        for _ in range(first_line - 1):
            handle.readline()
        remaining = os.fstat(handle.fileno()).st_size - handle.tell()
        rest = b""
        while remaining > 0:
            block = handle.read(min(max(reader.CHUNK_BYTES, 1 << 12), remaining))
            if not block:
                break
            remaining -= len(block)
            data = rest + block if rest else block
            cut = len(data) if remaining <= 0 else data.rfind(b"\n") + 1
            if cut == 0:
                rest = data
                continue
            rest = data[cut:]
            yield memoryview(data)[:cut]
        if rest:
            yield memoryview(rest)


def _refuse_whole_seconds(rows: list[str], column: int, name: str) -> None:
    """A plain `t` in whitespace text is in seconds (the public datasets' `events.txt`, whose times
    carry decimals); whole numbers under it are more likely a CSV's µs written with tabs or spaces,
    which read as seconds would be a million times too late."""
    read = [row.split() for row in rows[:50] if row.strip() and row.lstrip()[:1] not in ("#", "%")]
    values = [fields[column] for fields in read if len(fields) > column]
    whole = [value for value in values if _is_number(value) and not any(mark in value.lower() for mark in (".", "e"))]
    if values and len(whole) == len(values):  # every row read so far: a seconds file's first time may be a plain 0
        value = whole[-1]
        raise FormatError(f"whitespace text whose column {name!r} holds whole numbers ({value}): a plain {name!r} here is "
                          "seconds, which whole numbers rarely are; name the column t_us, t_ms or t_s (or write the file "
                          "with commas, where a plain t is µs)")


def _is_coordinate(field: str) -> bool:
    """A pixel coordinate as the kernel reads it: a whole number 0..65535, written 5, 5.0 or 5e0."""
    return _is_number(field) and float(field).is_integer() and 0 <= float(field) <= 65535


def _culprit(line: str, roles: np.ndarray, comma: bool, status: int) -> str:
    """The field of a bad row to quote (the kernel says which row and what is wrong, not which field);
    the whole row where it has the wrong number of fields or no one field is to blame."""
    from neurotac_cli.io import kernels

    fields = [field.strip() for field in (line.split(",") if comma else line.split())]
    if status == kernels.TEXT_FIELDS or len(fields) != len(roles):
        return line
    read = [(field, int(role)) for field, role in zip(fields, roles) if role >= 0]
    if status == kernels.TEXT_NUMBER:
        blamed = [field for field, _ in read if not _is_number(field)]
    elif status == kernels.TEXT_COORDINATE:
        blamed = [field for field, role in read if role in (1, 2) and not _is_coordinate(field)]
    elif status == kernels.TEXT_POLARITY:
        blamed = [field for field, role in read if role == 3]
    elif status == kernels.TEXT_FRACTION:
        blamed = [field for field, role in read if role == 0]
    else:  # too many digits: the longest
        blamed = sorted((field for field, _ in read), key=len, reverse=True)[:1]
    return blamed[0] if blamed else line


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False
