"""Event Stream 2.x (`.es`, the neuromorphic-systems format read by faery, loris and sepia): DVS and
ATIS types.

Header: `Event Stream`, version (major, minor, patch), event type (1 = DVS, 2 = ATIS), width and
height as little-endian uint16. Events are bytes (see kernels.decode_es; of ATIS events only the
change detections are kept, as faery does). The format's origin is the
bottom-left corner, so rows are flipped (row = height - 1 - y), as faery does.
"""

import struct

import numpy as np

from neurotac_cli.errors import FormatError
from neurotac_cli.io.reader import Decoded, read_chunks

HEADER = 12 + 3 + 1 + 4
TYPES = {0: "generic", 1: "DVS", 2: "ATIS", 4: "color"}


def open_es(path: str, head: bytes, sensor) -> Decoded:
    from neurotac_cli.io import kernels

    if len(head) < 16:
        raise FormatError("the Event Stream header is cut short")
    major, minor, patch, event_type = head[12], head[13], head[14], head[15]
    if major != 2:
        raise FormatError(f"Event Stream version {major}.{minor}.{patch} is not supported (2.x is)")
    if event_type not in (1, 2):
        raise FormatError(f"Event Stream events of type {TYPES.get(event_type, event_type)} are not supported (DVS and ATIS are)")
    if len(head) < HEADER:
        raise FormatError("the Event Stream header is cut short")
    width, height = struct.unpack_from("<HH", head, 16)
    if width == 0 or height == 0:
        raise FormatError(f"the Event Stream header declares a {width}x{height} sensor")

    atis = event_type == 2

    def chunks():
        state = kernels.es_state()
        for block in read_chunks(path, HEADER, 1):
            t, x, y, p, outside = kernels.decode_es(np.frombuffer(block, dtype=np.uint8), width, height, atis, state)
            if outside:
                raise FormatError(f"an event lies outside the declared {width}x{height} sensor (damaged file)")
            yield t, x, (height - 1 - y.astype(np.int64)).astype(np.uint16), p

    cut = _cut_bytes(path, width, height, atis) if path is not None else 0
    return Decoded(sensor=(width, height), chunks=chunks, meta={"source": {"es_version": f"{major}.{minor}.{patch}"}}, cut_bytes=cut)


def _cut_bytes(path: str, width: int, height: int, atis: bool) -> int:
    """The bytes of an event the file ends in the middle of (0 for a whole one). Events have no fixed
    size, so only a pass over them tells (a compiled one: about 2 ms a megabyte, as the file's hash)."""
    from neurotac_cli.io import kernels

    state = kernels.es_state()
    for block in read_chunks(path, HEADER, 1):
        kernels.decode_es(np.frombuffer(block, dtype=np.uint8), width, height, atis, state)
    return kernels.es_pending(state)
