"""Events tables back into camera files, for the vendors' tools: Prophesee EVT 3.0 (.raw), iniVation
AEDAT 4.0 (.aedat4, `aedat4_bytes`), jAER AEDAT 2.0 (.aedat, io/writers.py), and HDF5 in DSEC's layout
(.h5/.hdf5, `write_hdf5`) for Python tools.

EVT 3.0 is 16-bit little-endian words after a `%` header (`% evt 3.0`, `% format EVT3;height=H;width=W`,
`% geometry WxH`, `% end`). Time is a 24-bit µs counter: TIME_HIGH (0x8) holds bits 12-23, TIME_LOW
(0x6) bits 0-11; a reader counts a loop of 2^24 µs each time TIME_HIGH falls back, so a TIME_HIGH is
written for every 4096 µs step of the recording, events or not, as a camera does. Each event is an
EVT_ADDR_Y (0x0, written when the row changes) and an EVT_ADDR_X (0x2: x, polarity in bit 11), after
a TIME_LOW when its time changes. A reader starts at time 0, so the TIME_HIGH steps are written from
0 and times come back as they were; a recording that starts later than 10 minutes (Unix time, as
AEDAT 4.0 writes) is written from the 2^24 µs loop of its first event instead, and comes back
earlier by whole loops (`shift_us` in the report). Events must be in time order, as EVT 3.0 cannot go back in time.
"""

import io
import os
import struct

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, UsageError

EVT3_LOOP_US = 1 << 24
WALK_LIMIT_US = 600_000_000  # first events up to 10 min in: TIME_HIGH walked from 0 (146k words at most)
FORMATS = {".raw": "evt3", ".aedat": "aedat2", ".aedat4": "aedat4", ".h5": "hdf5", ".hdf5": "hdf5"}
AEDAT4_PACKET_EVENTS = 1 << 15
AEDAT4_EVENT = np.dtype({"names": ["t", "x", "y", "on"], "formats": ["<i8", "<i2", "<i2", "u1"], "offsets": [0, 8, 10, 12], "itemsize": 16})


def export_format(path: str) -> str:
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in FORMATS:
        raise UsageError(f"cannot tell the camera format of {path!r} from its suffix (use .raw for EVT 3.0, .aedat4 for AEDAT 4.0, "
                         ".aedat for AEDAT 2.0, .h5 for HDF5)")
    return FORMATS[suffix]


MAX_TIME_WORDS = 50_000_000  # EVT 3.0 time words of an export (100 MB: over 57 hours of camera time)


