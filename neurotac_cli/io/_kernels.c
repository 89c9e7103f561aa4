/* Compiled kernels of neurotac: the framing count and the stateful camera-word decoders.
 *
 * Built at install (setuptools ext-modules) so that a process pays nothing to load them: each verb is
 * a process in a pipe, and a JIT's import and cache load (about 1.7 s measured for numba) cost more
 * than counting 20 million events. Arrays come in through the buffer protocol, allocated by the
 * Python wrappers in io/kernels.py, which also document each function; decoders have a count pass
 * (to size their output) and a decode pass. Decoder state lives in a small int64 array that the
 * caller keeps from chunk to chunk.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    Py_buffer view;
    int held;
} Buf;

static void release(Buf *b, int n) {
    for (int i = 0; i < n; i++)
        if (b[i].held) PyBuffer_Release(&b[i].view);
}

/* Get a C-contiguous buffer of `object`, writable or not, whose size is a multiple of `item` bytes. */
static int take(PyObject *object, Buf *b, int writable, Py_ssize_t item, const char *what) {
    if (PyObject_GetBuffer(object, &b->view, PyBUF_C_CONTIGUOUS | (writable ? PyBUF_WRITABLE : 0)) < 0) return -1;
    b->held = 1;
    if (b->view.len % item) {
        PyErr_Format(PyExc_ValueError, "%s: %zd bytes is not a whole number of %zd-byte items", what, b->view.len, item);
        return -1;
    }
    return 0;
}

/* The four event outputs every decoder fills, from b[0]: t (int64), x, y (uint16), p (uint8). */
static int take_events(PyObject *ot, PyObject *ox, PyObject *oy, PyObject *op, Buf *b) {
    return take(ot, &b[0], 1, 8, "t") || take(ox, &b[1], 1, 2, "x") || take(oy, &b[2], 1, 2, "y") || take(op, &b[3], 1, 1, "p");
}

#define ITEMS(b, type) ((b).view.len / (Py_ssize_t)sizeof(type))
#define DATA(b, type) ((type *)(b).view.buf)

