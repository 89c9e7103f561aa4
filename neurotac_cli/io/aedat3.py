"""AEDAT 3.1 (cAER and libcaer; IBM's DVS Gesture recordings): `#` header lines up to `#!END-HEADER`,
then packets. A packet is a 28-byte little-endian header (int16 type, int16 source, int32 event size,
int32 timestamp offset, int32 timestamp overflow, int32 capacity, int32 number, int32 valid) and
capacity x size bytes of events.

Polarity events (type 1, 8 bytes): uint32 data (bit 0 valid, bit 1 polarity with 1 = ON, bits 2-16 y,
bits 17-31 x; libcaer's origin is the top-left, as ours) and int32 timestamp; the full timestamp is
overflow << 31 | timestamp, in µs. An event whose valid bit is clear was removed by a filter before
the file was written and is skipped. Special events (type 0: bit 0 valid, bits 1-7 type, bits 8-31
data) carry the external triggers and timestamp resets, kept in `neurotac:triggers` as AEDAT 4.0's
are. Frames, IMU samples and the polarity events of a second source (another camera in the same
file) are skipped; the last is counted in `neurotac:source`.
"""

import os
import re
import struct

import numpy as np

from neurotac_cli.errors import FormatError
from neurotac_cli.io.reader import CHUNK_BYTES, Decoded

HEADER_END = b"#!END-HEADER"
PACKET = 28
SPECIAL, POLARITY = 0, 1
EVENT_BYTES = 8  # polarity and special events
# libcaer's special event types that are external triggers or resets: (the name AEDAT 4.0's use, the input's id)
TRIGGER_TYPES = {1: ("timestamp_reset", None), 2: ("rising", 0), 3: ("falling", 0), 4: ("pulse", 0), 6: ("rising", 1),
                 7: ("falling", 1), 8: ("pulse", 1), 9: ("rising", 2), 10: ("falling", 2), 11: ("pulse", 2),
                 12: ("generator_rising", None), 13: ("generator_falling", None)}
CHIPS = [("dvs128", (128, 128)), ("dvxplorer_lite", (320, 240)), ("dvxplorer", (640, 480))]


def header_length(data) -> int | None:
    """Bytes of the header, its `#!END-HEADER` line included; None while that line has not arrived."""
    at = data.find(HEADER_END)
    end = data.find(b"\n", at) if at >= 0 else -1
    return None if end < 0 else end + 1


def sensor_of_header(header: bytes) -> tuple[tuple[int, int] | None, str | None, int | None]:
    """(sensor size, camera name, source id) of the first source the header names (`#Source N: CHIP`):
    a `dvsSizeX`/`dvsSizeY` attribute of its configuration, else the size of its chip. Its events are
    the ones read."""
    from neurotac_cli.io import aedat2

    source = re.search(rb"#Source (\d+):\s*([^\r\n]+)", header)
    camera = source.group(2).strip().decode("latin-1") if source else None
    chosen = int(source.group(1)) if source else None
    sizes = [re.search(rb'key="dvsSize' + axis + rb'"[^>]*>\s*(\d+)', header) for axis in (b"X", b"Y")]
    if all(sizes):
        return (int(sizes[0].group(1)), int(sizes[1].group(1))), camera, chosen
    name = (camera or "").lower().replace(" ", "_")
    for fragment, size in CHIPS:
        if fragment in name:
            return size, camera, chosen
    return aedat2.sensor_of_chip(camera) or (aedat2.OTHER_DAVIS if "davis" in name else None), camera, chosen


def packet_header(data: bytes, offset: int = 0) -> tuple[int, int, int, int, int, int]:
    """(type, source, event size, timestamp overflow, bytes of events, valid events) of the packet at `offset`."""
    kind, source, size, stamp_at, overflow, capacity, number, valid = struct.unpack_from("<hhiiiiii", data, offset)
    if size <= 0 or capacity < 0 or not 0 <= valid <= number <= capacity or overflow < 0 or size * capacity > 1 << 31:
        raise FormatError(f"an AEDAT 3.1 packet header is damaged (type {kind}, event size {size}, capacity {capacity}, "
                          f"events {number}, valid {valid}, overflow {overflow})")
    if kind in (SPECIAL, POLARITY) and stamp_at != 4:
        raise FormatError(f"an AEDAT 3.1 packet puts its events' timestamps at byte {stamp_at} (the format's are at 4; damaged file)")
    if kind in (SPECIAL, POLARITY) and size != EVENT_BYTES:
        raise FormatError(f"an AEDAT 3.1 {'special' if kind == SPECIAL else 'polarity'} packet has {size}-byte events "
                          f"(the format's are {EVENT_BYTES}; damaged file)")
    return kind, source, size, overflow, size * capacity, valid


def whole_packets(data, length: int) -> int:
    """Bytes of the leading whole packets of `data` (a bytes-like of `length` bytes)."""
    offset = 0
    while offset + PACKET <= length:
        end = offset + PACKET + packet_header(data, offset)[4]
        if end > length:
            break
        offset = end
    return offset