def evt3_bytes(t, x, y, p, width: int, height: int) -> tuple[bytes, int]:
    """(the bytes of an EVT 3.0 file, the whole loops taken off the times in µs)."""
    t = np.asarray(t, dtype=np.int64)
    if len(t) and np.any(np.diff(t) < 0):
        raise NeurotacError("EVT 3.0 cannot go back in time: the events are not in time order (sort them by t first)")
    if len(t) and t[0] < 0:
        raise NeurotacError(f"EVT 3.0 times start at 0, the first event is at {int(t[0])} µs (export a recordings trial "
                            "with --trial, which puts it back on the camera's clock, or shift the times)")
    if width > 2048 or height > 2048:
        raise NeurotacError(f"EVT 3.0 addresses 2048x2048 pixels at most, the sensor is {width}x{height}")
    header = f"% evt 3.0\n% format EVT3;height={height};width={width}\n% geometry {width}x{height}\n% end\n".encode()
    if not len(t):
        return header, 0
    shift = 0 if t[0] < WALK_LIMIT_US else int(t[0]) // EVT3_LOOP_US * EVT3_LOOP_US
    t = t - shift
    high = t >> 12
    y = np.asarray(y, dtype=np.int64)
    # before each event: the TIME_HIGH steps since the previous event's (every one, so loops are seen),
    # a TIME_LOW when its time changes, an ADDR_Y when its row changes (or a TIME_HIGH came between)
    previous = np.r_[-1, high[:-1]]  # the clock is walked from 0 (a reader counts loops from there)
    highs_before = high - previous
    if highs_before.sum() > MAX_TIME_WORDS:  # a gap of hours between two events, or times in the wrong unit
        gap = int(np.argmax(np.diff(t))) if len(t) > 1 else 0
        raise NeurotacError(f"EVT 3.0 writes a time word every 4.096 ms, and these events span {int(t[-1] - t[0]) / 1e6:,.0f} s "
                            f"(the largest gap, {int(t[gap + 1] - t[gap]) / 1e6 if len(t) > 1 else 0:,.0f} s, after event {gap:,}): "
                            f"{int(highs_before.sum()) * 2 / 1e6:,.0f} MB of time words; select the part with events, or export .aedat4")
    new_time = np.r_[True, np.diff(t) != 0]
    new_row = np.r_[True, np.diff(y) != 0] | (highs_before > 0)
    per_event = highs_before + new_time + new_row + 1
    out = np.empty(int(per_event.sum()), dtype=np.uint16)
    start = np.cumsum(per_event) - per_event
    within = np.arange(highs_before.sum()) - np.repeat(np.cumsum(highs_before) - highs_before, highs_before)
    out[np.repeat(start, highs_before) + within] = (0x8 << 12) | ((np.repeat(previous + 1, highs_before) + within) & 0xFFF)
    at = start + highs_before
    out[at[new_time]] = (0x6 << 12) | (t[new_time] & 0xFFF)
    at = at + new_time
    out[at[new_row]] = (0x0 << 12) | (y[new_row] & 0x7FF)
    at = at + new_row
    out[at] = (0x2 << 12) | ((np.asarray(p, dtype=np.int64) & 1) << 11) | (np.asarray(x, dtype=np.int64) & 0x7FF)
    return header + out.astype("<u2").tobytes(), shift


def aedat4_bytes(t, x, y, p, width: int, height: int) -> bytes:
    """The bytes of an AEDAT 4.0 file: one uncompressed events stream (id 0), as dv writes it.

    After `#!AER-DAT4.0\\r\\n`, the IOHeader flatbuffer (compression none, no file data table, the
    stream described in dv's XML with sizeX/sizeY) with its length before it, then packets:
    stream id, length, and a size-prefixed EventPacket flatbuffer (identifier EVTS) of 16-byte
    Event structs (t int64 µs, x int16, y int16, on bool). The flatbuffers are laid out by hand:
    fixed tables, offsets pointing forward, the struct vector 8-byte aligned."""
    description = (
        '<dv version="2.0"><node name="outInfo" path="/mainloop/neurotac/outInfo/">'
        '<node name="0" path="/mainloop/neurotac/outInfo/0/">'
        '<attr key="compression" type="string">NONE</attr>'
        '<attr key="originalModuleName" type="string">neurotac</attr>'
        '<attr key="originalOutputName" type="string">events</attr>'
        '<attr key="typeDescription" type="string">Array of events (polarity ON/OFF).</attr>'
        '<attr key="typeIdentifier" type="string">EVTS</attr>'
        '<node name="info" path="/mainloop/neurotac/outInfo/0/info/">'
        f'<attr key="sizeX" type="int">{int(width)}</attr><attr key="sizeY" type="int">{int(height)}</attr>'
        '<attr key="source" type="string">neurotac</attr></node></node></node></dv>'
    ).encode()
    if width > 32768 or height > 32768:  # dv's Event holds x and y as int16: a larger one would wrap negative
        raise NeurotacError(f"AEDAT 4.0 addresses 32768x32768 pixels at most (16-bit signed x and y), the sensor is {width}x{height}")
    # IOHeader: root offset, "IOHE", vtable (10 bytes) at 8, table at 24: soffset, compression at +4,
    # file_data_position (int64, 8-aligned) at +8, description offset at +16 -> string at 44
    header = struct.pack("<I4sHHHHH6xiiqI", 24, b"IOHE", 10, 20, 4, 8, 16, 16, 0, -1, 4)
    header += struct.pack("<I", len(description)) + description + b"\0"
    header += b"\0" * (-len(header) % 4)
    out = [b"#!AER-DAT4.0\r\n", struct.pack("<I", len(header)), header]
    events = np.zeros(len(t), dtype=AEDAT4_EVENT)
    events["t"], events["x"], events["y"], events["on"] = t, x, y, np.asarray(p) > 0
    for start in range(0, len(events), AEDAT4_PACKET_EVENTS):
        part = events[start : start + AEDAT4_PACKET_EVENTS]
        # size prefix, root offset (table at 20), "EVTS", vtable (6 bytes) at 12, table: soffset 8 and
        # the vector's offset (to 28), vector length at 28, elements from 32
        packet = struct.pack("<II4sHHH2xiII", 28 + 16 * len(part), 16, b"EVTS", 6, 8, 4, 8, 4, len(part)) + part.tobytes()
        out += [struct.pack("<II", 0, len(packet)), packet]
    return b"".join(out)


