"""Prophesee files: EVT 2.0 and EVT 3.0 `.raw` words, and `.dat` records, decoded with numpy.

The word streams are decoded a chunk at a time by the compiled kernels of `io/kernels.py`, with the
decoder state (time high, time low, row, vector base) carried across chunks.

Times follow Prophesee's own decoder (OpenEB): EVT 3.0 time = time-high base + the last time low,
where a TIME_HIGH resets the low part; a TIME_LOW that steps back without a new TIME_HIGH is kept
as written (time is then not monotonic). A TIME_HIGH that falls back by nearly its full range is a
wrap and adds 2^24 µs (EVT 3.0) or 2^34 µs (EVT 2.0). Events before the first TIME_HIGH have no time
base and are skipped, as OpenEB does.
"""

import os
import re

import numpy as np

from neurotac_cli.errors import FormatError
from neurotac_cli.io.reader import Decoded, cut_bytes, read_chunks

# plugin / sensor names in Prophesee headers -> (width, height)
SENSORS = [
    ("gen41", (1280, 720)),
    ("imx636", (1280, 720)),
    ("imx646", (1280, 720)),
    ("imx8", (1280, 720)),
    ("genx320", (320, 320)),
    ("gen31", (640, 480)),
    ("gen3", (640, 480)),
    ("gen4", (1280, 720)),
]


def header_of(path: str, head: bytes) -> tuple[int, dict]:
    """Length in bytes of the `%` header, and its `key value` lines (keys lowercased)."""
    data = head
    offset, fields = 0, {}
    while offset < len(data) and data[offset : offset + 1] == b"%":
        end = data.find(b"\n", offset)
        if end < 0:
            with open(path, "rb") as handle:
                data = handle.read()
            end = data.find(b"\n", offset)
            if end < 0:
                return len(data), fields
        text = data[offset + 1 : end].decode("latin-1").strip()
        key, _, value = text.partition(" ")
        fields.setdefault(key.lower(), value.strip())
        offset = end + 1
        if text.lower() == "end":
            break
    return offset, fields


def sensor_of_header(fields: dict) -> tuple[int, int] | None:
    geometry = fields.get("geometry", "")
    match = re.match(r"(\d+)\s*x\s*(\d+)", geometry)
    if match:
        return int(match.group(1)), int(match.group(2))
    if "width" in fields and "height" in fields:
        try:
            return int(fields["width"]), int(fields["height"])
        except ValueError:
            pass
    width = re.search(r"width=(\d+)", fields.get("format", ""))
    height = re.search(r"height=(\d+)", fields.get("format", ""))
    if width and height:
        return int(width.group(1)), int(height.group(1))
    text = (fields.get("plugin_name", "") + " " + fields.get("sensor_generation", "")).lower()
    for fragment, size in SENSORS:
        if fragment in text:
            return size
    return None


def _meta(fields: dict) -> dict:
    keep = {k: fields[k] for k in ("plugin_name", "serial_number", "date") if k in fields}
    return {"source": {"camera": keep.get("plugin_name")}} if keep.get("plugin_name") else {}


# ---------------------------------------------------------------- EVT 2.0 and 3.0


def open_evt2(path: str, head: bytes, sensor) -> Decoded:
    return _open_words(path, head, word_bytes=4)


def open_evt3(path: str, head: bytes, sensor) -> Decoded:
    return _open_words(path, head, word_bytes=2)


def _open_words(path: str, head: bytes, word_bytes: int) -> Decoded:
    from neurotac_cli.io import kernels, reader

    offset, fields = header_of(path, head)
    decode, fresh, dtype = (
        (kernels.decode_evt2, kernels.evt2_state, "<u4") if word_bytes == 4 else (kernels.decode_evt3, kernels.evt3_state, "<u2")
    )
    if os.path.getsize(path) - offset <= reader.CHUNK_BYTES:
        # one chunk: read it once, look for triggers in memory, decode it when the batches are asked for
        blocks = list(read_chunks(path, offset, word_bytes))
        triggers = _triggers(blocks, word_bytes)

        def chunks():
            state = fresh()
            for block in blocks:
                yield decode(np.frombuffer(block, dtype=dtype), state)

    else:
        triggers = _triggers(read_chunks(path, offset, word_bytes), word_bytes)

        def chunks():
            state = fresh()
            for block in read_chunks(path, offset, word_bytes):
                yield decode(np.frombuffer(block, dtype=dtype), state)

    meta = _meta(fields)
    if triggers is not None:
        meta["triggers"] = triggers
    return Decoded(sensor=sensor_of_header(fields), chunks=chunks, meta=meta, cut_bytes=cut_bytes(path, offset, word_bytes))


