"""Compiled kernels: the framing count and the decoders of camera formats whose words carry state.

EVT 2.0/2.1/3.0, AEDAT 2.0, Event Stream and text rows are sequential state machines (a TIME_HIGH word sets the
time of the words after it; an EVT 3.0 vector word's x depends on every vector word since its
base), and framing is one pass that adds each event to its frame's pixel. They run as C
(io/_kernels.c, built at install): a neurotac verb is a process in a pipe, and C costs nothing to
load where numba's import and cache load cost 1.7 s per process (see docs/design.md). These
wrappers allocate the outputs (each decoder counts its events first, so its output is exact) and
keep a decoder's state in a small int64 array, so a file can be decoded chunk by chunk.
"""

import numpy as np

from neurotac_cli.errors import NeurotacError

try:
    import neurotac_cli.io._kernels as _c
except ImportError as error:  # a source checkout whose extension was never built
    raise NeurotacError(
        f"neurotac's compiled kernels are missing ({error}; run `pip install -e .` in the source folder to build them)"
    ) from None

# EVT 3.0 state slots
HIGH, LOOP, LOW, Y, BASE_X, VECTOR_P, TIMED = range(7)
# EVT 2.0 state slots; EVT 2.1's are these and its word order (the same TIME_HIGH word times both)
E2_HIGH, E2_LOOP, E2_TIMED, E21_LEGACY = range(4)
# Event Stream 2.x state slots (FLAGS: bit 0 = ATIS threshold crossing, bit 1 = polarity)
ES_T, ES_STEP, ES_FLAGS, ES_X, ES_Y = range(5)

# text parser statuses
TEXT_OK, TEXT_NUMBER, TEXT_FIELDS, TEXT_COORDINATE, TEXT_POLARITY, TEXT_FRACTION, TEXT_DIGITS = range(7)
TEXT_PROBLEMS = {
    TEXT_NUMBER: "not a number",
    TEXT_FIELDS: "wrong number of fields",
    TEXT_COORDINATE: "x and y must be whole numbers from 0 to 65535",
    TEXT_POLARITY: "polarity must be 0/1 or -1/1",
    TEXT_FRACTION: "time is not a whole number of microseconds",
    TEXT_DIGITS: "number too long",
}


def evt3_state() -> np.ndarray:
    return np.zeros(7, dtype=np.int64)


def evt2_state() -> np.ndarray:
    return np.zeros(3, dtype=np.int64)


def evt21_state(legacy: bool) -> np.ndarray:
    """EVT 2.1's decoder state; `legacy`: the words are in IMX636's legacy order (fields first, then
    the mask), else in OpenEB's (mask first). The order is fixed for the stream, so it travels with the state."""
    state = np.zeros(4, dtype=np.int64)
    state[E21_LEGACY] = bool(legacy)
    return state


def es_state() -> np.ndarray:
    return np.zeros(5, dtype=np.int64)


def es_pending(state: np.ndarray) -> int:
    """Bytes of an Event Stream event begun but not finished in `state` (the decoder's step within it)."""
    return int(state[1])


def event_arrays(count: int):
    """(t, x, y, p) arrays for `count` events, not yet filled, in the dtypes every decoder returns."""
    return np.empty(count, np.int64), np.empty(count, np.uint16), np.empty(count, np.uint16), np.empty(count, np.uint8)


# ---------------------------------------------------------------- framing