static inline uint16_t load16(const unsigned char *p) { uint16_t v; memcpy(&v, p, 2); return v; }
static inline uint32_t load32(const unsigned char *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static inline uint64_t load64(const unsigned char *p) { uint64_t v; memcpy(&v, p, 8); return v; }

static inline int popcount(int64_t v) { return __builtin_popcountll((unsigned long long)v); }

/* ------------------------------------------------------------------ framing */

/* Count events into frames; with `order` (int64 [latest, slack, floor, gap, gap_at, gap_from]),
 * also count the events more than `slack` behind the latest earlier one, or before `floor`, keep
 * `latest` up to date, and record a step forward in time longer than `gap`: its length, the
 * event's index in this call and the time before it. */
static PyObject *count_events(PyObject *self, PyObject *args) {
    PyObject *ot, *ox, *oy, *op, *oout, *oorder;
    long long start, window, first, zeroed;
    Py_ssize_t n, height, width;
    if (!PyArg_ParseTuple(args, "OOOOLLLOnnnLO", &ot, &ox, &oy, &op, &start, &window, &first, &oout, &n, &height, &width, &zeroed, &oorder))
        return NULL;
    Buf b[6];
    memset(b, 0, sizeof b);
    if (take(ot, &b[0], 0, 8, "t") || take(ox, &b[1], 0, 2, "x") || take(oy, &b[2], 0, 2, "y") || take(op, &b[3], 0, 1, "p") ||
        take(oout, &b[4], 1, 2, "out") || (oorder != Py_None && take(oorder, &b[5], 1, 8, "order"))) {
        release(b, 6);
        return NULL;
    }
    Py_ssize_t events = ITEMS(b[0], int64_t);
    Py_ssize_t cells = 2 * height * width;
    if (window <= 0 || ITEMS(b[1], uint16_t) != events || ITEMS(b[2], uint16_t) != events || ITEMS(b[3], uint8_t) != events ||
        ITEMS(b[4], uint16_t) < n * cells || zeroed < 0 || zeroed > n || (b[5].held && ITEMS(b[5], int64_t) != 6)) {
        release(b, 6);
        PyErr_SetString(PyExc_ValueError, "count_events: arrays of different lengths, a buffer too small, or a bad window");
        return NULL;
    }
    const int64_t *t = DATA(b[0], int64_t);
    const uint16_t *x = DATA(b[1], uint16_t), *y = DATA(b[2], uint16_t);
    const uint8_t *p = DATA(b[3], uint8_t);
    uint16_t *flat = DATA(b[4], uint16_t);
    int64_t *order = b[5].held ? DATA(b[5], int64_t) : NULL;
    int64_t latest = order ? order[0] : 0, slack = order ? order[1] : 0, floor = order ? order[2] : INT64_MIN;
    int64_t gap = order ? order[3] : 0, gap_at = order ? order[4] : -1, gap_from = order ? order[5] : 0;
    long long inside = 0, saturated = 0, before = 0, late = 0, beyond = 0, k_max = -1, back = 0, outside = 0;
    Py_ssize_t first_back = -1;
    Py_BEGIN_ALLOW_THREADS
    int64_t k = 0, j = -1, lo = start, hi = start, base = 0;  /* [lo, hi): the previous event's window */
    for (Py_ssize_t i = 0; i < events; i++) {
        int64_t ti = t[i];
        if (order) {  /* branch-free but for the first event out of order */
            int bad = (ti < latest - slack) | (ti < floor);
            back += bad;
            if (bad && first_back < 0) first_back = i;
            if (ti - latest > gap) { gap = ti - latest; gap_at = i; gap_from = latest; }
            latest = ti > latest ? ti : latest;  /* an event out of order lies below `latest`: it stays */
        }
        if (ti < lo || ti >= hi) {
            int64_t d = ti - start;
            k = d >= 0 ? d / window : -((-d + window - 1) / window);  /* floor division */
            lo = start + k * window;
            hi = lo + window;
            j = k - first;
            if (j >= zeroed && j < n) {  /* frames are zeroed just before their first count, while in the cache */
                memset(flat + zeroed * cells, 0, (size_t)((j + 1 - zeroed) * cells) * sizeof(uint16_t));
                zeroed = j + 1;
            }
            base = j * cells;
        }
        if (k > k_max) k_max = k;
        if (k < 0) { before++; continue; }
        if (j < 0) { late++; continue; }
        if (j >= n) { beyond++; continue; }
        int64_t offset = ((int64_t)p[i] * height + y[i]) * width + x[i];
        /* callers check the sensor; one compare (no cost measured) keeps the buffer safe whatever they pass */
        if ((uint64_t)offset >= (uint64_t)cells) { outside++; continue; }
        inside++;
        uint16_t *cell = flat + base + offset;
        if (*cell == 65535) saturated++;
        else (*cell)++;
    }
    Py_END_ALLOW_THREADS
    if (order) { order[0] = latest; order[3] = gap; order[4] = gap_at; order[5] = gap_from; }
    release(b, 6);
    if (outside) {
        PyErr_Format(PyExc_ValueError, "count_events: %lld events fall outside the %zdx%zd frames (x, y or polarity out of range)", outside, width, height);
        return NULL;
    }
    return Py_BuildValue("(LLLLLLLLn)", inside, saturated, before, late, beyond, k_max, zeroed, back, first_back);
}

/* Events more than `slack` behind the latest earlier event, or before `floor`: (how many, index of
 * the first, -1 for none, the latest time after these events). */
static PyObject *time_order(PyObject *self, PyObject *args) {
    PyObject *ot;
    long long latest, slack, floor;
    if (!PyArg_ParseTuple(args, "OLLL", &ot, &latest, &slack, &floor)) return NULL;
    Buf b[1];
    memset(b, 0, sizeof b);
    if (take(ot, &b[0], 0, 8, "t")) { release(b, 1); return NULL; }
    const int64_t *t = DATA(b[0], int64_t);
    Py_ssize_t n = ITEMS(b[0], int64_t), first = -1;
    long long back = 0;
    for (Py_ssize_t i = 0; i < n; i++) {  /* branch-free but for the first one out of order */
        int64_t v = t[i];
        int bad = (v < latest - slack) | (v < floor);
        back += bad;
        if (bad && first < 0) first = i;
        latest = v > latest ? v : latest;  /* floor <= the first time: an event out of order is below `latest` */
    }
    release(b, 1);
    return Py_BuildValue("(LnL)", back, first, latest);
}

/* ------------------------------------------------------------------ Prophesee EVT 3.0 */

enum { HIGH, LOOP, LOW, ROW, BASE_X, VECTOR_P, TIMED };
#define EVT3_LOOP (1LL << 24)
#define EVT3_WRAP ((1LL << 12) - 1 - 10)

static PyObject *evt3_count(PyObject *self, PyObject *args) {
    PyObject *ow;
    if (!PyArg_ParseTuple(args, "O", &ow)) return NULL;
    Buf b[1];
    memset(b, 0, sizeof b);
    if (take(ow, &b[0], 0, 2, "words")) { release(b, 1); return NULL; }
    const unsigned char *w = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / 2;
    long long count = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t word = load16(w + 2 * i), kind = word >> 12;
        if (kind == 0x2) count++;
        else if (kind == 0x4) count += popcount(word & 0xFFF);
        else if (kind == 0x5) count += popcount(word & 0xFF);
    }
    release(b, 1);
    return PyLong_FromLongLong(count);
}

