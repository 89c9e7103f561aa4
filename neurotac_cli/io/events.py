"""Events from any path: a camera file, a pipe decoded as it arrives, several files as one table,
or a file followed while it is written. The one place that chooses between the file readers
(`io.camera`) and the live readers (`io.live`)."""

import os
from typing import Iterator

import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import InputError, UsageError
from neurotac_cli.io import camera, live


def read_events(path, sensor=None, fmt: str | None = None) -> tuple[pa.Schema, Iterator[pa.RecordBatch]]:
    """Decode a camera or text file into an `events` schema and an iterator of record batches.

    `sensor=(W, H)` supplies the size where the file does not say and overrides it where it does.
    `fmt` forces a format (one of FORMATS) instead of sniffing. Decoding happens lazily, chunk by
    chunk, as the batches are consumed; every decoding problem is raised as one `FormatError`.
    """
    if live.is_stream(path):  # a pipe, FIFO or process substitution: decoded as its bytes arrive
        stream = live.open_stream(path, sensor, fmt)
        return stream.schema, stream.batches
    local, cleanup = camera.local_path(path)
    name = "stdin" if path in (None, "-") else os.path.basename(str(path))
    return camera.read_local(local, name, sensor, fmt, cleanup)


def read_events_table(path, sensor=None, fmt: str | None = None) -> pa.Table:
    """The whole events table of a camera or text file (see `read_events`)."""
    schema, batches = read_events(path, sensor, fmt)
    return pa.Table.from_batches(list(batches), schema=schema)


def import_files(paths, sensor=None, fmt: str | None = None) -> tuple[pa.Schema, Iterator[pa.RecordBatch]]:
    """Several camera files, in order, as one events table (schema + lazily decoded batches).

    Every file must have the same sensor size (or `sensor` is given); the metadata `neurotac:source`
    names each file. A table given as a camera file is refused with a hint.
    """
    paths = list(paths)
    if not paths:
        raise InputError("no camera file given (e.g. `neurotac import recording.aedat -o events.parquet`)")
    opened = []
    for path in paths:
        if path not in (None, "-") and os.path.isfile(path) and camera.is_table(path) and fmt is None:
            raise InputError(f"{path} is already a table, not a camera file (pass it to the next command directly)")
        opened.append(read_events(path, sensor, fmt))
    schema = opened[0][0]
    common = common_sensor([s for s, _ in opened], paths)
    if common != sch.sensor_of(schema):
        schema = sch.set_meta(schema, sensor=sch.sensor_meta(*common))
    if len(opened) > 1:
        sources = [sch.get_meta(s, sch.SOURCE) for s, _ in opened]
        found = [sch.get_meta(s, "neurotac:triggers") for s, _ in opened]
        triggers = [t for each in found for t in (each or [])]
        schema = sch.set_meta(schema, source=sources, triggers=triggers if any(each is not None for each in found) else None)

    def batches():
        for _, part in opened:
            for batch in part:
                yield pa.RecordBatch.from_arrays(batch.columns, schema=schema)

    return schema, batches()


def common_sensor(schemas: list[pa.Schema], paths: list) -> tuple[int, int]:
    """The one sensor of several camera files' events schemas; InputError where they differ. A size
    guessed from a file's events is only the smallest sensor holding them, and one camera's files
    differ in it: it gives way to the largest guess, or to the size the other files state if it fits."""
    sizes = [sch.sensor_of(schema) for schema in schemas]
    guessed = [(sch.get_meta(schema, sch.SOURCE) or {}).get("sensor_from") == "events" for schema in schemas]
    stated = {size for size, guess in zip(sizes, guessed) if not guess}
    common = stated.pop() if len(stated) == 1 else (max(w for w, _ in sizes), max(h for _, h in sizes)) if not stated else None
    if common is None or any(w > common[0] or h > common[1] for (w, h), guess in zip(sizes, guessed) if guess):
        listed = ", ".join(f"{os.path.basename(str(p))}: {w}x{h}{' (guessed from its events)' if guess else ''}"
                           for p, (w, h), guess in zip(paths, sizes, guessed))
        raise InputError(f"the camera files have different sensor sizes ({listed}); import them separately, or give --sensor WxH")
    return common


def import_events(paths, sensor=None, fmt: str | None = None, follow: bool = False, idle_timeout: float = 2.0,
                  speed: float | None = None, stop=lambda: False) -> live.Stream:
    """What `neurotac import` reads: camera files in order as one events table; a pipe or stdin decoded
    as it arrives; with `follow`, one file still being written; with `speed`, replayed at `speed`
    times its recorded pace. `stop()` turning true ends a followed file, a pipe or a replay cleanly."""
    paths = list(paths)
    if follow and len(paths) != 1:
        raise UsageError(f"--follow reads one file at a time, got {len(paths)}; follow each in its own `neurotac import`")
    if follow or (len(paths) == 1 and live.is_stream(paths[0])):
        stream = live.open_stream(paths[0], sensor, fmt, follow=follow, idle_timeout=idle_timeout, stop=stop)
    else:
        stream = live.Stream(*import_files(paths, sensor=sensor, fmt=fmt))
    # a piped file read whole (HDF5, text) carries its reader's notes in the schema, as a file does
    stream.notes += source_notes(stream.schema)
    if speed is not None:
        stream.batches = live.replay(stream.batches, speed, stop, notes=stream.notes)
    stream.batches = _counted(stream, stream.batches)
    return stream


def source_notes(schema) -> list[str]:
    """A note for every camera file behind a table whose last record was cut short (not decoded), and
    each note a reader left about a file (`neurotac:source`'s `note`)."""
    notes = []
    for source in sch.camera_sources(schema):
        if isinstance(source, dict):
            if source.get("cut_bytes"):
                notes.append(live.cut_note(source.get("file", "a camera file"), source["cut_bytes"]))
            if source.get("note"):
                notes.append(f"{source.get('file', 'a camera file')}: {source['note']}")
    return notes


def _counted(stream: live.Stream, batches):
    """The batches, counting their events into `stream.rows` as they pass."""
    for batch in batches:
        stream.rows += batch.num_rows
        yield batch
