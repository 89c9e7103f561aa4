"""Camera files out: AEDAT 2.0 as jAER writes it for a DAVIS240C.

After `#` header lines (the first `#!AER-DAT2.0`), each event is a big-endian uint32 address and a
big-endian uint32 timestamp in µs. DAVIS address: y << 22 | x << 12 | p << 11, with jAER's y axis
pointing up, so the row (origin top-left) is written as y = height - 1 - row.
"""

import numpy as np

from neurotac_cli.errors import NeurotacError

HEADER = (
    "#!AER-DAT2.0\r\n"
    "# This is a raw AE data file - do not edit\r\n"
    "# Data format is int32 address, int32 timestamp (8 bytes total), repeated for each event\r\n"
    "# Timestamps tick is 1 us\r\n"
    "# created by neurotac\r\n"
)
DAVIS240C = "# AEChip: eu.seebetter.ini.chips.davis.DAVIS240C\r\n"
AEDAT2_LAST_US = 0xFFFFFFFF  # the last instant of AEDAT 2.0's 32-bit µs clock: 71.6 min from its zero


def aedat2_bytes(t, x, y, p, width: int = 240, height: int = 180) -> bytes:
    """The bytes of an AEDAT 2.0 file (header + events) for events with (t µs, x, row, p: 1 = ON)."""
    t = np.asarray(t, dtype=np.int64)
    x = np.asarray(x, dtype=np.int64)
    y = np.asarray(y, dtype=np.int64)
    p = np.asarray(p, dtype=np.int64)
    if not (t.shape == x.shape == y.shape == p.shape):
        raise ValueError("t, x, y and p must have the same length")
    if t.size:
        if t.min() < 0 or t.max() > AEDAT2_LAST_US:
            raise NeurotacError("AEDAT 2.0 timestamps are 32-bit µs (0 .. 71 min); shift the events' times into that range")
        if x.min() < 0 or x.max() >= width or y.min() < 0 or y.max() >= height:
            raise NeurotacError(f"events outside the {width}x{height} sensor cannot be written to AEDAT 2.0")
        if np.any(np.diff(t) < 0):
            raise NeurotacError("AEDAT 2.0 events must be in time order; sort them first")
    if width > 1024 or height > 512:
        raise NeurotacError("AEDAT 2.0 DAVIS addresses hold at most 1024x512 pixels")
    address = ((height - 1 - y) << 22) | (x << 12) | ((p & 1) << 11)
    words = np.empty((t.size, 2), dtype=">u4")
    words[:, 0] = address
    words[:, 1] = t
    header = HEADER + (DAVIS240C if (width, height) == (240, 180) else f"# sensor: {width}x{height}\r\n")
    return header.encode("ascii") + words.tobytes()


def write_aedat2(path, t, x, y, p, width: int = 240, height: int = 180) -> None:
    """Write events (t µs, x, row from the top, p: 1 = ON) as AEDAT 2.0, atomically (temp file + rename)."""
    from neurotac_cli.tables import atomic_file

    data = aedat2_bytes(t, x, y, p, width, height)
    with atomic_file(path) as temporary, open(temporary, "wb") as sink:
        sink.write(data)
