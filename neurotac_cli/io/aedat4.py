"""AEDAT 4.0 (iniVation dv): decoded by the `aedat` library (Rust; LZ4/zstd packets, flatbuffers).

The first events stream is read (x, y, polarity with t in µs, usually Unix time). External trigger
events (the `triggers` stream: signal and generator edges and pulses, timestamp resets) go into the
schema metadata `neurotac:triggers` as [{"t": µs, "type": ...}], which `sync --method trigger` uses;
frame and exposure triggers of the APS are left out, as are frames and IMU samples.
"""

import itertools
import os
import re
import struct

import numpy as np

from neurotac_cli.errors import FormatError
from neurotac_cli.io.reader import Decoded

TRIGGER_TYPES = {
    0: "timestamp_reset",
    1: "rising",
    2: "falling",
    3: "pulse",
    4: "generator_rising",
    5: "generator_falling",
}
BATCH_EVENTS = 1 << 20
SINGLE_PASS_BYTES = 64 << 20  # files up to this size are decoded once, larger ones twice


def check_header(path: str):
    """Check the IOHeader flatbuffer's info string before `aedat` sees it: invalid UTF-8 in it makes
    that library abort the whole process (pyo3 cannot build the string), which no `except` can catch."""
    with open(path, "rb") as handle:
        head = handle.read(14 + 4)
        if len(head) < 18 or not head.startswith(b"#!AER-DAT4.0"):
            raise FormatError("the AEDAT 4.0 header is cut short")
        size = struct.unpack_from("<I", head, 14)[0]
        if size > 1 << 24:
            raise FormatError(f"the AEDAT 4.0 header claims {size} bytes (damaged file)")
        buffer = handle.read(size)
    if len(buffer) < size or size < 8:
        raise FormatError("the AEDAT 4.0 header is cut short")
    try:
        table = struct.unpack_from("<I", buffer, 0)[0]
        vtable = table - struct.unpack_from("<i", buffer, table)[0]
        vtable_size = struct.unpack_from("<H", buffer, vtable)[0]
        if vtable_size >= 4 + 3 * 2:
            field = struct.unpack_from("<H", buffer, vtable + 4 + 2 * 2)[0]
            if field:
                start = table + field
                string = start + struct.unpack_from("<I", buffer, start)[0]
                length = struct.unpack_from("<I", buffer, string)[0]
                text = buffer[string + 4 : string + 4 + length]
                if len(text) < length:
                    raise FormatError("the AEDAT 4.0 header's description is cut short")
                text.decode("utf-8")
    except (struct.error, UnicodeDecodeError) as error:
        raise FormatError(f"the AEDAT 4.0 header is damaged ({error})") from None


def _packets(path: str, skip_streams: bool = False, limit: int | None = None):
    """The `aedat` decoder's packets (after its streams, unless `skip_streams`; the first `limit` only,
    where given), with its failures (a Rust panic included) as FormatError."""
    import aedat

    check_header(path)
    try:
        decoder = aedat.Decoder(path)
        streams = decoder.id_to_stream()
        if not skip_streams:
            yield streams
        # a packet cut short follows the first `limit`, which the decoder would refuse: never asked for
        yield from (decoder if limit is None else itertools.islice(decoder, limit))
    except (KeyboardInterrupt, SystemExit, GeneratorExit, FormatError):
        raise
    except BaseException as error:  # pyo3's PanicException derives from BaseException
        text = str(error).strip().splitlines()
        raise FormatError(f"not a valid AEDAT 4.0 file ({text[0][:160] if text else type(error).__name__})") from None


def walk_packets(read, size: int, streams, offset: int = 0) -> tuple[int, int, bool]:
    """(packets, end, finished): the packets lying whole from `offset` in `size` bytes that `read(offset,
    n)` returns, where the last of them ends, and whether the data is over there (a packet of no
    declared stream is the index table a finished file ends with). One rule for a file and a stream."""
    count = 0
    while offset + 8 <= size:
        stream, length = struct.unpack("<iI", read(offset, 8))
        if stream not in streams:
            return count, offset, True
        if offset + 8 + length > size:
            break
        offset, count = offset + 8 + length, count + 1
    return count, offset, False


def whole_packets(path: str, streams) -> tuple[int, int]:
    """(packets, cut bytes): how many packets lie whole in `path`, and the bytes after them of a packet
    cut short (0 where none). Where the packets end at one of no declared stream that is not the
    index table the header points to (a damaged packet, or a second file joined on), the file is
    refused: what follows would be lost without a word."""
    with open(path, "rb") as handle:
        size = os.fstat(handle.fileno()).st_size

        def read(offset, n):
            handle.seek(offset)
            return handle.read(n)

        header_end = 18 + struct.unpack("<I", read(14, 4))[0]
        count, end, finished = walk_packets(read, size, streams, header_end)
        if finished:
            check_table(end, table_position(read(0, header_end)), count, size - end)
    return count, 0 if finished else size - end


def check_table(end: int, table: int | None, count: int, rest: int | None = None) -> None:
    """Refuse packets that end, at byte `end`, at one of no declared stream that is not the index
    table: a damaged packet, or a second file joined on, whose data would be lost without a word.
    `table`: the position the header states (-1 or None: none). A header that states none (its writer
    stopped before updating it) may still end in a table, a few tens of bytes per packet, far fewer
    than a second recording: `rest`, the bytes from `end` to the file's end, tells (None in a stream,
    whose end is not known: only a stated table is checked there)."""
    stated = table is not None and table > 0
    if (stated and table != end) or (not stated and rest is not None and rest > TABLE_BYTES_PER_PACKET * (count + 1)):
        where = f", where the index table is not (it is at byte {table:,})" if stated else ""
        raise FormatError(f"the bytes from byte {end:,} are no packet of a declared stream{where}: a damaged file, or two "
                          f"joined? (the {count:,} packets before them are whole)")


