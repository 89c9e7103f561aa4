"""What every camera-format reader shares: the `Decoded` it returns and how it reads a file in chunks.

A format module exposes `open_<format>(path, head, sensor) -> Decoded`; `io.readers.OPENERS` lists
them by format name and `io.camera` turns their chunks into `events` batches.
"""

import os
import stat
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

from neurotac_cli.errors import FormatError, InputError
from neurotac_cli.units import MAX_SIDE

CHUNK_BYTES = 8 << 20  # bytes of camera data decoded at a time: memory does not grow with the file


@dataclass
class Decoded:
    """What a format module found: the declared sensor, a chunk source, and extra metadata."""

    sensor: tuple[int, int] | None
    chunks: Callable[[], Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]]
    meta: dict = field(default_factory=dict)
    cut_bytes: int = 0  # bytes after the last whole record (a file cut mid-record): not decoded


def unwrap_32(t: np.ndarray, state: dict) -> np.ndarray:
    """32-bit microsecond timestamps (they wrap after 71.6 minutes) as int64 times that go on rising:
    a fall by more than half the range is a wrap, a smaller one the camera's own order, kept.
    `state` ({"last": None, "loop": 0}) carries the wraps from one block to the next."""
    t = t.astype(np.int64)
    if not len(t):
        return t
    previous = np.concatenate(([state["last"] if state["last"] is not None else t[0]], t[:-1]))
    loops = np.cumsum(previous - t > (1 << 31)) + state["loop"]
    state["last"], state["loop"] = int(t[-1]), int(loops[-1])
    return t + (loops << 32)


def refuse_device(path: str, what: str) -> None:
    """Refuse a device that gives bytes (/dev/zero, a serial port) or waits for them (a terminal) as
    a file read whole into memory: it never ends, and the read would take all memory or wait for
    ever. An empty one (/dev/null) is left to the reader's own message for an empty file; a pipe or
    FIFO ends when its writer does. The byte is asked for without waiting."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return
    if not (stat.S_ISCHR(mode) or stat.S_ISBLK(mode)):
        return
    try:
        handle = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    except OSError:
        return
    try:
        if not os.read(handle, 1):
            return
    except BlockingIOError:
        pass  # it has nothing yet and would wait
    except OSError:
        return
    finally:
        os.close(handle)
    raise InputError(f"{path} is a device, not {what} (read whole, it would never end); save it to a file and give that")


def check_sensor(sensor: tuple[int, int] | None) -> tuple[int, int] | None:
    """The sensor a file's header declares, refused where no event could lie on it or its sides pass
    the 16-bit coordinates (a damaged header: at 0x0 every event is outside, 70000 rows wrap a flip)."""
    if sensor is not None and not (1 <= sensor[0] <= MAX_SIDE and 1 <= sensor[1] <= MAX_SIDE):
        raise FormatError(f"the file declares a {sensor[0]}x{sensor[1]} sensor, which cannot be (sides of 1 to {MAX_SIDE} "
                          "pixels); the file is damaged, or give the right size with --sensor WxH")
    return sensor


def cut_bytes(path: str, offset: int, record: int) -> int:
    """The bytes of `path` after its last whole `record`-byte record from `offset`, which `read_chunks` drops."""
    return max(0, os.path.getsize(path) - offset) % record


def read_chunks(path: str, offset: int, record: int) -> Iterator[bytes]:
    """The bytes of `path` from `offset`, in chunks of whole `record`-byte records (a cut last record is dropped)."""
    size = max(record, (CHUNK_BYTES // record) * record)
    with open(path, "rb") as handle:
        remaining = os.fstat(handle.fileno()).st_size - offset
        handle.seek(offset)
        rest = b""
        while remaining > 0:
            # never ask for more than is left: a read of n bytes allocates n bytes first
            block = handle.read(min(size, remaining))
            if not block:
                return
            remaining -= len(block)
            data = rest + block if rest else block
            usable = len(data) - len(data) % record
            rest = data[usable:]
            if usable:
                yield data if usable == len(data) else data[:usable]
