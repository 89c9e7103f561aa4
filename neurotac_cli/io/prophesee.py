"""Prophesee files: EVT 2.0, 2.1 and 3.0 `.raw` words (compiled kernels), and `.dat` records (numpy).

The word streams are decoded a chunk at a time by the compiled kernels of `io/kernels.py`, the decoder
state (time high, time low, row, vector base) carried across chunks. The EVT 2.1 word order is told here,
from the header or the first words.

Times follow Prophesee's own decoder (OpenEB): EVT 3.0 time = time-high base + the last time low,
where a TIME_HIGH resets the low part; a TIME_LOW that steps back without a new TIME_HIGH is kept
as written (time is then not monotonic). A TIME_HIGH that falls back by nearly its full range is a
wrap and adds 2^24 µs (EVT 3.0) or 2^34 µs (EVT 2.0 and 2.1). Events before the first TIME_HIGH have no time
base and are skipped, as OpenEB does.
"""

import os
import re

import numpy as np

from neurotac_cli.errors import FormatError
from neurotac_cli.io.reader import Decoded, cut_bytes, read_chunks, unwrap_32

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
            if end < 0:  # read as a header without events, it was an empty table and exit 0
                raise FormatError(f"the Prophesee header is cut short: the file ends mid-line after {len(data)} bytes "
                                  "(is it the whole file?)")
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


def time_origin(fields: dict) -> int:
    """µs to add to every time: faery writes `% t0 N` into the Prophesee files it converts (their times
    counted from N) and adds N back when it reads them; OpenEB's files have no such line (0)."""
    match = re.match(r"\s*(\d+)\s*$", fields.get("t0", ""))
    return int(match.group(1)) if match else 0


def shifted(decoded: tuple, t0: int) -> tuple:
    """(t, x, y, p) with `t0` µs added to t (`time_origin`)."""
    t, *rest = decoded
    return (t + t0, *rest) if t0 else decoded


def _meta(fields: dict) -> dict:
    keep = {k: fields[k] for k in ("plugin_name", "serial_number", "date") if k in fields}
    return {"source": {"camera": keep.get("plugin_name")}} if keep.get("plugin_name") else {}


# ---------------------------------------------------------------- EVT 2.0, 2.1 and 3.0


def open_evt2(path: str, head: bytes, sensor) -> Decoded:
    return _open_words(path, head, word_bytes=4)


def open_evt3(path: str, head: bytes, sensor) -> Decoded:
    return _open_words(path, head, word_bytes=2)


def open_evt21(path: str, head: bytes, sensor) -> Decoded:
    """EVT 2.1: 64-bit words, CD events in vectors of 32 pixels (a base x aligned on 32 and a mask).

    Each word is two little-endian 32-bit halves: the event's fields (type in the top 4 bits, a 6-bit
    time low, x, y) and the 32-bit mask. Prophesee's `% format EVT21` header says in which order
    (`endianness=legacy`, IMX636's: fields first; otherwise mask first, as OpenEB reads them); an older
    file with no `format` line is told by which order gives only EVT 2.1 word types, TIME_HIGH words
    whose other half is empty, and time-high values that rise (or wrap)."""
    return _open_words(path, head, word_bytes=8)


def word_kernels(word_bytes: int, legacy: bool | None = None) -> tuple:
    """(decode, find triggers, fresh state, dtype) of the compiled kernels for Prophesee words of
    `word_bytes` (2: EVT 3.0, 4: EVT 2.0, 8: EVT 2.1, whose word order `legacy` travels in its state)."""
    from neurotac_cli.io import kernels

    if word_bytes == 8:
        return kernels.decode_evt21, kernels.evt21_triggers, lambda: kernels.evt21_state(bool(legacy)), "<u8"
    if word_bytes == 4:
        return kernels.decode_evt2, kernels.evt2_triggers, kernels.evt2_state, "<u4"
    return kernels.decode_evt3, kernels.evt3_triggers, kernels.evt3_state, "<u2"


def _open_words(path: str, head: bytes, word_bytes: int) -> Decoded:
    from neurotac_cli.io import reader

    offset, fields = header_of(path, head)
    legacy = _evt21_order(path, offset, fields) if word_bytes == 8 else None
    decode, find, fresh, dtype = word_kernels(word_bytes, legacy)
    # one chunk: read it once, look for triggers in memory, decode it when the batches are asked for;
    # a longer file is read twice (its triggers go into the metadata first)
    held = list(read_chunks(path, offset, word_bytes)) if os.path.getsize(path) - offset <= reader.CHUNK_BYTES else None

    def blocks():
        return held if held is not None else read_chunks(path, offset, word_bytes)

    t0 = time_origin(fields)

    def chunks():
        state = fresh()
        for block in blocks():
            yield shifted(decode(np.frombuffer(block, dtype=dtype), state), t0)

    triggers = _triggers(blocks(), dtype, find, fresh())
    for trigger in triggers or ():
        trigger["t"] += t0
    meta = _meta(fields)
    if legacy is not None:
        note_evt21_order(meta, legacy)
    if triggers is not None:
        meta["triggers"] = triggers
    return Decoded(sensor=sensor_of_header(fields), chunks=chunks, meta=meta, cut_bytes=cut_bytes(path, offset, word_bytes))