MS_TO_IDX_MOST = 30 * 24 * 3600 * 1000  # milliseconds: a longer span is a clock jump, not a recording
MS_BLOCK = 1 << 20  # milliseconds of ms_to_idx computed at once, so memory stays flat however long the span


def _write_ms_to_idx(handle, t: np.ndarray) -> None:
    """DSEC's `ms_to_idx` of time-sorted events `t` (µs from the first), written a block at a time,
    compressed: one entry per millisecond of the span, which a clock jump would make enormous."""
    count = int(t[-1]) // 1000 + 2 if len(t) else 1
    if count > MS_TO_IDX_MOST:
        raise NeurotacError(f"the events span {count / 8.64e7:.1f} days, beyond the {MS_TO_IDX_MOST // 86_400_000} days "
                            "an HDF5 ms_to_idx index is written for (a clock jump?); cut the events first (`neurotac select`)")
    dataset = handle.create_dataset("ms_to_idx", shape=(count,), dtype=np.uint64, chunks=True, compression="gzip", compression_opts=4)
    for start in range(0, count, MS_BLOCK):
        milliseconds = np.arange(start, min(count, start + MS_BLOCK), dtype=np.int64) * 1000
        dataset[start:start + len(milliseconds)] = np.searchsorted(t, milliseconds).astype(np.uint64)


def write_hdf5(path: str, t, x, y, p, width: int, height: int) -> bool:
    """An HDF5 file in DSEC's layout: `events/{x, y, t, p}` (uint16, uint16, int64 µs after `t_offset`,
    uint8 0/1), `t_offset` (the first event's time, µs) and, for time-sorted events, `ms_to_idx` (the
    index of the first event at or after each millisecond from `t_offset`); the sensor as `width`,
    `height` and `geometry` attributes. gzip-compressed, which every HDF5 reader decodes without a
    plugin. Returns whether `ms_to_idx` was written (it needs the events in time order)."""
    import h5py

    t = np.asarray(t, dtype=np.int64)
    offset = int(t.min()) if len(t) else 0
    ordered = not len(t) or bool(np.all(np.diff(t) >= 0))
    chunked = {"chunks": True, "compression": "gzip", "compression_opts": 4, "shuffle": True} if len(t) else {}
    # built in memory (compressed, it is smaller than the arrays) and written to disk here: HDF5 that
    # meets a full disk fails again in each of its objects' clean-up, a dozen "Exception ignored"
    # tracebacks and then a segmentation fault
    image = io.BytesIO()
    with h5py.File(image, "w") as handle:
        group = handle.create_group("events")
        group.create_dataset("x", data=np.asarray(x, dtype=np.uint16), **chunked)
        group.create_dataset("y", data=np.asarray(y, dtype=np.uint16), **chunked)
        group.create_dataset("t", data=t - offset, **chunked)
        group.create_dataset("p", data=(np.asarray(p) > 0).astype(np.uint8), **chunked)
        handle.create_dataset("t_offset", data=np.int64(offset))
        if ordered:
            _write_ms_to_idx(handle, t - offset)
        handle.attrs["width"], handle.attrs["height"] = int(width), int(height)
        handle.attrs["geometry"] = f"{int(width)}x{int(height)}"
    with open(path, "wb") as sink:
        sink.write(image.getbuffer())
    return ordered