TABLE_BYTES_PER_PACKET = 256  # an index table entry is ~35 bytes (1,408 bytes for 40 packets in a DAVIS346 file)


def table_offset(header: bytes) -> int | None:
    """Where in `header` (the file's first bytes, through its IOHeader) the index table's position
    is stored; None where the IOHeader does not hold it."""
    try:
        table = struct.unpack_from("<I", header, 18)[0] + 18
        vtable = table - struct.unpack_from("<i", header, table)[0]
        if struct.unpack_from("<H", header, vtable)[0] >= 4 + 2 * 2:
            offset = struct.unpack_from("<H", header, vtable + 4 + 2)[0]
            return table + offset if offset else None
    except struct.error:
        raise FormatError("the AEDAT 4.0 header is damaged") from None
    return None


def table_position(header: bytes) -> int | None:
    """The index table's byte position the header states (-1: none written), or None."""
    offset = table_offset(header)
    return None if offset is None else struct.unpack_from("<q", header, offset)[0]


def open_aedat4(path: str, head: bytes, sensor) -> Decoded:
    packets = _packets(path)
    streams = next(packets)
    events_id, declared, others = events_stream(streams, head, "file")
    has_triggers = any(s.get("type") == "triggers" for s in streams.values())
    # A recording stopped mid-write (mid-packet, or between packets before its index table) is read as
    # far as its last whole packet: the decoder, asked for one more, fails on the missing bytes.
    limit, cut = whole_packets(path, streams)
    if not has_triggers:
        packets.close()
        return Decoded(sensor=declared, chunks=lambda: _event_chunks(_packets(path, limit=limit), events_id),
                       meta={"source": others} if others else {}, cut_bytes=cut)
    # The triggers go into the schema, which is written before the first batch: find them first.
    # A small file is decoded once and its events kept; a large one is decoded twice, so memory
    # stays flat.
    small = os.path.getsize(path) <= SINGLE_PASS_BYTES
    triggers, kept = [], []
    for packet in itertools.islice(packets, limit):
        if "triggers" in packet:
            found = packet["triggers"]
            keep = np.isin(found["source"], list(TRIGGER_TYPES))
            triggers += [{"t": int(t), "type": TRIGGER_TYPES[int(s)]} for t, s in zip(found["t"][keep], found["source"][keep])]
        elif small and packet.get("stream_id") == events_id and "events" in packet:
            kept.append(packet)
    if small:
        chunks = lambda: _event_chunks(iter(kept), events_id)  # noqa: E731
    else:
        chunks = lambda: _event_chunks(_packets(path, skip_streams=True, limit=limit), events_id)  # noqa: E731
    return Decoded(sensor=declared, chunks=chunks, meta={"triggers": triggers, **({"source": others} if others else {})}, cut_bytes=cut)


def events_stream(streams: dict, header: bytes, what: str) -> tuple:
    """(id of the events stream read, the sensor it declares or None, source metadata naming the
    events streams not read) of a file's or a stream's (`what`) streams. A second events stream
    (another camera, or the same one undistorted) is not read: named in the source."""
    event_ids = sorted(i for i, s in streams.items() if s.get("type") == "events")
    if not event_ids:
        raise FormatError(f"the AEDAT 4.0 {what} has no events stream")
    found = streams[event_ids[0]]
    declared = (int(found["width"]), int(found["height"])) if "width" in found else None
    given = _output_names(header)
    names = [given.get(i, f"#{i}") for i in event_ids]
    others = {"other_event_streams": names[1:], "note": f"events stream(s) {', '.join(names[1:])} not read (the first, "
              f"{names[0]}, is)"} if len(names) > 1 else {}
    return event_ids[0], declared, others


def _output_names(head: bytes) -> dict:
    """{stream id: the name its writer gave it} from the header's `outInfo` nodes (as far as `head` holds them)."""
    found = re.findall(rb'<node name="(\d+)" path="/[^"]*outInfo/\d+/">\s*(?:<attr[^>]*>[^<]*</attr>\s*)*?'
                       rb'<attr key="originalOutputName" type="string">([^<]*)</attr>', head)
    return {int(i): name.decode("utf-8", "replace") for i, name in found}


def _event_chunks(packets, events_id):
    pending, count = [], 0
    for packet in packets:
        if packet.get("stream_id") != events_id or "events" not in packet:
            continue
        events = packet["events"]
        pending.append(events)
        count += len(events)
        if count >= BATCH_EVENTS:
            yield _columns(pending)
            pending, count = [], 0
    if pending:
        yield _columns(pending)


def _columns(pending):
    """Packets of structured events -> contiguous t, x, y, p columns: one copy per field."""
    total = sum(len(events) for events in pending)
    t = np.empty(total, np.int64)
    x = np.empty(total, np.uint16)
    y = np.empty(total, np.uint16)
    p = np.empty(total, np.uint8)
    start = 0
    for events in pending:
        end = start + len(events)
        t[start:end] = events["t"]
        x[start:end] = events["x"]
        y[start:end] = events["y"]
        p[start:end] = events["on"]
        start = end
    return t, x, y, p
