"""The text parser (numba): one compiled pass over the bytes of CSV or whitespace-separated rows.

Kept in numba rather than in the C kernels of io/kernels.py: it is a long state machine, and only
`import` of a text file pays numba's start-up (about 1.7 s measured), which a text file large enough
to matter takes longer than that to read anyway. The problem codes are io/kernels.py's TEXT_*.
"""

import numpy as np
from numba import njit

from neurotac_cli.io.kernels import TEXT_COORDINATE, TEXT_DIGITS, TEXT_FIELDS, TEXT_FRACTION, TEXT_NUMBER, TEXT_OK, TEXT_POLARITY

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