def events_arrays(table: pa.Table, trial: str | None = None) -> tuple:
    """(t, x, y, p, width, height) of an events table, or of one trial of a recordings table on the
    camera's clock (t0 added back)."""
    kind = sch.table_kind(table.schema)
    sensor = sch.sensor_of(table.schema)
    if sensor is None:
        raise NeurotacError("the table does not say its sensor size, which a camera file needs (import with --sensor WxH)")
    if kind == "events":
        if trial is not None:
            raise NeurotacError("--trial picks a trial of a recordings table; an events table is one recording")
        columns = [table.column(name).to_numpy() for name in ("t", "x", "y", "p")]
        return (*columns, *sensor)
    if kind != "recordings":
        raise NeurotacError(f"export writes events or recordings tables, got {kind or 'an unknown'} table")
    trials = table.column("trial").to_pylist()
    if trial is None and len(trials) > 1:
        raise NeurotacError(f"the recordings hold {len(trials)} trials: pick one with --trial (e.g. {trials[0]})")
    name = trial or trials[0]
    found = sch.trial_recording(table, name)
    if found is None:
        raise NeurotacError(f"no trial {name!r} in the recordings (trials: {', '.join(trials[:6])})")
    t0, (t, x, y, p), _ = found
    return (t.astype(np.int64) + t0, x, y, p, *sensor)


def export(table: pa.Table, path: str, trial: str | None = None) -> dict:
    """Write `table` (events, or one trial of recordings) as the camera file `path` by its suffix."""
    from neurotac_cli.io.writers import aedat2_bytes
    from neurotac_cli.tables import atomic_file

    fmt = export_format(path)
    t, x, y, p, width, height = events_arrays(table, trial)
    sch.check_events(t, x, y, p, (width, height), sorted_time=False)  # a camera file cannot hold them as they are
    from neurotac_cli.io.hdf5 import LARGEST_US

    if len(t) and max(-int(t.min()), int(t.max())) >= LARGEST_US:  # `import` refuses such a time: the file would not read back
        raise NeurotacError(f"a time of {max(-int(t.min()), int(t.max()))} µs is not one a camera writes (beyond about "
                            "146,000 years); `neurotac import` would refuse the file")
    if fmt == "hdf5":
        with atomic_file(path) as temporary:
            indexed = write_hdf5(temporary, t, x, y, p, width, height)
            size = os.path.getsize(temporary)
        return {"format": fmt, "events": int(len(t)), "bytes": size, "shift_us": 0, "unindexed": not indexed}
    if fmt == "evt3":
        data, shift = evt3_bytes(t, x, y, p, width, height)
    elif fmt == "aedat4":
        data, shift = aedat4_bytes(t, x, y, p, width, height), 0
    else:
        if len(t) and (t.min() < 0 or t.max() >= 1 << 32):
            raise NeurotacError("AEDAT 2.0 holds times from 0 to 71 minutes in µs; these events lie outside (use .raw)")
        data, shift = aedat2_bytes(t, x, y, p, width=width, height=height), 0
    with atomic_file(path) as temporary:
        with open(temporary, "wb") as sink:
            sink.write(data)
    return {"format": fmt, "events": int(len(t)), "bytes": len(data), "shift_us": shift}
