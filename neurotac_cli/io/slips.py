"""True slips of recorded or simulated sessions, from a CSV: what `frame --slips` labels frames with."""

import csv
import math

from neurotac_cli.errors import NeurotacError
from neurotac_cli.io.reader import refuse_device

START, END = "slip_start_ms", "slip_end_ms"
TRIAL_COLUMNS = ("trial", "session")  # `simulate --session` names a session's trial in `session`


def read_slips(path: str) -> dict[str, list[tuple[int, int]]]:
    """{trial: [(start µs, end µs), ...]} from a CSV with a trial (or session) column and
    slip_start_ms / slip_end_ms on the trial's synced clock. Rows with no slip start (grasps that
    did not slip, as in `simulate --session`'s grasps.csv) are skipped; every other row must hold a
    slip that ends after it starts."""
    refuse_device(path, "a CSV of true slips")
    try:
        with open(path, encoding="utf-8-sig", newline="") as source:  # a spreadsheet's export may start with a byte-order mark
            reader = csv.DictReader(source)
            columns = reader.fieldnames or []
            trial_column = next((name for name in TRIAL_COLUMNS if name in columns), None)
            missing = [name for name in (START, END) if name not in columns]
            if trial_column is None or missing:
                wanted = ", ".join((["trial (or session)"] if trial_column is None else []) + missing)
                raise NeurotacError(f"{path}: no {wanted} column for the true slips (columns: {', '.join(columns) or 'none'})")
            slips: dict[str, list[tuple[int, int]]] = {}
            for line, row in enumerate(reader, start=2):
                if not (row.get(START) or "").strip():
                    continue
                start, end = _ms(path, line, row, START), _ms(path, line, row, END)
                if not end > start:
                    raise NeurotacError(f"{path}, line {line}: the slip ends at {end / 1000:g} ms, not after its start at {start / 1000:g} ms")
                slips.setdefault(row[trial_column], []).append((start, end))
    except OSError as error:
        raise NeurotacError(f"{path}: cannot read the true slips ({error.strerror or error})") from None
    except (UnicodeDecodeError, csv.Error) as error:
        raise NeurotacError(f"{path}: not a CSV of true slips ({error})") from None
    return slips


def _ms(path: str, line: int, row: dict, column: str) -> int:
    text = (row.get(column) or "").strip()
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise NeurotacError(f"{path}, line {line}: {column} is {text!r}, not a time in ms")
    return round(value * 1000)
