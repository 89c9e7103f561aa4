"""Events as text: CSV with a header (`t,x,y,p`), or whitespace `t x y p` with t in float seconds.

CSV time unit comes from the header: `t`, `t_us` or `timestamp` = µs, `t_ms` = ms, `t_s` = s. In a
whitespace file (the public event-camera datasets' `events.txt`) a plain `t` is in seconds and the
header is optional. Polarity 0/1 or -1/1 (-1 = OFF). Leading `#` or `%` comment lines are skipped.
Parsing is pyarrow's multithreaded CSV reader, streamed block by block; a bad row is found again
by a line-by-line pass, only on the error path, so its line number can be reported.
"""

import re

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from neurotac_cli.errors import FormatError
from neurotac_cli.io import camera
from neurotac_cli.io.camera import Decoded

TIME_NAMES = {"t": None, "t_us": 1, "timestamp": 1, "ts": 1, "time": None, "t_ms": 1_000, "t_s": 1_000_000}
POLARITY_NAMES = ("p", "polarity", "pol")
MAX_COORDINATE = 65535


def open_text(path: str, head: bytes, sensor) -> Decoded:
    lines = head.decode("ascii", "replace").splitlines()
    skip = 0
    while skip < len(lines) and (not lines[skip].strip() or lines[skip].lstrip()[:1] in ("#", "%")):
        skip += 1
    if skip >= len(lines):
        raise FormatError("no rows after the comment lines")
    first = lines[skip]
    delimiter = "," if "," in first else ("\t" if "\t" in first else " ")
    fields = [f.strip() for f in (first.split(",") if delimiter == "," else first.split())]
    has_header = any(re.search(r"[a-zA-Z_]", f) and not _is_number(f) for f in fields)
    if has_header:
        names = [f.lower() for f in fields]
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
    factor = TIME_NAMES[time_name] or (1 if delimiter == "," else 1_000_000)
    data_line = skip + 1 + (1 if has_header else 0)  # 1-based line number of the first data row
    types = {name: pa.float64() if factor != 1 else pa.int64() for name in names}
    types.update({"x": pa.int64(), "y": pa.int64(), polarity_name: pa.int64()})

    def chunks():
        read = pacsv.ReadOptions(skip_rows=data_line - 1, column_names=names, block_size=max(1 << 12, min(camera.CHUNK_BYTES, 1 << 22)))
        parse = pacsv.ParseOptions(delimiter=delimiter)
        convert = pacsv.ConvertOptions(column_types=types, include_columns=[time_name, "x", "y", polarity_name])
        try:
            reader = pacsv.open_csv(path, read_options=read, parse_options=parse, convert_options=convert)
            for batch in reader:
                yield _columns(batch, time_name, polarity_name, factor)
        except (pa.ArrowInvalid, ValueError) as error:
            raise FormatError(_locate(path, data_line, names, delimiter, time_name, polarity_name, factor, error)) from None

    return Decoded(sensor=None, chunks=chunks)


def _columns(batch, time_name, polarity_name, factor):
    t = batch.column(time_name).to_numpy(zero_copy_only=False)
    x = batch.column("x").to_numpy(zero_copy_only=False)
    y = batch.column("y").to_numpy(zero_copy_only=False)
    p = batch.column(polarity_name).to_numpy(zero_copy_only=False)
    if any(column.null_count for column in batch.columns):
        raise ValueError("empty field")
    if factor != 1:
        if not np.isfinite(t).all():
            raise ValueError("time is not a finite number")
        t = np.rint(t * factor)
        if len(t) and np.abs(t).max() >= 2.0**62:
            raise ValueError("time out of range")
        t = t.astype(np.int64)
    if len(x) and (min(x.min(), y.min()) < 0 or max(x.max(), y.max()) > MAX_COORDINATE):
        raise ValueError("coordinate out of range")
    if len(p) and not np.isin(p, (-1, 0, 1)).all():
        raise ValueError("polarity is not 0/1 or -1/1")
    return t, x.astype(np.uint16), y.astype(np.uint16), (p > 0).astype(np.uint8)


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _locate(path, data_line, names, delimiter, time_name, polarity_name, factor, error) -> str:
    """Find the first bad row again, line by line, to name its line number."""
    with open(path, "rb") as handle:
        for number, raw in enumerate(handle, start=1):
            if number < data_line:
                continue
            line = raw.decode("utf-8", "replace").rstrip("\r\n")
            if not line.strip():
                continue
            fields = line.split(",") if delimiter == "," else line.split(delimiter)
            problem = _row_problem(fields, names, time_name, polarity_name, factor)
            if problem:
                return f"line {number}: {problem}: {line[:80]!r} (fix or delete that row)"
    return f"cannot parse the text ({str(error).splitlines()[0][:160]})"


def _row_problem(fields, names, time_name, polarity_name, factor) -> str | None:
    if len(fields) != len(names):
        return f"{len(fields)} fields where the header has {len(names)}"
    row = dict(zip(names, (f.strip() for f in fields)))
    try:
        t = float(row[time_name]) if factor != 1 else int(row[time_name])
        if t != t or abs(t) == float("inf"):
            return "time is not a finite number"
        x, y, p = int(row["x"]), int(row["y"]), int(row[polarity_name])
    except ValueError:
        kind = "a number" if factor != 1 else "whole microseconds, x, y and p integers"
        return f"not {kind}"
    if not (0 <= x <= MAX_COORDINATE and 0 <= y <= MAX_COORDINATE):
        return "coordinate out of range"
    if p not in (-1, 0, 1):
        return f"polarity {p} is not 0/1 or -1/1"
    return None