class Packets:
    """Decodes whole packets: the polarity events of one source (the header's first, else the first
    that has any), and the triggers."""

    def __init__(self, source: int | None = None):
        self.source = source  # the source whose polarity events are kept
        self.triggers = []

    def decode(self, block: bytes):
        """(t, x, y, p) of the polarity events in `block`, whole packets."""
        parts, offset = [], 0
        while offset < len(block):
            kind, source, _, overflow, length, _ = packet_header(block, offset)
            start, offset = offset + PACKET, offset + PACKET + length
            if kind not in (SPECIAL, POLARITY):
                continue
            events = np.frombuffer(block, dtype="<u4", count=length // 4, offset=start).reshape(-1, 2)
            if kind == SPECIAL:
                self._special(events, overflow)
            elif kind == POLARITY:
                if self.source is None:
                    self.source = source
                if source == self.source:
                    parts.append(_polarity(events, overflow))
        if not parts:
            return _polarity(np.zeros((0, 2), np.uint32), 0)
        return tuple(np.concatenate(column) for column in zip(*parts))

    def _special(self, events, overflow: int):
        data = events[:, 0]
        kinds = (data >> 1) & 0x7F
        keep = ((data & 1) == 1) & np.isin(kinds, list(TRIGGER_TYPES))
        stamps = _stamps(events[keep, 1], overflow)
        for t, k in zip(stamps, kinds[keep]):
            name, input_id = TRIGGER_TYPES[int(k)]
            self.triggers.append({"t": int(t), "type": name} if input_id is None else {"t": int(t), "type": name, "id": input_id})


def _stamps(low: np.ndarray, overflow: int) -> np.ndarray:
    return (np.int64(overflow) << np.int64(31)) | (low.astype(np.int64) & 0x7FFFFFFF)


def _polarity(events: np.ndarray, overflow: int):
    data = events[:, 0]
    valid = (data & 1) == 1
    data = data[valid]
    return (_stamps(events[valid, 1], overflow), ((data >> 17) & 0x7FFF).astype(np.uint16),
            ((data >> 2) & 0x7FFF).astype(np.uint16), ((data >> 1) & 1).astype(np.uint8))


def open_aedat3(path: str, head: bytes, sensor) -> Decoded:
    # read, not mapped: a mapped file that another program truncates while it is read kills the
    # process with SIGBUS, without a word; packets are walked by their headers, and only the chunk
    # being decoded is read
    with open(path, "rb") as handle:
        header = _header(handle, head)
        length = header_length(header)
        declared, camera, source = sensor_of_header(header[:length])
        size_of = os.fstat(handle.fileno()).st_size - length
        # One walk over the packet headers: where each whole packet ends (a last one cut short is
        # left), the polarity events of each source, and the triggers, which go into the schema
        # before the first batch (special packets are small); the events are decoded later in chunks.
        packets, ends, valid_of = Packets(), [], {}
        whole = 0
        handle.seek(length)
        while whole + PACKET <= size_of:
            at = handle.read(PACKET)
            if len(at) < PACKET:
                break
            kind, from_source, _, _, size, valid = packet_header(at)
            if whole + PACKET + size > size_of:
                break
            if kind == SPECIAL:
                packets.decode(at + _exactly(handle, size))
            else:
                handle.seek(size, os.SEEK_CUR)
                if kind == POLARITY:
                    valid_of[from_source] = valid_of.get(from_source, 0) + valid
            whole += PACKET + size
            ends.append(whole)
    if valid_of and source not in valid_of:  # the header names no source of these events: its camera is not theirs
        source, camera, declared = next(iter(valid_of)), None, None
    others = sum(valid_of.values()) - valid_of.get(source, 0)

    def chunks():
        reader, begin = Packets(source), 0
        with open(path, "rb") as events:
            events.seek(length)
            for end in ends:
                if end - begin >= CHUNK_BYTES or end == whole:
                    yield reader.decode(_exactly(events, end - begin))
                    begin = end

    meta = {"source": {"camera": camera} if camera else {}, "triggers": packets.triggers}
    if others:
        meta["source"]["events_of_other_sources"] = others
    return Decoded(sensor=declared, chunks=chunks, meta=meta, cut_bytes=size_of - whole)


def _header(handle, head: bytes) -> bytes:
    """The file's bytes up to its `#!END-HEADER` line, read on past `head` where the header is longer."""
    data = bytearray(head)
    handle.seek(len(data))
    while header_length(data) is None:
        more = handle.read(1 << 16)
        if not more:
            raise FormatError("the AEDAT 3.1 header has no `#!END-HEADER` line (is it the whole file?)")
        data += more
    return bytes(data)


def _exactly(handle, size: int) -> bytes:
    """`size` bytes from the handle: fewer means the file shrank while it was read."""
    data = handle.read(size)
    if len(data) < size:
        raise FormatError("the file was cut short while it was read (another program truncated it)")
    return data