def count_events(t, x, y, p, start: int, window_us: int, first: int, out: np.ndarray, zeroed: int | None = None, order=None) -> tuple:
    """Add events to `out` (n, 2, H, W) uint16, whose frame 0 is window `first` counted from `start`.

    One pass; returns (inside, saturated, before, late, beyond, k_max, zeroed, back, first_back):
    events counted into these windows (of which `saturated` could not be, the pixel being at
    65535), events before `start`, events of windows before `first` (late), events of windows past
    the buffer (beyond), the largest window index seen (-1 for none), how many leading frames of
    `out` now hold counts, and, with `order` (an int64 array [latest, slack, floor, gap, gap_at,
    gap_from], updated in place), the events more than `slack` µs behind the latest earlier event
    or before `floor` and the index of the first of them (-1 for none; without `order`: 0 and -1).
    `order` also records the largest step forward in time beyond `gap`: its length, the index of
    the event after it in this call (left as it was when no step is longer) and the time before it.
    Frames from `zeroed` on (by default none: all of `out` holds counts) hold garbage and are zeroed
    when an event first reaches them (and every frame before it), so each is written while it is in
    the cache: framing a long stream is bound by memory traffic, and zeroing a buffer ahead of time
    reads it from memory twice. Coordinates must lie inside the sensor and p in {0, 1}.
    """
    n, channels, height, width = out.shape
    if channels != 2 or out.dtype != np.uint16 or not out.flags.c_contiguous:
        raise ValueError("count_events counts into a C-contiguous (n, 2, H, W) uint16 array")
    zeroed = n if zeroed is None else int(zeroed)
    t = np.ascontiguousarray(t, dtype=np.int64)
    x = np.ascontiguousarray(x, dtype=np.uint16)
    y = np.ascontiguousarray(y, dtype=np.uint16)
    p = np.ascontiguousarray(p, dtype=np.uint8)
    return _c.count_events(t, x, y, p, int(start), int(window_us), int(first), out, n, height, width, zeroed, order)


def time_order(t, latest: int, slack: int, floor: int | None = None) -> tuple[int, int, int]:
    """Events more than `slack` µs behind the latest earlier event (`latest` before these), or before
    `floor`: (how many, index of the first (-1 for none), the latest time after these events)."""
    t = np.ascontiguousarray(t, dtype=np.int64)
    return _c.time_order(t, int(latest), int(slack), -(1 << 63) if floor is None else int(floor))


# ---------------------------------------------------------------- decoders


def decode_evt3(words: np.ndarray, state: np.ndarray):
    """EVT 3.0 16-bit words -> (t, x, y, p) following OpenEB: TIME_HIGH resets the low part, a
    backward TIME_LOW is kept as written, events before the first TIME_HIGH are skipped."""
    t, x, y, p = event_arrays(_c.evt3_count(words))
    k = _c.evt3_decode(words, state, t, x, y, p)
    return t[:k], x[:k], y[:k], p[:k]


def decode_evt2(words: np.ndarray, state: np.ndarray):
    """EVT 2.0 32-bit words -> (t, x, y, p): CD_OFF/CD_ON words timed by the last TIME_HIGH."""
    t, x, y, p = event_arrays(_c.evt2_count(words))
    k = _c.evt2_decode(words, state, t, x, y, p)
    return t[:k], x[:k], y[:k], p[:k]


def decode_evt21(words: np.ndarray, state: np.ndarray):
    """EVT 2.1 64-bit words -> (t, x, y, p), as OpenEB's decoder reads them: a CD_OFF/CD_ON word is a
    vector of up to 32 pixels from its base x (emitted from the lowest bit up), timed by the last
    TIME_HIGH (x 64 µs, plus 2^34 µs per wrap) plus its own 6-bit low part; words before the first
    TIME_HIGH have no time base and are skipped. `state` (`evt21_state`) carries the time base and the order."""
    t, x, y, p = event_arrays(_c.evt21_count(words, bool(state[E21_LEGACY])))
    k = _c.evt21_decode(words, state, t, x, y, p)
    return t[:k], x[:k], y[:k], p[:k]


def decode_davis(data: np.ndarray, height: int):
    """AEDAT 2.0 DAVIS records (big-endian bytes, 8 per record) -> (t, x, row, p, largest) of the DVS
    events; APS/IMU (bit 31) and special (bit 10) words skipped; y flipped; timestamps unsigned.
    `largest` is the largest jAER y seen (-1 for none), so the caller can report a row outside the sensor."""
    data = data[: len(data) - len(data) % 8]
    t, x, y, p = event_arrays(_c.davis_count(data))
    k, largest = _c.davis_decode(data, int(height), t, x, y, p)
    return t[:k], x[:k], y[:k], p[:k], largest


