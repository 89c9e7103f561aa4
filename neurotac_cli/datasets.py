"""Data sets: several camera files, a directory of them, or a glob, as one trial per file.

A directory gives its camera files (AEDAT, EVT .raw, DAT, ES), sorted by name, not its force logs
or manifests; a glob the shell did not expand (quoted, or matching nothing there) is expanded here.
Several files become a `recordings` table with one row per file: the trial is named after the file
(`grasp-01.aedat` -> `grasp-01`), t0 is its first event's time, its events are relative to t0, it
has no force. Its `frame` then starts each trial at its own first event, so no frames span the gap
between two recordings. Trial names two files share are refused.
"""

import glob
import os

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import InputError
from neurotac_cli.units import first_few

CAMERA_SUFFIXES = (".aedat", ".aedat4", ".raw", ".dat", ".es", ".h5", ".hdf5")


def expand(paths) -> list[str]:
    """The camera files that `paths` (files, directories, globs, `-`) name, in order."""
    files = []
    for path in paths:
        if path in (None, "-") or os.path.isfile(path):
            files.append(path)
        elif os.path.isdir(path):
            found = sorted(os.path.join(path, name) for name in os.listdir(path)
                           if name.lower().endswith(CAMERA_SUFFIXES) and os.path.isfile(os.path.join(path, name)))
            if not found:
                raise InputError(f"{path} holds no camera files ({', '.join(CAMERA_SUFFIXES)}); name the files to import")
            files += found
        elif glob.has_magic(path):
            found = sorted(glob.glob(path))
            if not found:
                raise InputError(f"{path} matches no file")
            files += found
        else:
            files.append(path)  # the reader says what is wrong with it
    return files


def recordings_per_file(paths: list[str], sensor=None, fmt: str | None = None) -> pa.Table:
    """One recordings row per camera file (see the module doc)."""
    from neurotac_cli import provenance
    from neurotac_cli.io.camera import trial_name
    from neurotac_cli.io.events import common_sensor, read_events_table

    rows, sources, named = [], [], {}
    for path in paths:
        events = read_events_table(path, sensor=sensor, fmt=fmt)
        name = trial_name(path)
        if name in named:
            raise InputError(f"{named[name]} and {path} would both be trial {name!r}; rename one, or import them separately")
        named[name] = path
        t = events.column("t").to_numpy()
        t0 = int(t.min()) if len(t) else 0
        columns = [events.column(c).to_numpy() for c in ("x", "y", "p")]
        rows.append({"trial": name, "t0": t0, "events": (t - t0, *columns), "force": (np.zeros(0, np.int64), np.zeros(0, np.float32))})
        sources.append(events.schema)
    width, height = common_sensor(sources, paths)
    table = sch.recordings_table(rows, width, height, sync={"method": "first event", "note": "t0 = each file's first event; no force"})
    return provenance.carry(table, sources)


FORCE_NAMES = ("{stem}_force.csv", "{stem}-force.csv", "{stem}.force.csv", "{stem}_force.parquet")
MANIFEST = "manifest.csv"


def folder_manifest(folder: str) -> tuple[str, str]:
    """(the manifest of a folder of camera files and force logs, what was done): the folder's
    manifest.csv when it has one, else one written there pairing each camera file with the force
    log named after it (`grasp-01.aedat` with `grasp-01_force.csv`), for the user to edit (labels
    are columns after trial,events,force)."""
    import csv

    from neurotac_cli.io.camera import trial_name

    path = os.path.join(folder, MANIFEST)
    if os.path.isfile(path):
        return path, f"using {path} (delete it to pair the folder's files by name again)"
    cameras = [name for name in sorted(os.listdir(folder)) if name.lower().endswith(CAMERA_SUFFIXES)]
    if not cameras:
        raise InputError(f"{folder} holds no camera files ({', '.join(CAMERA_SUFFIXES)}) and no {MANIFEST}")
    rows, alone = [], []
    for name in cameras:
        stem = trial_name(name)
        force = next((f.format(stem=stem) for f in FORCE_NAMES if os.path.isfile(os.path.join(folder, f.format(stem=stem)))), None)
        (rows.append([stem, name, force]) if force else alone.append(name))
    if alone:
        raise InputError(f"no force log for {len(alone)} camera file(s) in {folder} ({first_few(alone)})"
                         f"; name each {FORCE_NAMES[0].format(stem='<name>')}, "
                         f"or write {path} yourself (trial,events,force,<labels>)")
    from neurotac_cli.tables import atomic_file

    with atomic_file(path) as temporary, open(temporary, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["trial", "events", "force"])
        writer.writerows(rows)
    note = f"wrote {path} pairing {len(rows)} camera files with their force logs (add label columns to it, then sync again)"
    return path, note + _unpaired_force_logs(folder, {force for _, _, force in rows})


def _unpaired_force_logs(folder: str, paired: set) -> str:
    """The note's tail naming force logs no camera file is named after: a grasp left out of the
    manifest must not go unsaid (a camera file without its log is refused above)."""
    patterns = [name.format(stem="") for name in FORCE_NAMES]
    unpaired = [name for name in sorted(os.listdir(folder))
                if name not in paired and any(name.endswith(end) and len(name) > len(end) for end in patterns)]
    if not unpaired:
        return ""
    return f"; {len(unpaired)} force log(s) have no camera file of their name and were left out ({first_few(unpaired)})"
