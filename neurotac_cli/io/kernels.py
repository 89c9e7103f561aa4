"""Compiled word decoders (numba) for the formats whose words carry state from word to word.

EVT 2.0/3.0 and AEDAT 2.0 are sequential state machines (a TIME_HIGH word sets the time of the
words after it; an EVT 3.0 vector word's x depends on every vector word since its base). numpy
can express them with forward fills, but needs a dozen passes over the data; one compiled pass is
5-20x faster and as fast as the C/Rust peers (see docs/design.md). Each decoder counts its events
first, so its output is allocated exactly, and takes/returns its state in a small int64 array so
a file can be decoded chunk by chunk. `cache=True` keeps the compiled code between runs.
"""

import numpy as np
from numba import njit

# EVT 3.0 state slots
HIGH, LOOP, LOW, Y, BASE_X, VECTOR_P, TIMED = range(7)
EVT3_LOOP = 1 << 24
EVT3_WRAP = (1 << 12) - 1 - 10
# EVT 2.0 state slots
E2_HIGH, E2_LOOP, E2_TIMED = range(3)
EVT2_LOOP = 1 << 34


def evt3_state() -> np.ndarray:
    return np.zeros(7, dtype=np.int64)


def evt2_state() -> np.ndarray:
    return np.zeros(3, dtype=np.int64)


@njit(cache=True, nogil=True)
def _popcount(value):
    count = 0
    while value:
        value &= value - 1
        count += 1
    return count


@njit(cache=True, nogil=True)
def decode_evt3(words, state):
    """EVT 3.0 16-bit words -> (t, x, y, p) following OpenEB: TIME_HIGH resets the low part, a
    backward TIME_LOW is kept as written, events before the first TIME_HIGH are skipped."""
    n = words.shape[0]
    count = 0
    for i in range(n):
        kind = words[i] >> 12
        if kind == 0x2:
            count += 1
        elif kind == 0x4:
            count += _popcount(words[i] & 0xFFF)
        elif kind == 0x5:
            count += _popcount(words[i] & 0xFF)
    t = np.empty(count, np.int64)
    x = np.empty(count, np.uint16)
    y = np.empty(count, np.uint16)
    p = np.empty(count, np.uint8)
    high, loop, low, row, base_x, vector_p, timed = state[0], state[1], state[2], state[3], state[4], state[5], state[6]
    k = 0
    for i in range(n):
        word = np.int64(words[i])
        kind = word >> 12
        payload = word & 0xFFF
        if kind == 0x0:
            row = payload & 0x7FF
        elif kind == 0x2:
            if timed:
                t[k] = ((high << 12) + loop * EVT3_LOOP) + low
                x[k] = payload & 0x7FF
                y[k] = row
                p[k] = (payload >> 11) & 1
                k += 1
        elif kind == 0x3:
            base_x = payload & 0x7FF
            vector_p = (payload >> 11) & 1
        elif kind == 0x4 or kind == 0x5:
            width = 12 if kind == 0x4 else 8
            if timed:
                time = ((high << 12) + loop * EVT3_LOOP) + low
                for bit in range(width):
                    if (payload >> bit) & 1:
                        t[k] = time
                        x[k] = base_x + bit
                        y[k] = row
                        p[k] = vector_p
                        k += 1
            base_x += width
        elif kind == 0x6:
            low = payload
        elif kind == 0x8:
            if timed and high - payload >= EVT3_WRAP:
                loop += 1
            high = payload
            low = 0
            timed = 1
    state[0], state[1], state[2], state[3], state[4], state[5], state[6] = high, loop, low, row, base_x, vector_p, timed
    return t[:k], x[:k], y[:k], p[:k]


@njit(cache=True, nogil=True)
def decode_evt2(words, state):
    """EVT 2.0 32-bit words -> (t, x, y, p): CD_OFF/CD_ON words timed by the last TIME_HIGH."""
    n = words.shape[0]
    count = 0
    for i in range(n):
        count += (words[i] >> 28) <= 1  # branch-free, so it vectorises
    t = np.empty(count, np.int64)
    x = np.empty(count, np.uint16)
    y = np.empty(count, np.uint16)
    p = np.empty(count, np.uint8)
    high, loop, timed = state[0], state[1], state[2]
    k = 0
    for i in range(n):
        word = np.int64(words[i])
        kind = word >> 28
        if kind <= 1:
            if timed:
                t[k] = (high << 6) + loop * EVT2_LOOP + ((word >> 22) & 0x3F)
                x[k] = (word >> 11) & 0x7FF
                y[k] = word & 0x7FF
                p[k] = kind
                k += 1
        elif kind == 0x8:
            value = word & 0x0FFFFFFF
            if timed and high - value > (1 << 27):
                loop += 1
            high = value
            timed = 1
    state[0], state[1], state[2] = high, loop, timed
    return t[:k], x[:k], y[:k], p[:k]