/* Advance the EVT 3.0 clock on a TIME_LOW or TIME_HIGH word; returns 1 when the word was one of them. */
static inline int evt3_time(int64_t kind, int64_t payload, int64_t *s) {
    if (kind == 0x6) { s[LOW] = payload; return 1; }
    if (kind == 0x8) {
        if (s[TIMED] && s[HIGH] - payload >= EVT3_WRAP) s[LOOP]++;
        s[HIGH] = payload;
        s[LOW] = 0;
        s[TIMED] = 1;
        return 1;
    }
    return 0;
}

static PyObject *evt3_decode(PyObject *self, PyObject *args) {
    PyObject *ow, *os, *ot, *ox, *oy, *op;
    if (!PyArg_ParseTuple(args, "OOOOOO", &ow, &os, &ot, &ox, &oy, &op)) return NULL;
    Buf b[6];
    memset(b, 0, sizeof b);
    if (take(ow, &b[0], 0, 2, "words") || take(os, &b[1], 1, 8, "state") || take_events(ot, ox, oy, op, &b[2])) { release(b, 6); return NULL; }
    const unsigned char *w = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / 2, cap = ITEMS(b[2], int64_t);
    int64_t s[7];
    memcpy(s, b[1].view.buf, sizeof s);
    int64_t *t = DATA(b[2], int64_t);
    uint16_t *x = DATA(b[3], uint16_t), *y = DATA(b[4], uint16_t);
    uint8_t *p = DATA(b[5], uint8_t);
    Py_ssize_t k = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t word = load16(w + 2 * i), kind = word >> 12, payload = word & 0xFFF;
        int64_t now = (s[HIGH] << 12) + s[LOOP] * EVT3_LOOP + s[LOW];
        if (kind == 0x0) s[ROW] = payload & 0x7FF;
        else if (kind == 0x2) {
            if (s[TIMED] && k < cap) { t[k] = now; x[k] = payload & 0x7FF; y[k] = s[ROW]; p[k] = (payload >> 11) & 1; k++; }
        } else if (kind == 0x3) {
            s[BASE_X] = payload & 0x7FF;
            s[VECTOR_P] = (payload >> 11) & 1;
        } else if (kind == 0x4 || kind == 0x5) {
            int width = kind == 0x4 ? 12 : 8;
            if (s[TIMED])
                for (int bit = 0; bit < width; bit++)
                    if (((payload >> bit) & 1) && k < cap) { t[k] = now; x[k] = s[BASE_X] + bit; y[k] = s[ROW]; p[k] = s[VECTOR_P]; k++; }
            s[BASE_X] += width;
        } else evt3_time(kind, payload, s);
    }
    memcpy(b[1].view.buf, s, sizeof s);
    release(b, 6);
    return PyLong_FromSsize_t(k);
}

/* ------------------------------------------------------------------ Prophesee EVT 2.0 */

enum { E2_HIGH, E2_LOOP, E2_TIMED };
#define EVT2_LOOP (1LL << 34)

static PyObject *evt2_count(PyObject *self, PyObject *args) {
    PyObject *ow;
    if (!PyArg_ParseTuple(args, "O", &ow)) return NULL;
    Buf b[1];
    memset(b, 0, sizeof b);
    if (take(ow, &b[0], 0, 4, "words")) { release(b, 1); return NULL; }
    const unsigned char *w = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / 4;
    long long count = 0;
    for (Py_ssize_t i = 0; i < n; i++) count += (load32(w + 4 * i) >> 28) <= 1;
    release(b, 1);
    return PyLong_FromLongLong(count);
}

static inline void evt2_time(int64_t word, int64_t *s) {
    int64_t value = word & 0x0FFFFFFF;
    if (s[E2_TIMED] && s[E2_HIGH] - value > (1LL << 27)) s[E2_LOOP]++;
    s[E2_HIGH] = value;
    s[E2_TIMED] = 1;
}

