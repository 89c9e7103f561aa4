"""Recordings to sync: camera files (or events tables) with their force logs and labels, from the
command line or from a manifest CSV."""

import csv
import os
from dataclasses import dataclass, field

import pyarrow as pa

from neurotac_cli import schema as sch, tables
from neurotac_cli.errors import NeurotacError, UsageError
from neurotac_cli.io.camera import is_table, trial_name
from neurotac_cli.io.events import read_events_table
from neurotac_cli.io.force import read_force_log


@dataclass
class Source:
    """One camera recording with its force log and labels (one manifest row, or the command line)."""

    trial: str
    events: pa.Table
    force: list  # list[ForceLog]
    labels: dict = field(default_factory=dict)


@dataclass(frozen=True)
class ForceOptions:
    time_column: str | None = None
    force_column: str | None = None
    time_unit: str | None = None
    force_unit: str | None = None

    def read(self, path: str) -> list:
        return read_force_log(path, self.time_column, self.force_column, self.time_unit, self.force_unit)


def read_camera(path: str, sensor=None) -> pa.Table:
    """A camera file in any format `import` reads, or an events table, as one events table."""
    if os.path.isfile(path) and is_table(path):  # a pipe is not peeked at: its first bytes would be lost
        table = tables.read([path], kind="events")
        try:
            return table.replace_schema_metadata(sch.with_given_sensor(table.schema, sensor).metadata)
        except UsageError as error:
            raise UsageError(f"{path}: {error}") from None
    return read_events_table(path, sensor=sensor)


MANIFEST_REQUIRED = ("trial", "events", "force")


def manifest_sources(path: str, force_options: ForceOptions, sensor=None, labels: dict | None = None):
    """Sources from a manifest CSV: one row per recording with columns trial, events, force (paths
    relative to the manifest's folder) and label columns. Columns named `true_*` (ground truth of
    simulated data) are neither used nor copied. Files are read one row at a time."""
    if not os.path.exists(path):
        raise NeurotacError(f"{path}: no such manifest")
    if not os.path.isfile(path):  # its entries are paths relative to its folder, which a pipe or device has not
        raise NeurotacError(f"{path} is a pipe or device, not a manifest file; give the path of the manifest CSV")
    try:  # utf-8-sig: a spreadsheet's "CSV UTF-8" export starts with a byte-order mark, which is no part of a column name
        with open(path, encoding="utf-8-sig", newline="") as handle:
            reader = csv.DictReader(handle)
            names = reader.fieldnames or []  # read while the file is open: the reader reads its header lazily
            rows = list(reader)
    except (UnicodeDecodeError, csv.Error) as error:
        raise NeurotacError(f"{path}: not a CSV manifest ({error})") from None
    if not names:
        raise NeurotacError(f"{path}: the manifest is empty; expected a header trial,events,force,<labels>... and a row per recording")
    _check_manifest(path, names, rows)
    if not rows:
        raise NeurotacError(f"{path}: the manifest has no rows")
    missing = [name for name in MANIFEST_REQUIRED if name not in rows[0]]
    if missing:
        raise NeurotacError(
            f"{path}: the manifest has no {', '.join(missing)} column (columns: {', '.join(rows[0])}; "
            "expected trial,events,force,<labels>...)"
        )
    folder = os.path.dirname(os.path.abspath(path))
    label_names = [name for name in rows[0] if name not in MANIFEST_REQUIRED and not name.startswith("true_") and name]
    for number, row in enumerate(rows, start=2):
        if not row["events"] or not row["force"] or not row["trial"]:
            raise NeurotacError(f"{path}: line {number} lacks a trial, events or force entry")
        row_labels = dict(labels or {})
        row_labels.update({name: row[name] for name in label_names if row.get(name) not in (None, "")})
        yield Source(
            trial=row["trial"],
            events=read_camera(os.path.join(folder, row["events"]), sensor),
            force=force_options.read(os.path.join(folder, row["force"])),
            labels=row_labels,
        )


def _check_manifest(path: str, header: list, rows: list[dict]) -> None:
    """Refuse what a dict of each row would lose without a word: a column named twice (one value
    would win), a row with more or fewer cells than the header, one recording on two rows."""
    named_twice = sorted({name for name in header if name and header.count(name) > 1})
    if named_twice:
        raise NeurotacError(f"{path}: column {', '.join(named_twice)} appears twice in the header; each column needs its own name")
    seen = {}
    for number, row in enumerate(rows, start=2):
        if None in row or None in row.values():
            cells = len(header) + len(row.get(None) or []) - sum(value is None for value in row.values())
            raise NeurotacError(f"{path}: line {number} has {cells} cells, the header {len(header)}; "
                                "quote a cell holding a comma, and give every row every column")
        events = os.path.normpath(row.get("events") or "")
        if events in seen and events != ".":
            # the same recording twice would count as two trials (and could land in both train and test)
            raise NeurotacError(f"{path}: line {number} names the events file {row['events']} again (line {seen[events]}); "
                                "give each recording one row")
        seen[events] = number


def folder_as_manifest(events, manifest, force):
    """A folder given as EVENTS: (None, its manifest, a note for the user), the manifest written by
    pairing camera files with force logs by name when the folder has none; anything else as given."""
    if events in (None, "-") or not os.path.isdir(events) or manifest or force:
        return events, manifest, None
    from neurotac_cli.datasets import folder_manifest

    manifest, note = folder_manifest(events)
    return None, manifest, note


def recording_sources(events=None, force=None, manifest=None, *, trial=None, labels=None,
                      force_options: ForceOptions = ForceOptions(), sensor=None):
    """The recordings `neurotac sync` is given: a manifest's rows, or one events file (or an events
    table on stdin, `-`) with its force log; `labels` are given to every trial."""
    labels = dict(labels or {})
    if manifest:
        if events or force:
            raise UsageError("give either --manifest or an events file with --force, not both")
        return manifest_sources(manifest, force_options, sensor, labels)
    if not force:
        raise UsageError("sync needs a force log (--force FILE) or a manifest (--manifest FILE)")
    if events in (None, "-"):
        table = tables.read(["-"], kind="events")
        name = trial or trial_name(sch.camera_source(table.schema).get("file") or "trial")
    else:
        table, name = read_camera(events, sensor), trial or trial_name(events)
    return [Source(trial=name, events=table, force=force_options.read(force), labels=labels)]