def _triggers(blocks, word_bytes: int) -> list | None:
    """External trigger events ([{"t", "type": rising|falling, "id"}]) for `neurotac:triggers`, or
    None when the file has none. Blocks already in memory get a quick compiled look for EXT_TRIGGER
    words first; otherwise (a file of several chunks) the trigger kernel reads them, timing words only."""
    from neurotac_cli.io import kernels

    dtype, shift = ("<u4", 28) if word_bytes == 4 else ("<u2", 12)
    if isinstance(blocks, list) and not any(kernels.has_kind(np.frombuffer(b, dtype=dtype), shift, 0xA) for b in blocks):
        return None
    find, state = (kernels.evt2_triggers, kernels.evt2_state()) if word_bytes == 4 else (kernels.evt3_triggers, kernels.evt3_state())
    triggers = []
    for block in blocks:
        t, value, channel = find(np.frombuffer(block, dtype=dtype), state)
        triggers += [{"t": int(a), "type": "rising" if b else "falling", "id": int(c)} for a, b, c in zip(t, value, channel)]
    return triggers or None


# ---------------------------------------------------------------- DAT

def open_dat(path: str, head: bytes, sensor) -> Decoded:
    offset, fields = header_of(path, head)
    with open(path, "rb") as handle:
        handle.seek(offset)
        kind_size = handle.read(2)
    if len(kind_size) < 2:  # every DAT file has them, events or none
        raise FormatError(f"the DAT header is cut short: the file ends after {offset + len(kind_size)} bytes, before "
                          "the event type and size that follow the header (is it the whole file?)")
    check_dat_kind(kind_size)

    def chunks():
        state = {"last": None, "loop": 0}
        for block in read_chunks(path, offset + 2, 8):
            yield decode_dat(block, state)

    return Decoded(sensor=sensor_of_header(fields), chunks=chunks, meta=_meta(fields), cut_bytes=cut_bytes(path, offset + 2, 8))


def check_dat_kind(kind_size: bytes):
    """The two bytes after a DAT header: event type and size; only 8-byte CD events are read."""
    event_type, event_size = kind_size[0], kind_size[1]
    if event_size != 8:
        raise FormatError(f"DAT events of {event_size} bytes are not supported (CD events are 8 bytes)")
    if event_type not in (0x00, 0x0C):
        raise FormatError(f"DAT event type 0x{event_type:02x} is not a CD event type (0x00 or 0x0c)")


def decode_dat(block: bytes, state: dict):
    """Whole 8-byte DAT records -> (t, x, y, p); `state` ({"last": None, "loop": 0}) carries the
    32-bit timestamp wraps from block to block."""
    records = np.frombuffer(block, dtype="<u4").reshape(-1, 2)
    t = records[:, 0].astype(np.int64)
    # 32-bit timestamps wrap after 71 minutes: a fall by more than half the range is a wrap
    previous = np.concatenate(([state["last"] if state["last"] is not None else t[0]], t[:-1])) if len(t) else t
    loops = np.cumsum(previous - t > (1 << 31)) + state["loop"]
    if len(t):
        state["last"], state["loop"] = int(t[-1]), int(loops[-1])
    data = records[:, 1]
    return (
        t + (loops << 32),
        (data & 0x3FFF).astype(np.uint16),
        ((data >> 14) & 0x3FFF).astype(np.uint16),
        ((data >> 28) & 0x1).astype(np.uint8),
    )