def decode_es(data: np.ndarray, width: int, height: int, atis: bool, state: np.ndarray):
    """Event Stream 2.x DVS or ATIS bytes -> (t, x, y_stored, p, outside). An event is a head byte
    followed by x and y as little-endian uint16. DVS head bytes: 0xFF adds 127 µs, 0xFE is a reset
    marker, any other byte starts an event (t += byte >> 1, polarity = byte & 1). ATIS head bytes: 6
    high bits set adds 63 µs times the 2 low bits, any other byte starts an event (t += byte >> 2,
    polarity = bit 1, threshold crossing = bit 0); only change detections are kept, exposure
    measurements (threshold crossings) are skipped. `outside`: some coordinate lies beyond the
    declared size."""
    t, x, y, p = event_arrays(len(data) // 5 + 1)
    k, outside = _c.es_decode(data, int(width), int(height), bool(atis), state, t, x, y, p)
    return t[:k], x[:k], y[:k], p[:k], outside


def kind_shift(word_bytes: int, state: np.ndarray) -> int:
    """Where a word's 4-bit type lies: the top of a 16- or 32-bit word, or of EVT 2.1's fields half."""
    if word_bytes == 8:
        return 28 if state[E21_LEGACY] else 60
    return 28 if word_bytes == 4 else 12


def _triggers(words: np.ndarray, word_bytes: int, state: np.ndarray):
    count = _c.count_kind(words, word_bytes, kind_shift(word_bytes, state), 0xA)
    t, value, channel = np.empty(count, np.int64), np.empty(count, np.uint8), np.empty(count, np.uint8)
    k = _c.triggers(words, word_bytes, state, t, value, channel)
    return t[:k], value[:k], channel[:k]


def evt3_triggers(words: np.ndarray, state: np.ndarray):
    """EXT_TRIGGER words of EVT 3.0 -> (t, value, id), timed as decode_evt3 times events."""
    return _triggers(words, 2, state)


def evt2_triggers(words: np.ndarray, state: np.ndarray):
    """EXT_TRIGGER words of EVT 2.0 -> (t, value, id), timed as decode_evt2 times events."""
    return _triggers(words, 4, state)


def evt21_triggers(words: np.ndarray, state: np.ndarray):
    """EXT_TRIGGER words of EVT 2.1 -> (t, value, id), timed as decode_evt21 times events."""
    return _triggers(words, 8, state)


def has_kind(words: np.ndarray, shift: int, kind: int) -> bool:
    """Whether any word has `kind` in the 4 bits from `shift` (see `kind_shift`)."""
    return _c.count_kind(words, words.dtype.itemsize, shift, kind) > 0


def parse_text(data: np.ndarray, roles: np.ndarray, comma: bool, time_digits: int):
    """Rows of text numbers -> (t, x, y, p, rows, status, offset, newlines).

    `roles[i]` says what field i is: 0 = time, 1 = x, 2 = y, 3 = polarity, -1 = ignored. Fields are
    separated by a comma (`comma`) or by runs of spaces and tabs; blank lines are skipped. Time is a
    decimal (optionally with an exponent) scaled by 10**time_digits to whole µs: exactly, from its
    digits, with no float rounding; a time column in µs (time_digits 0) must be whole, finer columns
    are rounded half away from zero to the µs. On the first problem, `status` says what and `offset`
    where (the start of its line). One pass over the bytes: a small state machine per field.
    """
    newlines = int(np.count_nonzero(data == 10))
    t, x, y, p = event_arrays(newlines + 1)
    rows, status, offset = _c.parse_text(data, np.ascontiguousarray(roles, dtype=np.int64), bool(comma), int(time_digits), t, x, y, p)
    return t[:rows], x[:rows], y[:rows], p[:rows], rows, status, offset, newlines