static PyObject *evt2_decode(PyObject *self, PyObject *args) {
    PyObject *ow, *os, *ot, *ox, *oy, *op;
    if (!PyArg_ParseTuple(args, "OOOOOO", &ow, &os, &ot, &ox, &oy, &op)) return NULL;
    Buf b[6];
    memset(b, 0, sizeof b);
    if (take(ow, &b[0], 0, 4, "words") || take(os, &b[1], 1, 8, "state") || take_events(ot, ox, oy, op, &b[2])) { release(b, 6); return NULL; }
    const unsigned char *w = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / 4, cap = ITEMS(b[2], int64_t);
    int64_t s[3];
    memcpy(s, b[1].view.buf, sizeof s);
    int64_t *t = DATA(b[2], int64_t);
    uint16_t *x = DATA(b[3], uint16_t), *y = DATA(b[4], uint16_t);
    uint8_t *p = DATA(b[5], uint8_t);
    Py_ssize_t k = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t word = load32(w + 4 * i), kind = word >> 28;
        if (kind <= 1) {
            if (s[E2_TIMED] && k < cap) {
                t[k] = (s[E2_HIGH] << 6) + s[E2_LOOP] * EVT2_LOOP + ((word >> 22) & 0x3F);
                x[k] = (word >> 11) & 0x7FF;
                y[k] = word & 0x7FF;
                p[k] = (uint8_t)kind;
                k++;
            }
        } else if (kind == 0x8) evt2_time(word, s);
    }
    memcpy(b[1].view.buf, s, sizeof s);
    release(b, 6);
    return PyLong_FromSsize_t(k);
}

/* ------------------------------------------------------------------ Prophesee EVT 2.1 */

/* EVT 2.1 times as EVT 2.0 does (the same TIME_HIGH word), so its state is EVT 2.0's slots plus the
 * word order, fixed when the state is made: each 64-bit word is two little-endian 32-bit halves, the
 * fields (type, time low, x, y) and a 32-pixel mask, fields first in IMX636's legacy order. */
enum { E21_LEGACY = 3 };

static inline uint32_t evt21_half(uint64_t word, int first) { return (uint32_t)(first ? word : word >> 32); }

static PyObject *evt21_count(PyObject *self, PyObject *args) {
    PyObject *ow;
    int legacy;
    if (!PyArg_ParseTuple(args, "Op", &ow, &legacy)) return NULL;
    Buf b[1];
    memset(b, 0, sizeof b);
    if (take(ow, &b[0], 0, 8, "words")) { release(b, 1); return NULL; }
    const unsigned char *w = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / 8;
    long long count = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        uint64_t word = load64(w + 8 * i);
        if ((evt21_half(word, legacy) >> 28) <= 1) count += __builtin_popcount(evt21_half(word, !legacy));
    }
    release(b, 1);
    return PyLong_FromLongLong(count);
}

/* A CD word's pixels go out from its base x up, as OpenEB emits them. */
static PyObject *evt21_decode(PyObject *self, PyObject *args) {
    PyObject *ow, *os, *ot, *ox, *oy, *op;
    if (!PyArg_ParseTuple(args, "OOOOOO", &ow, &os, &ot, &ox, &oy, &op)) return NULL;
    Buf b[6];
    memset(b, 0, sizeof b);
    if (take(ow, &b[0], 0, 8, "words") || take(os, &b[1], 1, 8, "state") || take_events(ot, ox, oy, op, &b[2])) { release(b, 6); return NULL; }
    if (ITEMS(b[1], int64_t) != 4) { release(b, 6); PyErr_SetString(PyExc_ValueError, "evt21_decode: the state holds 4 items"); return NULL; }
    const unsigned char *w = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / 8, cap = ITEMS(b[2], int64_t);
    int64_t s[4];
    memcpy(s, b[1].view.buf, sizeof s);
    int legacy = s[E21_LEGACY] != 0;
    int64_t *t = DATA(b[2], int64_t);
    uint16_t *x = DATA(b[3], uint16_t), *y = DATA(b[4], uint16_t);
    uint8_t *p = DATA(b[5], uint8_t);
    Py_ssize_t k = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        uint64_t word = load64(w + 8 * i);
        uint32_t fields = evt21_half(word, legacy), mask = evt21_half(word, !legacy);
        int64_t kind = fields >> 28;
        if (kind <= 1) {
            if (!s[E2_TIMED]) continue;
            int64_t now = (s[E2_HIGH] << 6) + s[E2_LOOP] * EVT2_LOOP + ((fields >> 22) & 0x3F);
            uint16_t base = (fields >> 11) & 0x7FF, row = fields & 0x7FF;
            for (; mask && k < cap; mask &= mask - 1) {
                t[k] = now; x[k] = base + (uint16_t)__builtin_ctz(mask); y[k] = row; p[k] = (uint8_t)kind;
                k++;
            }
        } else if (kind == 0x8) evt2_time(fields, s);
    }
    memcpy(b[1].view.buf, s, sizeof s);
    release(b, 6);
    return PyLong_FromSsize_t(k);
}

/* ------------------------------------------------------------------ EVT 2.0/2.1/3.0 external triggers */

