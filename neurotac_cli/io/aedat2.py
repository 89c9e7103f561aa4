"""AEDAT 2.0 (jAER): `#` header lines, then big-endian (int32 address, int32 timestamp µs) records.

DAVIS address layout (jAER's DavisChip): bit 31 set = APS sample or IMU word, skipped; bit 10 set =
special event (external input), skipped; otherwise y = (a >> 22) & 0x1FF, x = (a >> 12) & 0x3FF,
p = (a >> 11) & 1 (1 = ON). Timestamps are read unsigned, so they increase over the whole 71 minutes
a 32-bit µs clock holds. jAER's y axis points up, so the image row is H - 1 - y. A truncated
trailing record (a recording cut mid-write) is dropped. DVS128 files have their own layout (see
decode_dvs128).
"""

import os
import re

import numpy as np

from neurotac_cli.errors import FormatError
from neurotac_cli.io.reader import Decoded, check_sensor, cut_bytes, read_chunks, unwrap_32

# AEChip class name (lowercase, a fragment of it) -> (width, height)
CHIPS = [
    ("davis240", (240, 180)),
    ("davis346", (346, 260)),
    ("davis640", (640, 480)),
    ("rgbw640", (640, 480)),
    ("cdavis", (640, 480)),
    ("davis208", (208, 192)),
    ("davis128", (128, 128)),
]
OTHER_DAVIS = (240, 180)  # a DAVIS chip of no known size: the commonest, unless --sensor says otherwise
RECORD = 8
APS_OR_IMU = np.uint32(1 << 31)
SPECIAL = np.uint32(1 << 10)


_CONTROL = bytes(c for c in range(32) if c not in (9, 13))


def header_length(data: bytes) -> int:
    """Bytes of the `#` header: the lines starting with `#`, up to the first that does not.

    A record whose first address byte happens to be `#` (0x23: a DAVIS row 140-143 counted from the
    bottom) is not mistaken for a header line, because header lines are text: a candidate line with a
    control byte in it (other than tab and CR) is data.
    """
    offset = 0
    while offset < len(data) and data[offset : offset + 1] == b"#":
        end = data.find(b"\n", offset)
        line = data[offset : end if end >= 0 else len(data)]
        if line.translate(None, _CONTROL) != line:
            break
        if end < 0:
            return len(data)
        offset = end + 1
        if line.lower().startswith(b"#end of ascii header"):
            break
    return offset


def chip_of(header: bytes) -> str | None:
    match = re.search(rb"AEChip:\s*(\S+)", header)
    return match.group(1).decode("latin-1") if match else None


def sensor_line(header: bytes) -> tuple[int, int] | None:
    """A `# sensor: WxH` header line (written by neurotac's simulator for sizes other than 240x180)."""
    match = re.search(rb"#\s*sensor:\s*(\d+)\s*x\s*(\d+)", header)
    return (int(match.group(1)), int(match.group(2))) if match else None


def sensor_of_chip(chip: str | None) -> tuple[int, int] | None:
    if not chip:
        return None
    name = chip.rsplit(".", 1)[-1].lower()
    for fragment, size in CHIPS:
        if fragment in name:
            return size
    return None


def declared_sensor(header: bytes, chip: str | None, given) -> tuple[int, int] | None:
    """The sensor the header names (a `# sensor:` line, or the chip), else for another DAVIS chip the
    commonest size where --sensor (`given`) does not say."""
    declared = check_sensor(sensor_line(header) or sensor_of_chip(chip))
    if declared is None and given is None and "davis" in (chip or "").rsplit(".", 1)[-1].lower():
        return OTHER_DAVIS
    return declared


def _read_header(path: str, head: bytes) -> bytes:
    if header_length(head) < len(head) or len(head) < (1 << 16):
        return head[: header_length(head)]
    with open(path, "rb") as handle:  # a header longer than the sniffed bytes (long jAER preferences)
        data = handle.read()
    return data[: header_length(data)]


def open_aedat2(path: str, head: bytes, sensor) -> Decoded:
    header = _read_header(path, head)
    if not header.endswith(b"\n") and len(header) == os.path.getsize(path):
        raise FormatError(f"the AEDAT 2.0 header is cut short: the file ends mid-line after {len(header)} bytes "
                          "(is it the whole file?)")
    chip = chip_of(header)
    declared = declared_sensor(header, chip, sensor)  # its height flips the rows, --sensor or not
    offset = len(header)
    dvs128 = is_dvs128(chip) or (chip is None and declared is None and _dvs128_addresses(path, offset))
    height = None if dvs128 else flip_height(chip, declared, sensor)

    def chunks():
        state = {"last": None, "loop": 0}
        for block in read_chunks(path, offset, RECORD):
            yield decode(block, dvs128, height, state)

    camera = chip or (TOLD_DVS128 if dvs128 else None)
    return Decoded(sensor=(128, 128) if dvs128 else declared, chunks=chunks, meta={"source": {"camera": camera}} if camera else {},
                   cut_bytes=cut_bytes(path, offset, RECORD))