def _triggers(blocks, dtype: str, find, state: np.ndarray) -> list | None:
    """External trigger events ([{"t", "type": rising|falling, "id"}]) for `neurotac:triggers`, or
    None when the file has none. Blocks already in memory get a quick compiled look for EXT_TRIGGER
    words first; otherwise (a file of several chunks) the trigger kernel reads them, timing words only."""
    from neurotac_cli.io import kernels

    shift = kernels.kind_shift(np.dtype(dtype).itemsize, state)
    if isinstance(blocks, list) and not any(kernels.has_kind(np.frombuffer(b, dtype=dtype), shift, 0xA) for b in blocks):
        return None
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

    t0 = time_origin(fields)

    def chunks():
        state = dat_state(fields)
        for block in read_chunks(path, offset + 2, 8):
            yield shifted(decode_dat(block, state), t0)

    return Decoded(sensor=sensor_of_header(fields), chunks=chunks, meta=_meta(fields), cut_bytes=cut_bytes(path, offset + 2, 8))


def dat_state(fields: dict) -> dict:
    """What `decode_dat` carries: the timestamp wraps, and the address layout of the file's `% Version`
    (before version 2, ATIS files: x in 9 bits, y in 8, polarity at bit 17, as Prophesee's
    `load_cd_events` reads them; a file without the line is read as version 2, as files written today are)."""
    match = re.match(r"\s*(\d+)", fields.get("version", ""))
    return {"last": None, "loop": 0, "legacy": bool(match) and int(match.group(1)) < 2}


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
    data = records[:, 1]
    (x_bits, y_shift, y_bits, p_shift) = (0x1FF, 9, 0xFF, 17) if state.get("legacy") else (0x3FFF, 14, 0x3FFF, 28)
    return (
        unwrap_32(records[:, 0], state),
        (data & x_bits).astype(np.uint16),
        ((data >> y_shift) & y_bits).astype(np.uint16),
        ((data >> p_shift) & 0x1).astype(np.uint8),
    )


# ---------------------------------------------------------------- EVT 2.1 word order

EVT21_KINDS = (0x0, 0x1, 0x8, 0xA, 0xE, 0xF)  # CD OFF, CD ON, TIME_HIGH, EXT_TRIGGER, OTHERS, CONTINUED
EVT21_WRAP_FALL = 1 << 33  # a TIME_HIGH falling back by more than half its range is a wrap (as the kernels count)


def note_evt21_order(meta: dict, legacy: bool):
    """Record the word order a reader found (from the header or the words) in `neurotac:source`."""
    meta.setdefault("source", {})["evt21_order"] = "legacy" if legacy else "little"


def evt21_halves(pairs: np.ndarray, legacy: bool) -> tuple[np.ndarray, np.ndarray]:
    """(fields, mask) of (N, 2) little-endian 32-bit halves: IMX636's legacy order puts the fields first."""
    return (pairs[:, 0], pairs[:, 1]) if legacy else (pairs[:, 1], pairs[:, 0])


def _evt21_order(path: str, offset: int, fields: dict) -> bool:
    """Whether the words are in IMX636's legacy order (fields first), from the header or the words."""
    said = evt21_order_of_header(fields)
    if said is not None:
        return said
    with open(path, "rb") as handle:
        handle.seek(offset)
        data = handle.read(8 * 8192)
    order = evt21_order_of_words(np.frombuffer(data[: len(data) - len(data) % 8], dtype="<u4").reshape(-1, 2))
    return bool(order)  # words without a TIME_HIGH decode to nothing in either order


def evt21_order_of_header(fields: dict) -> bool | None:
    """Legacy (True) or little (False) as the header says it, or None for an older header that does not."""
    match = re.search(r"endianness=(\w+)", fields.get("format", ""), re.IGNORECASE)
    if match:
        if match.group(1).lower() not in ("legacy", "little"):
            raise FormatError(f"EVT 2.1 endianness {match.group(1)!r} is not one Prophesee writes (legacy or little)")
        return match.group(1).lower() == "legacy"
    return False if "format" in fields else None  # a `% format EVT21` line without an order: OpenEB reads it little


def evt21_order_of_words(pairs: np.ndarray) -> bool | None:
    """Legacy (True) or little (False): read the right way, every word has an EVT 2.1 type, there are
    TIME_HIGH words, their other half is unused (0), and their values rise (or wrap). None where the
    words hold no TIME_HIGH either way (nothing before the first one is decoded anyway)."""
    fits, timed = [], []
    for info, other in (evt21_halves(pairs, False), evt21_halves(pairs, True)):
        kinds = info >> 28
        highs = (info[kinds == 0x8] & 0x0FFFFFFF).astype(np.int64)
        steps = np.diff(highs)
        timed.append(len(highs) > 0)
        fits.append(bool(np.isin(kinds, EVT21_KINDS).all()) and len(highs) > 0 and not other[kinds == 0x8].any()
                    and bool(np.all((steps >= 0) | (steps < -(EVT21_WRAP_FALL >> 6)))))
    if fits[0] != fits[1]:
        return fits[1]
    if fits[0] or not len(pairs):
        return False  # nothing tells them apart: OpenEB's default order
    if not any(timed):
        return None
    raise FormatError("the EVT 2.1 words fit neither word order (little nor IMX636's legacy): the file is damaged, "
                      "or not EVT 2.1")