static PyObject *triggers(PyObject *self, PyObject *args) {
    PyObject *ow, *os, *ot, *ov, *oc;
    int word_bytes;
    if (!PyArg_ParseTuple(args, "OiOOOO", &ow, &word_bytes, &os, &ot, &ov, &oc)) return NULL;
    if (word_bytes != 2 && word_bytes != 4 && word_bytes != 8) { PyErr_SetString(PyExc_ValueError, "triggers: words of 2, 4 or 8 bytes"); return NULL; }
    Buf b[5];
    memset(b, 0, sizeof b);
    if (take(ow, &b[0], 0, word_bytes, "words") || take(os, &b[1], 1, 8, "state") || take(ot, &b[2], 1, 8, "t") ||
        take(ov, &b[3], 1, 1, "value") || take(oc, &b[4], 1, 1, "id")) { release(b, 5); return NULL; }
    if (ITEMS(b[1], int64_t) < (word_bytes == 2 ? 7 : word_bytes == 8 ? 4 : 3)) {
        release(b, 5);
        PyErr_SetString(PyExc_ValueError, "triggers: a state too small for these words");
        return NULL;
    }
    const unsigned char *w = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / word_bytes, cap = ITEMS(b[2], int64_t), k = 0;
    int64_t *s = DATA(b[1], int64_t), *t = DATA(b[2], int64_t);
    uint8_t *value = DATA(b[3], uint8_t), *channel = DATA(b[4], uint8_t);
    for (Py_ssize_t i = 0; i < n; i++) {
        if (word_bytes >= 4) {  /* EVT 2.1's fields half is an EVT 2.0 word, as far as time and triggers go */
            int64_t word = word_bytes == 8 ? evt21_half(load64(w + 8 * i), s[E21_LEGACY] != 0) : load32(w + 4 * i), kind = word >> 28;
            if (kind == 0x8) evt2_time(word, s);
            else if (kind == 0xA && s[E2_TIMED] && k < cap) {
                t[k] = (s[E2_HIGH] << 6) + s[E2_LOOP] * EVT2_LOOP + ((word >> 22) & 0x3F);
                value[k] = word & 1;
                channel[k] = (word >> 8) & 0x1F;
                k++;
            }
        } else {
            int64_t word = load16(w + 2 * i), kind = word >> 12, payload = word & 0xFFF;
            if (evt3_time(kind, payload, s)) continue;
            if (kind == 0xA && s[TIMED] && k < cap) {
                t[k] = (s[HIGH] << 12) + s[LOOP] * EVT3_LOOP + s[LOW];
                value[k] = payload & 1;
                channel[k] = (payload >> 8) & 0xF;
                k++;
            }
        }
    }
    release(b, 5);
    return PyLong_FromSsize_t(k);
}

/* How many words have `kind` in the 4 bits from `shift` (28 for 32-bit words, 12 for 16-bit words,
 * 60 or 28 for EVT 2.1's 64-bit words, little or legacy). */
static PyObject *count_kind(PyObject *self, PyObject *args) {
    PyObject *ow;
    int word_bytes, shift;
    long long kind;
    if (!PyArg_ParseTuple(args, "OiiL", &ow, &word_bytes, &shift, &kind)) return NULL;
    if (word_bytes != 2 && word_bytes != 4 && word_bytes != 8) { PyErr_SetString(PyExc_ValueError, "count_kind: words of 2, 4 or 8 bytes"); return NULL; }
    Buf b[1];
    memset(b, 0, sizeof b);
    if (take(ow, &b[0], 0, word_bytes, "words")) { release(b, 1); return NULL; }
    const unsigned char *w = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / word_bytes;
    long long count = 0;
    if (word_bytes == 8)
        for (Py_ssize_t i = 0; i < n; i++) count += ((load64(w + 8 * i) >> shift) & 0xF) == (uint64_t)kind;
    else if (word_bytes == 4)
        for (Py_ssize_t i = 0; i < n; i++) count += (load32(w + 4 * i) >> shift) == kind;
    else
        for (Py_ssize_t i = 0; i < n; i++) count += (load16(w + 2 * i) >> shift) == kind;
    release(b, 1);
    return PyLong_FromLongLong(count);
}

/* ------------------------------------------------------------------ AEDAT 2.0 DAVIS */

static inline int davis_dvs(const unsigned char *r) { return (r[0] & 0x80) == 0 && (r[2] & 0x04) == 0; }

static PyObject *davis_count(PyObject *self, PyObject *args) {
    PyObject *od;
    if (!PyArg_ParseTuple(args, "O", &od)) return NULL;
    Buf b[1];
    memset(b, 0, sizeof b);
    if (take(od, &b[0], 0, 8, "records")) { release(b, 1); return NULL; }
    const unsigned char *d = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / 8;
    long long count = 0;
    for (Py_ssize_t i = 0; i < n; i++) count += davis_dvs(d + 8 * i);
    release(b, 1);
    return PyLong_FromLongLong(count);
}

