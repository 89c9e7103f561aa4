"""Force logs: CSV, Parquet or Arrow (Feather), one time column and one force column, read into µs and newtons.

By default the first column is time and the second force. Units come from the header's suffix:
time `t_ms`, `time_us`, `t_s` (also `_ns`, `_min`); force `force_N`, `force_mN`, `force_kN`, `fz_g`
(grams-force). A header without a unit suffix is an error for time (peer tools disagree on it) and
newtons for force (noted in the log's `notes`). Options override the columns and the time unit.

A log may hold several trials: a `trial` column groups them, or, without one, each point where
time steps back starts a new trial (a micro-controller that restarts its clock at each LED-off).
"""

import os
import re
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from neurotac_cli.errors import FormatError, InputError
from neurotac_cli.io.reader import refuse_device

TIME_UNITS_US = {"ns": 1e-3, "us": 1.0, "µs": 1.0, "ms": 1e3, "s": 1e6, "min": 6e7}
FORCE_UNITS_N = {"n": 1.0, "mn": 1e-3, "kn": 1e3, "g": 9.80665e-3, "kg": 9.80665, "lbf": 4.4482216}


@dataclass
class ForceLog:
    """One trial's force samples: time in µs from the log's zero, force in newtons."""

    t: np.ndarray
    value: np.ndarray
    trial: str | None = None
    notes: list = field(default_factory=list)

    @property
    def period_us(self) -> float:
        return float(np.median(np.diff(self.t))) if len(self.t) > 1 else 0.0


def _suffix(name: str) -> str | None:
    match = re.search(r"[_\[\( ]([A-Za-zµ]+)\]?\)?$", name.strip())
    return match.group(1) if match else None


def time_unit_of(name: str) -> str | None:
    suffix = _suffix(name)
    if suffix is None:
        return None
    for unit in TIME_UNITS_US:
        if suffix.lower() == unit.lower():
            return unit
    return None


def force_unit_of(name: str) -> str | None:
    suffix = _suffix(name)
    if suffix is None:
        return None
    return suffix.lower() if suffix.lower() in FORCE_UNITS_N else None


def read_table(path: str, what: str = "force log") -> pa.Table:
    """A force log's columns as written (CSV, Parquet or Arrow, told from the first bytes), before any is chosen.
    Read once, into memory (a log is small), so a pipe such as bash's `<(...)` serves as well as a file.
    `what` names the file in errors (`info` reads any CSV file with it)."""
    expected = "; expected CSV, Parquet or Arrow with a header such as t_ms,force_N" if what == "force log" else ""
    if os.path.isdir(path):
        raise InputError(f"{path}: is a folder, not a {what}")
    if not os.path.exists(path):
        raise InputError(f"{path}: no such {what}")
    refuse_device(path, f"a {what}")
    try:
        with open(path, "rb") as handle:
            data = handle.read()
    except OSError as error:
        raise InputError(f"{path}: cannot read the {what} ({error.strerror or error})") from None
    if not data:
        raise FormatError(f"{path}: the {what} is empty{expected}")
    try:
        if data[:4] == b"PAR1":
            import pyarrow.parquet as pq

            table = pq.read_table(pa.BufferReader(data))
        elif data.startswith((b"ARROW1", b"\xff\xff\xff\xff")):  # Arrow (Feather) from another tool
            table = _arrow_log(data, path)
        elif b"\0" in data[:4096]:
            raise FormatError(f"{path}: holds binary data, not a {what} (a camera file?){expected}")
        else:
            import pyarrow.csv as csv

            data = _without_comments(data)
            first = data.split(b"\n", 1)[0].decode(errors="replace")
            table = csv.read_csv(pa.BufferReader(data), parse_options=csv.ParseOptions(delimiter=_delimiter(first)))
    except (pa.ArrowInvalid, OSError) as error:
        raise FormatError(f"{path}: cannot read the {what} ({str(error).splitlines()[0]}{expected})") from None
    names = table.column_names
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise FormatError(f"{path}: the {what} names column {repeated[0]!r} more than once; give each column its own name")
    return table