TOLD_DVS128 = "DVS128 (told from its addresses)"
ADDRESSES_TO_TELL = 1 << 16  # records looked at; at least 16 are needed


def _dvs128_addresses(path: str, offset: int) -> bool:
    with open(path, "rb") as handle:
        handle.seek(offset)
        return bool(dvs128_records(handle.read(ADDRESSES_TO_TELL * RECORD)))


def dvs128_records(data: bytes) -> bool | None:
    """Whether records of a file that names no chip are DVS128's: none of the first addresses has a
    bit above the 16 that layout uses (a DAVIS address holds x from bit 12 and y from bit 22, so all
    but the events of a 16-pixel corner set a higher bit). None: fewer than 16 whole records."""
    words = np.frombuffer(data[: min(len(data), ADDRESSES_TO_TELL * RECORD) // RECORD * RECORD], dtype=">u4").reshape(-1, 2)
    if len(words) < 16:
        return None
    return not np.any(words[:, 0] >> 16)


def flip_height(chip: str | None, declared, given) -> int:
    """The sensor height jAER's y axis is flipped with: the chip's own, else --sensor's."""
    height = (declared or given or (None, None))[1]
    if height is None:
        raise FormatError(f"jAER chip {chip or 'unnamed'} has an unknown sensor size, needed to flip jAER's y axis "
                          "(give it with --sensor WxH, e.g. --sensor 240x180)")
    return height


def decode(block: bytes, dvs128: bool, height: int | None, state: dict):
    """Whole records -> (t, x, y, p) of the DVS events, rows flipped, the 32-bit timestamps unwrapped
    across blocks (`state`: `reader.unwrap_32`; jAER's own reader unwraps them too)."""
    if dvs128:
        t, x, y, p = decode_dvs128(block)
    else:
        from neurotac_cli.io import kernels

        t, x, y, p, largest = kernels.decode_davis(np.frombuffer(block, dtype=np.uint8), height)
        if largest >= height:
            raise FormatError(f"DVS event row {largest} lies outside the sensor's {height} rows (damaged data, or wrong --sensor)")
    return unwrap_32(t, state), x, y, p


def is_dvs128(chip: str | None) -> bool:
    name = (chip or "").rsplit(".", 1)[-1].lower()
    return name.startswith("dvs128") or name.startswith("tmpdiff128")


def decode_dvs128(block: bytes):
    """DVS128 records, as jAER's DVS128 extractor reads them: address bits 15 (sync) or 31 (special)
    set = skipped; x = 127 - ((a >> 1) & 0x7F) (jAER flips x), jAER y = (a >> 8) & 0x7F (up, so the
    row is 127 - y), and the raw polarity bit is inverted (raw 0 = ON)."""
    words = np.frombuffer(block, dtype=">u4").reshape(-1, 2)
    address = words[:, 0]
    keep = (address & np.uint32(0x80008000)) == 0
    address = address[keep]
    t = words[keep, 1].astype(np.int64)
    x = (127 - ((address >> 1) & 0x7F)).astype(np.uint16)
    row = (127 - ((address >> 8) & 0x7F)).astype(np.uint16)
    p = (1 - (address & 1)).astype(np.uint8)
    return t, x, row, p


def decode_davis_numpy(block: bytes, height: int):
    """The same as kernels.decode_davis, in numpy (kept as the readable statement of the layout): whole 8-byte records -> (t, x, y, p) of the DVS events, y flipped to image rows."""
    words = np.frombuffer(block, dtype=">u4").reshape(-1, 2)
    address = words[:, 0]
    keep = (address & (APS_OR_IMU | SPECIAL)) == 0
    address = address[keep]
    t = words[keep, 1].astype(np.int64)
    y = (address >> 22) & 0x1FF
    if len(y) and int(y.max()) >= height:
        raise FormatError(f"DVS event row {int(y.max())} lies outside the sensor's {height} rows (damaged file, or wrong --sensor)")
    x = ((address >> 12) & 0x3FF).astype(np.uint16)
    p = ((address >> 11) & 1).astype(np.uint8)
    row = (height - 1 - y).astype(np.uint16)
    return t, x, row, p