static PyObject *davis_decode(PyObject *self, PyObject *args) {
    PyObject *od, *ot, *ox, *oy, *op;
    long long height;
    if (!PyArg_ParseTuple(args, "OLOOOO", &od, &height, &ot, &ox, &oy, &op)) return NULL;
    Buf b[5];
    memset(b, 0, sizeof b);
    if (take(od, &b[0], 0, 8, "records") || take_events(ot, ox, oy, op, &b[1])) { release(b, 5); return NULL; }
    const unsigned char *d = b[0].view.buf;
    Py_ssize_t n = b[0].view.len / 8, cap = ITEMS(b[1], int64_t), k = 0;
    int64_t *t = DATA(b[1], int64_t);
    uint16_t *x = DATA(b[2], uint16_t), *y = DATA(b[3], uint16_t);
    uint8_t *p = DATA(b[4], uint8_t);
    long long largest = -1;
    for (Py_ssize_t i = 0; i < n && k < cap; i++) {
        const unsigned char *r = d + 8 * i;
        if (!davis_dvs(r)) continue;
        int64_t address = ((int64_t)r[0] << 24) | ((int64_t)r[1] << 16) | ((int64_t)r[2] << 8) | r[3];
        int64_t row = (address >> 22) & 0x1FF;
        if (row > largest) largest = row;
        t[k] = ((int64_t)r[4] << 24) | ((int64_t)r[5] << 16) | ((int64_t)r[6] << 8) | r[7];
        x[k] = (address >> 12) & 0x3FF;
        y[k] = row < height ? height - 1 - row : 0;
        p[k] = (address >> 11) & 1;
        k++;
    }
    release(b, 5);
    return Py_BuildValue("(nL)", k, largest);
}

/* ------------------------------------------------------------------ Event Stream 2.x */

enum { ES_T, ES_STEP, ES_FLAGS, ES_X, ES_Y };

static PyObject *es_decode(PyObject *self, PyObject *args) {
    PyObject *od, *os, *ot, *ox, *oy, *op;
    long long width, height;
    int atis;
    if (!PyArg_ParseTuple(args, "OLLpOOOOO", &od, &width, &height, &atis, &os, &ot, &ox, &oy, &op)) return NULL;
    Buf b[6];
    memset(b, 0, sizeof b);
    if (take(od, &b[0], 0, 1, "data") || take(os, &b[1], 1, 8, "state") || take_events(ot, ox, oy, op, &b[2])) { release(b, 6); return NULL; }
    const unsigned char *d = b[0].view.buf;
    Py_ssize_t n = b[0].view.len, cap = ITEMS(b[2], int64_t), k = 0;
    int64_t *s = DATA(b[1], int64_t), *t = DATA(b[2], int64_t);
    uint16_t *x = DATA(b[3], uint16_t), *y = DATA(b[4], uint16_t);
    uint8_t *p = DATA(b[5], uint8_t);
    int outside = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t byte = d[i];
        switch (s[ES_STEP]) {
        case 0:
            if (atis) {
                if ((byte & 0xFC) == 0xFC) { s[ES_T] += 63 * (byte & 0x3); continue; }
                s[ES_T] += byte >> 2;
                s[ES_FLAGS] = byte & 0x3;
            } else {
                if (byte == 0xFF) { s[ES_T] += 127; continue; }
                if (byte == 0xFE) continue;
                s[ES_T] += byte >> 1;
                s[ES_FLAGS] = (byte & 1) << 1;
            }
            s[ES_STEP] = 1;
            break;
        case 1: s[ES_X] = byte; s[ES_STEP] = 2; break;
        case 2: s[ES_X] |= byte << 8; s[ES_STEP] = 3; break;
        case 3: s[ES_Y] = byte; s[ES_STEP] = 4; break;
        default:
            s[ES_Y] |= byte << 8;
            s[ES_STEP] = 0;
            outside |= s[ES_X] >= width || s[ES_Y] >= height;
            if ((s[ES_FLAGS] & 1) == 0 && k < cap) {
                t[k] = s[ES_T]; x[k] = (uint16_t)s[ES_X]; y[k] = (uint16_t)s[ES_Y]; p[k] = (uint8_t)(s[ES_FLAGS] >> 1);
                k++;
            }
        }
    }
    release(b, 6);
    return Py_BuildValue("(nO)", k, outside ? Py_True : Py_False);
}

/* ------------------------------------------------------------------ text (CSV, whitespace) */

enum { TEXT_OK, TEXT_NUMBER, TEXT_FIELDS, TEXT_COORDINATE, TEXT_POLARITY, TEXT_FRACTION, TEXT_DIGITS };
static const int64_t POWERS[19] = {1LL, 10LL, 100LL, 1000LL, 10000LL, 100000LL, 1000000LL, 10000000LL, 100000000LL,
    1000000000LL, 10000000000LL, 100000000000LL, 1000000000000LL, 10000000000000LL, 100000000000000LL,
    1000000000000000LL, 10000000000000000LL, 100000000000000000LL, 1000000000000000000LL};