def _without_comments(data: bytes) -> bytes:
    """A CSV log from its header on: loggers write `#` or `%` lines (firmware, date, settings) and blank
    lines above it, as camera text files do. Where numbers follow them, the last of those lines is the
    header (numpy's `savetxt(header=...)` writes `# t_ms,force_N`)."""
    data = data.removeprefix(b"\xef\xbb\xbf")
    start, last_comment = 0, None
    while start < len(data):
        end = data.find(b"\n", start)
        end = len(data) if end < 0 else end + 1
        line = data[start:end].strip()
        if line and line[:1] not in (b"#", b"%"):
            break
        if line:
            last_comment = line
        start = end
    if last_comment is not None and start < len(data) and data[start] in b"0123456789+-." and re.search(rb"[A-Za-z]", last_comment):
        return last_comment.lstrip(b"#% \t") + b"\n" + data[start:]
    return data[start:]


def _arrow_log(data: bytes, path: str) -> pa.Table:
    """An Arrow file or stream of a force log's columns; one of neurotac's own tables is no force log."""
    import pyarrow.ipc as ipc

    from neurotac_cli import schema as sch

    reader = ipc.open_file(pa.BufferReader(data)) if data.startswith(b"ARROW1") else ipc.open_stream(pa.BufferReader(data))
    table = reader.read_all()
    kind = sch.kind_of(table.schema)
    if kind:
        raise FormatError(f"{path}: is a neurotac {kind} table, not a force log; give the log the force sensor wrote (CSV, Parquet or Arrow)")
    return table


def _delimiter(line: str) -> str:
    for delimiter in (",", ";", "\t"):
        if delimiter in line:
            return delimiter
    return ","


def _column(table: pa.Table, chosen, default_index: int, what: str, path: str) -> str:
    names = table.column_names
    if chosen is None:
        usable = [name for name in names if name.lower() != "trial"]
        if len(usable) <= default_index:
            raise FormatError(f"{path}: a force log needs a time and a force column, found {', '.join(names) or 'none'}")
        return usable[default_index]
    if chosen in names:
        return chosen
    if str(chosen).isdigit() and int(chosen) < len(names):
        return names[int(chosen)]
    raise InputError(f"{path}: no {what} column {chosen!r} (columns: {', '.join(names)})")


RESTART_LEAST_SAMPLES = 10  # a trial of a log whose clock restarts per trial holds at least a grasp's samples