@njit(cache=True, nogil=True)
def decode_davis(data, height):
    """AEDAT 2.0 DAVIS records (big-endian uint8 bytes, 8 per record) -> (t, x, row, p) of the DVS
    events; APS/IMU (bit 31) and special (bit 10) words skipped; y flipped; timestamps unsigned. Returns the largest
    jAER y seen, so the caller can report a row outside the sensor."""
    n = data.shape[0] // 8
    count = 0
    for i in range(n):
        count += ((data[8 * i] & 0x80) == 0) & ((data[8 * i + 2] & 0x04) == 0)
    t = np.empty(count, np.int64)
    x = np.empty(count, np.uint16)
    y = np.empty(count, np.uint16)
    p = np.empty(count, np.uint8)
    largest = -1
    k = 0
    for i in range(n):
        j = 8 * i
        if (data[j] & 0x80) == 0 and (data[j + 2] & 0x04) == 0:
            address = (np.int64(data[j]) << 24) | (np.int64(data[j + 1]) << 16) | (np.int64(data[j + 2]) << 8) | np.int64(data[j + 3])
            stamp = (np.int64(data[j + 4]) << 24) | (np.int64(data[j + 5]) << 16) | (np.int64(data[j + 6]) << 8) | np.int64(data[j + 7])
            row = (address >> 22) & 0x1FF
            if row > largest:
                largest = row
            t[k] = stamp
            x[k] = (address >> 12) & 0x3FF
            y[k] = height - 1 - row if row < height else 0
            p[k] = (address >> 11) & 1
            k += 1
    return t, x, y, p, largest


# Event Stream 2.x state slots (FLAGS: bit 0 = ATIS threshold crossing, bit 1 = polarity)
ES_T, ES_STEP, ES_FLAGS, ES_X, ES_Y = range(5)


def es_state() -> np.ndarray:
    return np.zeros(5, dtype=np.int64)