/* One field's number, its digits read: scaled to µs for the time (role 0), checked for x, y, p. */
typedef struct {
    int64_t mantissa, significant, fraction, exponent, exp_digits;
    int negative, exp_negative, signed_, digits, content, part;  /* part: 0 before a digit, 1 integer, 2 fraction, 3 exponent */
    int dropped, dropped_first;  /* a time's fraction digits past 18 significant ones (Unix seconds to the ns): the first of them */
} Field;

static int text_value(const Field *f, int64_t role, int64_t time_digits, int64_t *out) {
    int64_t scale = (role == 0 ? time_digits : 0) + (f->exp_negative ? -f->exponent : f->exponent) - f->fraction;
    int64_t value = f->mantissa;
    if (scale > 0) {  /* digits dropped before the µs would be digits of the time itself */
        if (f->dropped || scale > 18 || f->mantissa > INT64_MAX / POWERS[scale]) return TEXT_DIGITS;
        value = f->mantissa * POWERS[scale];
    } else if (scale == 0) {
        if (f->dropped && f->dropped_first >= 5) value += 1;  /* half away from zero, as below */
    } else if (scale < 0) {  /* dropped digits lie below the kept remainder: they cannot move its rounding */
        int64_t divisor = POWERS[-scale > 18 ? 18 : -scale];
        value = -scale > 18 ? 0 : f->mantissa / divisor;
        int64_t rest = f->mantissa - value * divisor;
        if (rest != 0) {
            if (role != 0 || time_digits == 0) return role == 0 ? TEXT_FRACTION : TEXT_COORDINATE;
            if (2 * rest >= divisor) value += 1;  /* half away from zero */
        }
    }
    if (f->negative) value = -value;
    if ((role == 1 || role == 2) && (value < 0 || value > 65535)) return TEXT_COORDINATE;
    if (role == 3 && value != -1 && value != 0 && value != 1) return TEXT_POLARITY;
    *out = value;
    return TEXT_OK;
}

/* A byte of a number that is not a digit (sign, point, exponent); 0 when it has no place there. */
static int text_sign_or_point(Field *f, unsigned char byte) {
    if (byte == '.' && f->part <= 1) f->part = 2;
    else if ((byte == '-' || byte == '+') && f->part == 0 && !f->signed_) { f->negative = byte == '-'; f->signed_ = 1; }
    else if ((byte == 'e' || byte == 'E') && f->digits && f->part <= 2) f->part = 3;
    else if ((byte == '-' || byte == '+') && f->part == 3 && f->exp_digits == 0 && !f->exp_negative) f->exp_negative = byte == '-';
    else return 0;
    return 1;
}