def _trial_rows(table: pa.Table, t_us: np.ndarray, path: str) -> list[tuple]:
    """(trial name or None, its rows) of a force log: by its `trial` column, else cut where the clock
    restarts (a log of several trials restarts its clock once per trial)."""
    if "trial" in table.column_names:
        names = np.asarray([str(v) for v in table.column("trial").to_pylist()], dtype=object)
        return [(name, np.flatnonzero(names == name)) for name in dict.fromkeys(names)]
    cuts = np.flatnonzero(np.diff(t_us) < 0) + 1
    bounds = np.concatenate([[0], cuts, [len(t_us)]])
    # not trials whose clocks restart, but a log out of order: steps back at most samples, or so often
    # that a typical run between them is shorter than a grasp's few samples
    if len(cuts) and (len(cuts) >= len(t_us) // 2 or (len(cuts) > 2 and np.median(np.diff(bounds)) < RESTART_LEAST_SAMPLES)):
        raise FormatError(f"{path}: force time runs backwards at {len(cuts):,} of {len(t_us):,} samples; sort the log by "
                          "time (a log of several trials restarts its clock once per trial)")
    return [(None, np.arange(a, b)) for a, b in zip(bounds[:-1], bounds[1:])]


def read_force_log(path: str, time_column=None, force_column=None, time_unit=None, force_unit=None) -> list[ForceLog]:
    """Read a force log into one ForceLog per trial (see the module doc for columns and units)."""
    table = read_table(path)
    time_name = _column(table, time_column, 0, "time", path)
    force_name = _column(table, force_column, 1, "force", path)
    notes = []
    typed = table.schema.field(time_name).type
    if pa.types.is_timestamp(typed) or pa.types.is_duration(typed):  # Parquet's time types carry their unit
        table = table.set_column(table.schema.get_field_index(time_name), time_name, table.column(time_name).cast(pa.int64()))
        time_unit = time_unit or typed.unit
    if pa.types.is_boolean(table.schema.field(force_name).type):
        raise FormatError(f"{path}: force column {force_name!r} holds true/false flags, not forces; name the force column "
                          "with --force-column")
    unit = time_unit or time_unit_of(time_name)
    if unit is None:
        raise InputError(
            f"{path}: cannot tell the unit of time column {time_name!r} (name it like t_ms, time_us or t_s, "
            "or give --force-time-unit ms)"
        )
    if unit not in TIME_UNITS_US:
        raise InputError(f"unknown time unit {unit!r} (use one of {', '.join(TIME_UNITS_US)})")
    funit = (force_unit or force_unit_of(force_name) or "n").lower()
    if funit not in FORCE_UNITS_N:
        raise InputError(f"unknown force unit {funit!r} (use one of N, mN, kN, g, kg, lbf)")
    if force_unit is None and force_unit_of(force_name) is None:
        suffix = _suffix(force_name)
        notes.append(f"force column {force_name!r} has no unit suffix: read as newtons" if suffix is None else
                     f"force column {force_name!r}: {suffix!r} is no force unit (N, mN, kN, g, kg, lbf): read as newtons "
                     "(give --force-unit if they are not)")
    try:
        # unsafe: a whole number past 2^53 is still a number (the range is checked below), not a cast error
        times = table.column(time_name).cast(pa.float64(), safe=False).to_numpy(zero_copy_only=False)
        values = table.column(force_name).cast(pa.float64(), safe=False).to_numpy(zero_copy_only=False)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        raise FormatError(f"{path}: time column {time_name!r} and force column {force_name!r} must be numbers") from None
    if not np.isfinite(times).all():
        raise FormatError(f"{path}: {int((~np.isfinite(times)).sum())} empty, infinite or non-numeric times in column {time_name!r}")
    if not np.isfinite(values).all():
        raise FormatError(f"{path}: {int((~np.isfinite(values)).sum())} force values are not numbers (NaN or empty, or inf); clean the force log first")
    if len(times) and np.abs(times).max() * TIME_UNITS_US[unit] >= 2.0**62:  # would wrap in int64 µs
        raise FormatError(f"{path}: force time {np.abs(times).max():g} {unit} is beyond what a clock in µs holds (about "
                          "146,000 years); check the time column and its unit (--force-time-unit)")
    t_us = np.round(times * TIME_UNITS_US[unit]).astype(np.int64)
    newtons = values * FORCE_UNITS_N[funit]
    logs = []
    for name, rows in _trial_rows(table, t_us, path):
        t = t_us[rows]
        if len(t) > 1 and np.diff(t).min() <= 0:
            bad = int(np.argmax(np.diff(t) <= 0)) + 1
            what = (f"repeats {t[bad] / 1000:g} ms" if t[bad] == t[bad - 1] else
                    f"goes back from {t[bad - 1] / 1000:g} ms to {t[bad] / 1000:g} ms")
            raw = times[rows]
            if t[bad] == t[bad - 1] and raw[bad] != raw[bad - 1]:  # distinct in the log, one µs once converted
                what += f" ({raw[bad - 1]:g} and {raw[bad]:g} {unit} round to one microsecond: is the unit {unit}?)"
            raise FormatError(f"{path}: force time {what} at sample {bad + 1} of trial {name or len(logs) + 1}; give every "
                              "sample its own time, in order (drop repeated rows, sort the log)")
        logs.append(ForceLog(t=t, value=newtons[rows], trial=name, notes=list(notes)))
    if not logs or not len(logs[0].t):
        raise FormatError(f"{path}: the force log has no samples")
    return logs