@njit(cache=True, nogil=True)
def decode_es(data, width, height, atis, state):
    """Event Stream 2.x DVS or ATIS bytes -> (t, x, y_stored, p, outside). An event is a head byte
    followed by x and y as little-endian uint16. DVS head bytes: 0xFF adds 127 µs, 0xFE is a reset
    marker, any other byte starts an event (t += byte >> 1, polarity = byte & 1). ATIS head bytes: 6
    high bits set adds 63 µs times the 2 low bits, any other byte starts an event (t += byte >> 2,
    polarity = bit 1, threshold crossing = bit 0); only change detections are kept, exposure
    measurements (threshold crossings) are skipped. `outside`: some coordinate lies beyond the
    declared size."""
    n = data.shape[0]
    t = np.empty(n // 5 + 1, np.int64)
    x = np.empty(n // 5 + 1, np.uint16)
    y = np.empty(n // 5 + 1, np.uint16)
    p = np.empty(n // 5 + 1, np.uint8)
    time, step, flags, cx, cy = state[0], state[1], state[2], state[3], state[4]
    outside = False
    k = 0
    for i in range(n):
        byte = np.int64(data[i])
        if step == 0:
            if atis:
                if (byte & 0xFC) == 0xFC:
                    time += 63 * (byte & 0x3)
                    continue
                time += byte >> 2
                flags = byte & 0x3
            else:
                if byte == 0xFF:
                    time += 127
                    continue
                if byte == 0xFE:
                    continue
                time += byte >> 1
                flags = (byte & 1) << 1
            step = 1
        elif step == 1:
            cx = byte
            step = 2
        elif step == 2:
            cx |= byte << 8
            step = 3
        elif step == 3:
            cy = byte
            step = 4
        else:
            cy |= byte << 8
            step = 0
            outside |= cx >= width or cy >= height
            if (flags & 1) == 0:
                t[k] = time
                x[k] = cx
                y[k] = cy
                p[k] = flags >> 1
                k += 1
    state[0], state[1], state[2], state[3], state[4] = time, step, flags, cx, cy
    return t[:k], x[:k], y[:k], p[:k], outside


# ---------------------------------------------------------------- text

TEXT_OK, TEXT_NUMBER, TEXT_FIELDS, TEXT_COORDINATE, TEXT_POLARITY, TEXT_FRACTION, TEXT_DIGITS = range(7)
TEXT_PROBLEMS = {
    TEXT_NUMBER: "not a number",
    TEXT_FIELDS: "wrong number of fields",
    TEXT_COORDINATE: "x and y must be whole numbers from 0 to 65535",
    TEXT_POLARITY: "polarity must be 0/1 or -1/1",
    TEXT_FRACTION: "time is not a whole number of microseconds",
    TEXT_DIGITS: "number too long",
}
POWERS = np.array([10**k for k in range(19)], dtype=np.int64)
LIMITS = np.array([np.iinfo(np.int64).max // 10**k for k in range(19)], dtype=np.int64)  # largest mantissa per scale


@njit(cache=True, nogil=True)
def _finish(mantissa, negative, fraction, exponent, exp_negative, role, time_digits):
    """A field's digits -> (value, status): scaled to µs for the time, checked for x, y and p."""
    if exp_negative:
        exponent = -exponent
    scale = (time_digits if role == 0 else 0) + exponent - fraction
    if scale == 0:
        value = mantissa
    elif scale > 0:
        if scale > 18 or mantissa > LIMITS[scale]:
            return 0, TEXT_DIGITS
        value = mantissa * POWERS[scale]
    else:
        if -scale > 18:
            divisor = POWERS[18]
            value = np.int64(0)
            rest = mantissa
        else:
            divisor = POWERS[-scale]
            value = mantissa // divisor
            rest = mantissa - value * divisor
        if rest != 0:
            if role != 0 or time_digits == 0:
                return 0, TEXT_FRACTION if role == 0 else TEXT_COORDINATE
            if 2 * rest >= divisor:
                value += 1
    if negative:
        value = -value
    if role == 1 or role == 2:
        if value < 0 or value > 65535:
            return 0, TEXT_COORDINATE
    elif role == 3:
        if value != -1 and value != 0 and value != 1:
            return 0, TEXT_POLARITY
    return value, TEXT_OK



@njit(cache=True, nogil=True)
def parse_text(data, roles, comma, time_digits):
    """Rows of text numbers -> (t, x, y, p, rows, status, offset, newlines).

    `roles[i]` says what field i is: 0 = time, 1 = x, 2 = y, 3 = polarity, -1 = ignored. Fields are
    separated by a comma (`comma`) or by runs of spaces and tabs; blank lines are skipped. Time is a
    decimal (optionally with an exponent) scaled by 10**time_digits to whole µs: exactly, from its
    digits, with no float rounding; a time column in µs (time_digits 0) must be whole, finer columns
    are rounded half away from zero to the µs. On the first problem, `status` says what and `offset` where (the
    start of its line). One pass over the bytes: a small state machine per field.
    """
    n = data.shape[0]
    newlines = 0
    for i in range(n):
        newlines += data[i] == 10
    rows_max = newlines + 1
    t = np.empty(rows_max, np.int64)
    x = np.empty(rows_max, np.uint16)
    y = np.empty(rows_max, np.uint16)
    p = np.empty(rows_max, np.uint8)
    ncols = roles.shape[0]
    row = 0
    line_start = 0
    field = 0
    role = roles[0]
    mantissa = np.int64(0)
    significant = 0
    fraction = 0
    exponent = 0
    negative = False
    exp_negative = False
    signed = False
    part = 0  # 0 = before any digit, 1 = integer digits, 2 = after the point, 3 = exponent
    digits = False
    exp_digits = 0
    content = False  # the field has a byte other than spaces
    for i in range(n + 1):
        byte = data[i] if i < n else 10
        digit = np.int64(byte) - 48
        if 0 <= digit <= 9:
            content = True
            if role < 0:
                continue
            if part == 3:
                exponent = exponent * 10 + digit
                exp_digits += 1
                if exponent > 40:
                    return t[:row], x[:row], y[:row], p[:row], row, TEXT_DIGITS, line_start, newlines
                continue
            digits = True
            if significant < 18:
                mantissa = mantissa * 10 + digit
                significant += mantissa != 0
                fraction += part == 2
            elif part != 2 or digit != 0:
                return t[:row], x[:row], y[:row], p[:row], row, TEXT_DIGITS, line_start, newlines
            if part == 0:
                part = 1
            continue
        newline = byte == 10
        separator = (byte == 44) if comma else (byte == 32 or byte == 9)
        if not (separator or newline):
            if byte == 13 or byte == 32 or byte == 9:
                # CR, and spaces around a CSV field; after a number only the field's end may follow
                if content and role >= 0:
                    j = i + 1
                    while j < n and (data[j] == 13 or data[j] == 32 or data[j] == 9):
                        j += 1
                    # (the separator test as at the top of the loop: written `comma and ...`, the loop measured 15% slower)
                    if j < n and data[j] != 10 and not (data[j] == 44 if comma else (data[j] == 32 or data[j] == 9)):
                        return t[:row], x[:row], y[:row], p[:row], row, TEXT_NUMBER, line_start, newlines
                continue
            content = True
            if role < 0:
                continue
            if byte == 46 and part <= 1:
                part = 2
            elif (byte == 45 or byte == 43) and part == 0 and not signed:
                negative = byte == 45
                signed = True
            elif (byte == 101 or byte == 69) and digits and part <= 2:
                part = 3
            elif (byte == 45 or byte == 43) and part == 3 and exp_digits == 0 and not exp_negative:
                exp_negative = byte == 45
            else:
                return t[:row], x[:row], y[:row], p[:row], row, TEXT_NUMBER, line_start, newlines
            continue
        if newline and field == 0 and not content:
            line_start = i + 1  # a blank line
            continue
        if comma or content:
            # the end of a field
            if field >= ncols:
                return t[:row], x[:row], y[:row], p[:row], row, TEXT_FIELDS, line_start, newlines
            if role >= 0:
                if not digits or (part == 3 and exp_digits == 0):
                    return t[:row], x[:row], y[:row], p[:row], row, TEXT_NUMBER, line_start, newlines
                value, status = _finish(mantissa, negative, fraction, exponent, exp_negative, role, time_digits)
                if status != TEXT_OK:
                    return t[:row], x[:row], y[:row], p[:row], row, status, line_start, newlines
                if role == 0:
                    t[row] = value
                elif role == 1:
                    x[row] = value
                elif role == 2:
                    y[row] = value
                else:
                    p[row] = 1 if value == 1 else 0
            field += 1
            role = roles[field] if field < ncols else -1
            mantissa = np.int64(0)
            significant = 0
            fraction = 0
            exponent = 0
            negative = exp_negative = signed = digits = content = False
            part = 0
            exp_digits = 0
        if newline:
            if field != ncols:
                return t[:row], x[:row], y[:row], p[:row], row, TEXT_FIELDS, line_start, newlines
            row += 1
            field = 0
            role = roles[0]
            line_start = i + 1
    return t[:row], x[:row], y[:row], p[:row], row, TEXT_OK, n, newlines


# ---------------------------------------------------------------- Prophesee external triggers


@njit(cache=True, nogil=True)
def evt3_triggers(words, state):
    """EXT_TRIGGER words of EVT 3.0 -> (t, value, id), timed as decode_evt3 times events."""
    n = words.shape[0]
    count = 0
    for i in range(n):
        if (words[i] >> 12) == 0xA:
            count += 1
    t = np.empty(count, np.int64)
    value = np.empty(count, np.uint8)
    channel = np.empty(count, np.uint8)
    high, loop, low, timed = state[0], state[1], state[2], state[6]
    k = 0
    for i in range(n):
        word = np.int64(words[i])
        kind = word >> 12
        payload = word & 0xFFF
        if kind == 0x6:
            low = payload
        elif kind == 0x8:
            if timed and high - payload >= EVT3_WRAP:
                loop += 1
            high = payload
            low = 0
            timed = 1
        elif kind == 0xA and timed:
            t[k] = ((high << 12) + loop * EVT3_LOOP) + low
            value[k] = payload & 1
            channel[k] = (payload >> 8) & 0xF
            k += 1
    state[0], state[1], state[2], state[6] = high, loop, low, timed
    return t[:k], value[:k], channel[:k]


@njit(cache=True, nogil=True)
def evt2_triggers(words, state):
    """EXT_TRIGGER words of EVT 2.0 -> (t, value, id), timed as decode_evt2 times events."""
    n = words.shape[0]
    count = 0
    for i in range(n):
        if (words[i] >> 28) == 0xA:
            count += 1
    t = np.empty(count, np.int64)
    value = np.empty(count, np.uint8)
    channel = np.empty(count, np.uint8)
    high, loop, timed = state[0], state[1], state[2]
    k = 0
    for i in range(n):
        word = np.int64(words[i])
        kind = word >> 28
        if kind == 0x8:
            new = word & 0x0FFFFFFF
            if timed and high - new > (1 << 27):
                loop += 1
            high = new
            timed = 1
        elif kind == 0xA and timed:
            t[k] = (high << 6) + loop * EVT2_LOOP + ((word >> 22) & 0x3F)
            value[k] = word & 1
            channel[k] = (word >> 8) & 0x1F
            k += 1
    state[0], state[1], state[2] = high, loop, timed
    return t[:k], value[:k], channel[:k]


@njit(cache=True, nogil=True)
def has_kind(words, shift, kind):
    """Whether any word has `kind` in its top bits (a branch-free count, which the compiler vectorises)."""
    count = 0
    for i in range(words.shape[0]):
        count += (words[i] >> shift) == kind
    return count > 0