static PyObject *parse_text(PyObject *self, PyObject *args) {
    PyObject *od, *oroles, *ot, *ox, *oy, *op;
    int comma;
    long long time_digits;
    if (!PyArg_ParseTuple(args, "OOpLOOOO", &od, &oroles, &comma, &time_digits, &ot, &ox, &oy, &op)) return NULL;
    Buf b[6];
    memset(b, 0, sizeof b);
    if (take(od, &b[0], 0, 1, "data") || take(oroles, &b[1], 0, 8, "roles") || take_events(ot, ox, oy, op, &b[2])) { release(b, 6); return NULL; }
    const unsigned char *data = b[0].view.buf;
    const int64_t *roles = DATA(b[1], int64_t);
    Py_ssize_t n = b[0].view.len, ncols = ITEMS(b[1], int64_t), cap = ITEMS(b[2], int64_t), row = 0, line_start = 0, field = 0;
    int64_t *t = DATA(b[2], int64_t);
    uint16_t *x = DATA(b[3], uint16_t), *y = DATA(b[4], uint16_t);
    uint8_t *p = DATA(b[5], uint8_t);
    int64_t role = ncols ? roles[0] : -1;
    int status = TEXT_OK;
    Field f;
    memset(&f, 0, sizeof f);
#define FAIL(why) do { status = (why); goto done; } while (0)
    for (Py_ssize_t i = 0; i <= n; i++) {
        unsigned char byte = i < n ? data[i] : '\n';
        if (byte >= '0' && byte <= '9') {
            int64_t digit = byte - '0';
            f.content = 1;
            if (role < 0) continue;
            if (f.part == 3) {
                f.exponent = f.exponent * 10 + digit;
                f.exp_digits++;
                if (f.exponent > 40) FAIL(TEXT_DIGITS);
                continue;
            }
            f.digits = 1;
            if (f.significant < 18) {
                f.mantissa = f.mantissa * 10 + digit;
                f.significant += f.mantissa != 0;
                f.fraction += f.part == 2;
            } else if (f.part <= 1 && f.mantissa <= (INT64_MAX - digit) / 10) {  /* a 19th whole digit that int64 holds */
                f.mantissa = f.mantissa * 10 + digit;
                f.significant++;
            } else if (f.part == 2 && role == 0 && time_digits > 0) {
                if (!f.dropped) f.dropped_first = (int)digit;
                f.dropped = 1;
            } else if (f.part != 2 || digit != 0) FAIL(TEXT_DIGITS);
            if (f.part == 0) f.part = 1;
            continue;
        }
        int newline = byte == '\n';
        int separator = comma ? byte == ',' : (byte == ' ' || byte == '\t');
        if (!(separator || newline)) {
            if (byte == '\r' || byte == ' ' || byte == '\t') {  /* CR, spaces around a CSV field: after a number only the field's end may follow */
                if (f.content && role >= 0) {
                    Py_ssize_t j = i + 1;
                    while (j < n && (data[j] == '\r' || data[j] == ' ' || data[j] == '\t')) j++;
                    if (j < n && data[j] != '\n' && !(comma ? data[j] == ',' : (data[j] == ' ' || data[j] == '\t'))) FAIL(TEXT_NUMBER);
                }
                continue;
            }
            f.content = 1;
            if (role >= 0 && !text_sign_or_point(&f, byte)) FAIL(TEXT_NUMBER);
            continue;
        }
        if (newline && field == 0 && !f.content) {  /* a blank line */
            line_start = i + 1;
            continue;
        }
        if (comma || f.content) {  /* the end of a field */
            if (field >= ncols) FAIL(TEXT_FIELDS);
            if (role >= 0) {
                int64_t value = 0;
                if (!f.digits || (f.part == 3 && f.exp_digits == 0)) FAIL(TEXT_NUMBER);
                int why = text_value(&f, role, time_digits, &value);
                if (why != TEXT_OK) FAIL(why);
                if (row >= cap) FAIL(TEXT_FIELDS);  /* cannot happen: rows are counted from newlines */
                if (role == 0) t[row] = value;
                else if (role == 1) x[row] = (uint16_t)value;
                else if (role == 2) y[row] = (uint16_t)value;
                else p[row] = value == 1;
            }
            field++;
            role = field < ncols ? roles[field] : -1;
            memset(&f, 0, sizeof f);
        }
        if (newline) {
            if (field != ncols) FAIL(TEXT_FIELDS);
            row++;
            field = 0;
            role = roles[0];
            line_start = i + 1;
        }
    }
    line_start = n;
#undef FAIL
done:
    release(b, 6);
    return Py_BuildValue("(nin)", row, status, line_start);
}

/* ------------------------------------------------------------------ module */

static PyMethodDef methods[] = {
    {"count_events", count_events, METH_VARARGS, "Count events into frames (see io/kernels.py count_events)."},
    {"time_order", time_order, METH_VARARGS, "Events out of time order (see io/kernels.py time_order)."},
    {"evt3_count", evt3_count, METH_VARARGS, "Events in EVT 3.0 words."},
    {"evt3_decode", evt3_decode, METH_VARARGS, "Decode EVT 3.0 words into given arrays; returns how many."},
    {"evt2_count", evt2_count, METH_VARARGS, "Events in EVT 2.0 words."},
    {"evt2_decode", evt2_decode, METH_VARARGS, "Decode EVT 2.0 words into given arrays; returns how many."},
    {"evt21_count", evt21_count, METH_VARARGS, "Events in EVT 2.1 words (in the given order)."},
    {"evt21_decode", evt21_decode, METH_VARARGS, "Decode EVT 2.1 words into given arrays; returns how many."},
    {"triggers", triggers, METH_VARARGS, "External triggers of EVT 2.0/2.1/3.0 words into given arrays; returns how many."},
    {"count_kind", count_kind, METH_VARARGS, "Words of one kind."},
    {"davis_count", davis_count, METH_VARARGS, "DVS events in AEDAT 2.0 DAVIS records."},
    {"davis_decode", davis_decode, METH_VARARGS, "Decode AEDAT 2.0 DAVIS records; returns (how many, largest jAER row)."},
    {"parse_text", parse_text, METH_VARARGS, "Parse rows of text numbers into given arrays; returns (rows, status, offset)."},
    {"es_decode", es_decode, METH_VARARGS, "Decode Event Stream 2.x bytes; returns (how many, any outside the sensor)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_kernels", "Compiled kernels of neurotac (see io/kernels.py).", -1, methods};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&module); }
