"""Bin events into two-channel count frames (thesis eq. 4.1), label them with force and phase.

Windows are half-open, `[k·T, (k+1)·T)` from each trial's sync instant t0 (recordings) or from the
first event (plain events tables, unless a start is given). A trial covers `[0, E)`: E is one force
period past the last force sample where the trial has a force trace (the force log defines the
experiment's length), else one microsecond past its last event. Window k is complete when
(k+1)·T <= E; the last, partial window is kept (default) or dropped. Empty windows are zero frames.
A plain events stream follows tonic's `ToFrame` instead: window k is complete when it ends at or
before the last event's time, so its frames equal tonic's (see docs/commands/frame.md for the two
edge cases where tonic differs from its own description).

Counts are uint16 (channel 0 = OFF, 1 = ON); a pixel that would pass 65535 stays there and the
events it could not hold are counted as saturated. `dtype="float32"` divides each channel by a
scale: by default the channel's largest count over the whole output (thesis 4.5.2), recorded in
the `neurotac:scale` metadata and in history so the same scale can be given to new data.

Everything not framed is counted in a `FramingReport`: events before the start, after the end
(or past --pad-to N), late events (out of time order by more than one window), saturated events.
"""

import os
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, SchemaError
from neurotac_cli.ops import phases as ph

MAX_COUNT = int(np.iinfo(np.uint16).max)
FORCE_AT = ("end", "mean", "median")
BUFFER_CELLS = 1 << 22  # uint16 cells of one streaming buffer: 8 MiB, whatever the recording's length
SCAN_EVENTS = 1 << 18  # events scanned at a time: a huge input batch (a whole Parquet file) is cut up
EMIT_FRAMES = 16  # completed frames leave together, as one Arrow batch (at most 16 windows of stream time late)


# ---------------------------------------------------------------- kernel

PAGE_BYTES = 4096

try:  # numba compiles the one-pass loop; numpy's bincount path below gives identical results.
    if os.environ.get("NEUROTAC_NO_NUMBA"):
        raise ImportError
    import numba

    @numba.njit(cache=True, nogil=True)
    def _scan_numba(t, x, y, p, start, window_us, first, out, zeroed):  # pragma: no cover - compiled
        n, _, height, width = out.shape
        cells = 2 * height * width
        flat = out.reshape(-1)
        inside = saturated = before = late = beyond = 0
        k_max = -1
        k = 0
        lo = hi = start  # [lo, hi) = the window of the previous event: sorted time rarely leaves it
        base = 0  # flat offset of frame j = k - first
        j = -1
        for i in range(t.shape[0]):
            ti = t[i]
            if ti < lo or ti >= hi:
                k = (ti - start) // window_us
                lo = start + k * window_us
                hi = lo + window_us
                j = k - first
                if j >= zeroed and j < n:  # frames enter the cache zeroed just before their first count
                    flat[zeroed * cells : (j + 1) * cells] = 0
                    zeroed = j + 1
                base = j * cells
            if k > k_max:
                k_max = k
            if k < 0:
                before += 1
                continue
            if j < 0:
                late += 1
                continue
            if j >= n:
                beyond += 1
                continue
            inside += 1
            cell = base + (p[i] * height + y[i]) * width + x[i]
            count = flat[cell]
            if count == 65535:
                saturated += 1
            else:
                flat[cell] = count + 1
        return inside, saturated, before, late, beyond, k_max, zeroed

    @numba.njit(cache=True, nogil=True)
    def _touch_pages(flat):  # pragma: no cover - compiled
        for i in range(0, flat.shape[0], PAGE_BYTES // 2):
            flat[i] = 0

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised with NEUROTAC_NO_NUMBA=1
    HAVE_NUMBA = False


def _scan_numpy(t, x, y, p, start, window_us, first, out, zeroed):
    n, _, height, width = out.shape
    window = (t - start) // window_us
    k = window - first
    if len(k) and k.max() >= zeroed:
        out[zeroed : int(k.max()) + 1] = 0
        zeroed = min(n, int(k.max()) + 1)
    keep = (k >= 0) & (k < n)
    before = int(np.count_nonzero(window < 0))
    late = int(np.count_nonzero((window >= 0) & (k < 0)))
    beyond = int(np.count_nonzero(k >= n))
    k, x, y, p = k[keep], x[keep], y[keep], p[keep]
    flat = ((k * 2 + p) * height + y.astype(np.int64)) * width + x
    total = out.reshape(-1).astype(np.int64) + np.bincount(flat, minlength=out.size)
    saturated = int(np.clip(total - MAX_COUNT, 0, None).sum())
    out.reshape(-1)[:] = np.minimum(total, MAX_COUNT)
    k_max = int(window.max()) if len(window) else -1
    return int(keep.sum()), saturated, before, late, beyond, k_max, zeroed


def scan_into(t, x, y, p, start: int, window_us: int, first: int, out: np.ndarray, zeroed: int | None = None) -> tuple:
    """Add events to `out` (n, 2, H, W) uint16, whose frame 0 is window `first` counted from `start`.

    One pass; returns (inside, saturated, before, late, beyond, k_max, zeroed): events counted into
    these windows (of which `saturated` could not be, the pixel being at 65535), events before
    `start`, events of windows before `first` (late), events of windows past the buffer (beyond),
    the largest window index seen (-1 for none), and how many leading frames of `out` now hold counts.
    Frames from `zeroed` on (by default none: all of `out` holds counts) hold garbage and are zeroed
    when an event first reaches them (and every frame before it), so each is written while it is in
    the cache: framing a long stream is bound by memory traffic, and zeroing a buffer ahead of time
    reads it from memory twice.
    Coordinates must lie inside the sensor and p in {0, 1}.
    """
    zeroed = out.shape[0] if zeroed is None else int(zeroed)
    t = np.ascontiguousarray(t, dtype=np.int64)
    x = np.ascontiguousarray(x, dtype=np.uint16)
    y = np.ascontiguousarray(y, dtype=np.uint16)
    p = np.ascontiguousarray(p, dtype=np.uint8)
    if HAVE_NUMBA and out.flags.c_contiguous:
        return tuple(int(v) for v in _scan_numba(t, x, y, p, np.int64(start), np.int64(window_us), np.int64(first), out, np.int64(zeroed)))
    return _scan_numpy(t, x, y, p, int(start), int(window_us), int(first), out, zeroed)


def _faulted_in(shape) -> np.ndarray:
    """A fresh uint16 buffer whose pages the system has supplied (one write per page)."""
    buffer = np.empty(shape, dtype=np.uint16)
    if HAVE_NUMBA:
        _touch_pages(buffer.reshape(-1))
    else:
        buffer.reshape(-1)[:: PAGE_BYTES // 2] = 0
    return buffer


class _FreshBuffers:
    """Fresh streaming buffers, each faulted in by a second thread while the kernel counts into the
    one before: a long stream whose frames are all held downstream needs new memory at its own rate,
    and having the system supply those pages (zeroed) takes as long as counting the events into them.
    The first buffer is made on the spot; one more is prepared only once a stream has used it up."""

    _pool = None

    def __init__(self, shape):
        self.shape, self.next = shape, None

    def take(self) -> np.ndarray:
        if _FreshBuffers._pool is None:
            _FreshBuffers._pool = ThreadPoolExecutor(1, thread_name_prefix="neurotac-pages")
        buffer = self.next.result() if self.next is not None else np.empty(self.shape, dtype=np.uint16)
        self.next = _FreshBuffers._pool.submit(_faulted_in, self.shape)
        return buffer


def bin_into(t, x, y, p, start: int, window_us: int, first: int, out: np.ndarray) -> tuple[int, int]:
    """`scan_into`, returning only (events inside these windows, of which lost to saturation)."""
    inside, saturated, *_ = scan_into(t, x, y, p, start, window_us, first, out)
    return inside, saturated


def count_frames(t, x, y, p, window_us: int, n_frames: int, height: int, width: int, start: int = 0) -> np.ndarray:
    """The (n_frames, 2, H, W) uint16 counts of events in windows [start + k·T, start + (k+1)·T)."""
    out = np.zeros((n_frames, 2, height, width), dtype=np.uint16)
    bin_into(t, x, y, p, start, window_us, 0, out)
    return out


def n_windows(end_us: int, window_us: int, partial: str = "keep") -> int:
    """Windows of a trial covering [0, end_us): complete ones, plus the partial last one when kept."""
    if end_us <= 0:
        return 0
    full = end_us // window_us
    return full + (1 if partial == "keep" and end_us % window_us else 0)


# ---------------------------------------------------------------- options and report


@dataclass(frozen=True)
class Framing:
    """How to frame. Validated when built; never changed afterwards."""

    window_us: int
    partial: str = "keep"
    pad_to: int | str | None = None
    force_at: str = "end"
    phases: str | tuple = "auto"
    accumulate: bool = False
    dtype: str = "uint16"
    scale: tuple | None = None
    start_us: int | None = None
    trial: str = "events"

    def __post_init__(self):
        if not isinstance(self.window_us, (int, np.integer)) or self.window_us <= 0:
            raise NeurotacError(f"window must be a positive duration, got {self.window_us} µs")
        if self.partial not in ("keep", "drop"):
            raise NeurotacError(f"partial must be keep or drop, got {self.partial!r}")
        if self.pad_to is not None and self.pad_to != "longest" and (not isinstance(self.pad_to, int) or self.pad_to <= 0):
            raise NeurotacError(f"cannot pad to {self.pad_to!r} (give a number of frames, e.g. 41, or `longest`)")
        if self.force_at not in FORCE_AT:
            raise NeurotacError(f"force-at must be one of {', '.join(FORCE_AT)}, got {self.force_at!r}")
        if self.dtype not in ("uint16", "float32"):
            raise NeurotacError(f"dtype must be uint16 or float32, got {self.dtype!r}")
        if self.scale is not None:
            if self.dtype != "float32":
                raise NeurotacError("a scale only applies to --dtype float32")
            if len(self.scale) != 2 or min(self.scale) <= 0:
                raise NeurotacError(f"scale must be one or two positive counts (OFF,ON), got {self.scale!r}")
        if not (self.phases in ("auto", "none", "session") or (isinstance(self.phases, tuple) and len(self.phases) == 3)):
            raise NeurotacError(f"phases must be auto, session, none or three frame ranges, got {self.phases!r}")

    def args(self) -> dict:
        """The settings as history records them."""
        return {
            "window_us": int(self.window_us),
            "partial": self.partial,
            "pad_to": self.pad_to,
            "force_at": self.force_at,
            "phases": self.phases if isinstance(self.phases, str) else [list(r) for r in self.phases],
            "accumulate": self.accumulate,
            "dtype": self.dtype,
            "scale": list(self.scale) if self.scale else None,
            "start_us": self.start_us,
        }


@dataclass
class FramingReport:
    """What was framed and what was not, filled as frames are made."""

    events: int = 0
    framed: int = 0
    before_start: int = 0
    after_end: int = 0
    late: int = 0
    saturated_events: int = 0
    saturated_pixels: int = 0
    trials: int = 0
    frames: int = 0
    padded_frames: int = 0
    scale: list | None = None
    notes: list = field(default_factory=list)

    @property
    def dropped(self) -> int:
        return self.before_start + self.after_end + self.late

    def as_dict(self) -> dict:
        out = {
            "events": self.events,
            "framed": self.framed,
            "dropped": {"before_start": self.before_start, "after_end": self.after_end, "late": self.late},
            "saturated": {"events": self.saturated_events, "pixels": self.saturated_pixels},
            "trials": self.trials,
            "frames": self.frames,
            "padded_frames": self.padded_frames,
        }
        if self.scale is not None:
            out["scale"] = self.scale
        return out

    def warnings(self, threshold: float = 0.01, lead_in_expected: bool = False) -> list[str]:
        """Lines for stderr: drops above `threshold` of the events, and any saturation.

        `lead_in_expected`: events before t0 of synced trials are their LED blink and lead-in, not
        part of the trial by design: counted in history, not warned about."""
        lines = []
        unexpected = self.after_end + self.late + (0 if lead_in_expected else self.before_start)
        if self.events and unexpected > threshold * self.events:
            lines.append(
                f"{self.dropped} of {self.events} events ({100 * self.dropped / self.events:.1f}%) lie outside the frames "
                f"(before start {self.before_start}, after end {self.after_end}, out of time order {self.late})"
            )
        if self.saturated_events:
            lines.append(
                f"{self.saturated_pixels} pixel counts reached {MAX_COUNT} (uint16) and {self.saturated_events} events "
                "could not be counted; use a shorter --window or crop --pool later"
            )
        return lines


# ---------------------------------------------------------------- recordings


def frame_recordings(table: pa.Table, window_us: int, report: FramingReport | None = None, **options) -> pa.Table:
    """Frame every trial of a `recordings` table (see the module doc); returns a `frames` table."""
    framing = Framing(window_us=window_us, **options)
    report = report if report is not None else FramingReport()
    schema, batches = frame_recordings_batches(table, framing, report)
    return pa.Table.from_batches(list(batches), schema=schema)


def _trial_rows(table: pa.Table):
    """Yield (trial, events (t, x, y, p), force (t, value), labels) per row, without Python loops over events."""
    labels = sch.label_columns(table.schema)
    for batch in table.to_batches():
        events = batch.column("events")
        force = batch.column("force")
        ev_offsets = events.offsets.to_numpy()
        ev_values = events.flatten()  # the values this (possibly sliced) list array spans
        fields = {name: ev_values.field(name).to_numpy(zero_copy_only=False) for name in ("t", "x", "y", "p")}
        f_offsets = force.offsets.to_numpy()
        f_values = force.flatten()
        f_t = f_values.field("t").to_numpy(zero_copy_only=False)
        f_v = f_values.field("value").to_numpy(zero_copy_only=False)
        trials = batch.column("trial").to_pylist()
        label_values = {name: batch.column(name).to_pylist() for name in labels}
        for row in range(batch.num_rows):
            a, b = ev_offsets[row] - ev_offsets[0], ev_offsets[row + 1] - ev_offsets[0]
            c, d = f_offsets[row] - f_offsets[0], f_offsets[row + 1] - f_offsets[0]
            yield (
                trials[row],
                tuple(fields[name][a:b] for name in ("t", "x", "y", "p")),
                (f_t[c:d], f_v[c:d]),
                {name: label_values[name][row] for name in labels},
            )


def trial_end(event_t: np.ndarray, force_t: np.ndarray) -> int:
    """The end E of a trial's span [0, E): one force period past the last force sample where there
    is a force trace, else one microsecond past the last event."""
    if len(force_t):
        period = int(np.median(np.diff(force_t))) if len(force_t) > 1 else 1
        return int(force_t[-1]) + max(period, 1)
    if len(event_t):
        return int(event_t.max()) + 1
    return 0


def frame_recordings_batches(table: pa.Table, framing: Framing, report: FramingReport):
    """(frames schema, iterator of record batches, one per trial) for a recordings table."""
    sensor = sch.sensor_of(table.schema)
    if sensor is None:
        raise SchemaError("recordings table has no neurotac:sensor metadata (give the sensor size with --sensor WxH)")
    width, height = sensor
    labels = sch.label_columns(table.schema)
    window = framing.window_us
    rows = list(_trial_rows(table))
    lengths = [n_windows(trial_end(ev[0], force[0]), window, framing.partial) for _, ev, force, _ in rows]
    target = None
    if framing.pad_to == "longest":
        target = max(lengths, default=0)
    elif isinstance(framing.pad_to, int):
        target = framing.pad_to
    dtype = np.float32 if framing.dtype == "float32" else np.uint16

    plan = []
    for (trial, events, (force_t, force_v), label_values), n_real in zip(rows, lengths):
        t, x, y, p = events
        sch.check_events(t, x, y, p, sensor, where=f"trial {trial}", sorted_time=False)
        sch.check_force(force_v, where=f"trial {trial}")
        n_total = n_real if target is None else target
        n_real = min(n_real, n_total)
        before = int(np.count_nonzero(t < 0))
        after = int(np.count_nonzero(t >= n_real * window))
        report.events += len(t)
        report.before_start += before
        report.after_end += after
        report.framed += len(t) - before - after
        report.trials += 1
        report.frames += n_total
        report.padded_frames += n_total - n_real
        plan.append((trial, events, force_t, force_v, label_values, n_real, n_total))

    def counts_of(events, n_real, n_total, count=True):
        t, x, y, p = events
        counts = np.zeros((n_total, 2, height, width), dtype=np.uint16)
        _, saturated = bin_into(t, x, y, p, 0, window, 0, counts[:n_real])
        if framing.accumulate and n_real:
            counts[:n_real] = _accumulate(counts[:n_real], report if count else FramingReport())
        if count:
            report.saturated_events += saturated
            report.framed -= saturated
            report.saturated_pixels += int(np.count_nonzero(counts == MAX_COUNT))
        return counts

    scale = None
    if framing.dtype == "float32":
        if framing.scale is not None:
            scale = [float(s) for s in framing.scale]
        else:  # a first pass for the channels' largest counts; frames are made again below, one trial at a time
            peaks = np.zeros(2, dtype=np.int64)
            for _, events, _, _, _, n_real, n_total in plan:
                counts = counts_of(events, n_real, n_real, count=False)
                if len(counts):
                    peaks = np.maximum(peaks, counts.max(axis=(0, 2, 3)))
            scale = [float(max(peak, 1)) for peak in peaks]
        report.scale = scale
    extra = (("grasp", pa.int32()),) if framing.phases == "session" else ()
    out_schema = sch.frames_schema(height, width, labels, dtype=dtype, window_us=window, sensor=sch.sensor_meta(width, height), extra=extra)
    if scale is not None:
        out_schema = sch.set_meta(out_schema, scale=scale)
    out_schema = _keep_meta(table.schema, out_schema)

    def batches():
        for trial, events, force_t, force_v, label_values, n_real, n_total in plan:
            counts = counts_of(events, n_real, n_total)
            force = frame_force(force_t, force_v, window, n_total, framing.force_at)
            if framing.phases == "session":
                phase, grasp = ph.session_columns(force, n_real, n_total)
            else:
                phase, grasp = _phases(force, n_real, n_total, framing.phases), None
            yield _frames_batch(out_schema, trial, counts, force, phase, label_values, labels, window, scale, grasp=grasp)

    return out_schema, batches()


def _accumulate(counts: np.ndarray, report: FramingReport) -> np.ndarray:
    total = np.cumsum(counts, axis=0, dtype=np.int64)
    over = total > MAX_COUNT
    if over.any():
        report.notes.append(f"accumulated counts passed {MAX_COUNT} in {int(over.sum())} pixel-frames")
    return np.minimum(total, MAX_COUNT).astype(np.uint16)


def frame_force(force_t: np.ndarray, force_v: np.ndarray, window_us: int, n_frames: int, how: str = "end") -> np.ndarray:
    """Force per frame (float32, NaN where the trace says nothing).

    end: the latest sample at or before the window's end (k+1)·T, as a logger read on the frame
    clock shows it (thesis 5.4.1: the 2 ms force read every 10 ms); past the trace's end it holds
    the last sample. mean / median: of the samples inside [k·T, (k+1)·T), the `end` value where a
    window holds none.
    """
    out = np.full(n_frames, np.nan, dtype=np.float32)
    if not len(force_t) or not n_frames:
        return out
    force_t = np.asarray(force_t, dtype=np.int64)
    force_v = np.asarray(force_v, dtype=np.float64)
    ends = (np.arange(n_frames, dtype=np.int64) + 1) * window_us
    index = np.searchsorted(force_t, ends, side="right") - 1
    known = index >= 0
    out[known] = force_v[index[known]]
    if how == "end":
        return out
    starts = ends - window_us
    lo = np.searchsorted(force_t, starts, side="left")
    hi = np.searchsorted(force_t, ends, side="left")
    if how == "mean":
        sums = np.concatenate([[0.0], np.cumsum(force_v)])
        filled = hi > lo
        out[filled] = ((sums[hi] - sums[lo])[filled] / (hi - lo)[filled]).astype(np.float32)
        return out
    for k in np.flatnonzero(hi > lo):  # one median per frame: frames, not events
        out[k] = np.median(force_v[lo[k]:hi[k]])
    return out


def _phases(force: np.ndarray, n_real: int, n_total: int, how):
    if how == "none":
        return None
    if isinstance(how, tuple):
        return ph.phases_from_ranges(n_total, list(how))
    if np.isnan(force).all():
        return None
    labels = np.full(n_total, ph.NONE, dtype=object)
    labels[:n_real] = ph.detect_phases(force[:n_real])
    return labels


def _keep_meta(source: pa.Schema, target: pa.Schema) -> pa.Schema:
    """Carry the input's history (and other foreign keys) over to the output schema."""
    metadata = dict(target.metadata or {})
    for key, value in (source.metadata or {}).items():
        if key not in metadata and key not in (sch.KIND.encode(), sch.SYNC.encode(), b"neurotac:triggers"):
            metadata[key] = value
    return target.with_metadata(metadata)


def _frames_batch(schema, trial, counts, force, phase, label_values, labels, window_us, scale, first_frame=0, grasp=None) -> pa.RecordBatch:
    n = len(counts)
    if scale is not None:
        counts = counts.astype(np.float32) / np.asarray(scale, dtype=np.float32)[None, :, None, None]
    columns = [
        pa.array([trial] * n, pa.string()),
        pa.array(np.arange(first_frame, first_frame + n, dtype=np.int32)),
        pa.array((np.arange(first_frame, first_frame + n, dtype=np.int64)) * window_us),
        sch.counts_array(counts),
        pa.array(force, pa.float32(), from_pandas=True) if force is not None else pa.nulls(n, pa.float32()),
        pa.array(list(phase), pa.string()) if phase is not None else pa.nulls(n, pa.string()),
    ]
    if grasp is not None:
        columns.append(pa.array(grasp, pa.int32()))
    columns += [pa.array([label_values.get(name)] * n, pa.string()) for name in labels]
    names = schema.names
    for extra in names[len(columns):]:
        columns.append(pa.nulls(n, schema.field(extra).type))
    return pa.RecordBatch.from_arrays(columns, schema=schema)


# ---------------------------------------------------------------- plain events, streamed


def frame_events(schema: pa.Schema, batches, framing: Framing, report: FramingReport, sensor=None):
    """Frame a plain `events` stream as one unlabelled trial, batch by batch.

    Memory stays flat: frames are counted into a buffer of at most BUFFER_CELLS counts and leave it,
    without a copy, as soon as a later event shows they are complete (one window of slack absorbs
    small time disorder, such as the steps back of Prophesee EVT 3.0 files; events later than that
    are counted as late). Returns (frames schema, iterator of batches); the
    report is complete once the iterator is exhausted.
    """
    sensor = sensor or sch.sensor_of(schema)
    if sensor is None:
        raise SchemaError("events table has no neurotac:sensor metadata (give the sensor size with --sensor WxH)")
    width, height = sensor
    window = framing.window_us
    if framing.phases not in ("auto", "none", "session"):
        phases = framing.phases
    else:
        phases = None
    dtype = np.float32 if framing.dtype == "float32" else np.uint16
    out_schema = sch.frames_schema(height, width, (), dtype=dtype, window_us=window, sensor=sch.sensor_meta(width, height))
    if framing.dtype == "float32" and framing.scale is not None:
        out_schema = sch.set_meta(out_schema, scale=[float(s) for s in framing.scale])
    out_schema = _keep_meta(schema, out_schema)
    capacity = int(min(256, max(2, BUFFER_CELLS // (2 * height * width))))
    cap = framing.pad_to if isinstance(framing.pad_to, int) else None

    def generate():
        # Frames are counted straight into `buffer` and leave as views of it (no copy); when events
        # reach past its end, a fresh buffer takes over, carrying the frames still open (one or two).
        # Buffer frames [0, zeroed) hold counts; later ones are garbage until the kernel zeroes them.
        state = {"start": framing.start_us, "first": 0, "base": 0, "zeroed": 0, "last_t": None, "emitted": 0}
        buffer = np.empty((capacity, 2, height, width), dtype=np.uint16)
        spares = []  # earlier buffers, reused once nothing downstream holds their frames
        fresh_buffers = _FreshBuffers(buffer.shape)
        running = np.zeros((2, height, width), dtype=np.int64) if framing.accumulate else None
        held = []  # float32 output without a given scale: frames wait for the maximum
        ready = []  # frames batches made, waiting to be yielded

        def emit(frames: np.ndarray):
            """Frames leave here, in order, numbered from state['emitted']; never written again."""
            nonlocal running
            if not len(frames):
                return
            if running is not None:
                total = running[None] + np.cumsum(frames, axis=0, dtype=np.int64)
                running = total[-1].copy()
                frames = np.minimum(total, MAX_COUNT).astype(np.uint16)
            if report.saturated_events or running is not None:
                report.saturated_pixels += int(np.count_nonzero(frames == MAX_COUNT))
            first = state["emitted"]
            state["emitted"] += len(frames)
            report.frames += len(frames)
            phase = ph.phases_from_ranges(first + len(frames), list(phases))[first:] if phases else None
            if framing.dtype == "float32" and framing.scale is None:
                held.append((first, frames, phase))
                return
            scale = [float(s) for s in framing.scale] if framing.dtype == "float32" else None
            ready.append(_frames_batch(out_schema, framing.trial, frames, None, phase, {}, (), window, scale, first_frame=first))

        def zeros(count: int):
            while count > 0:
                step = min(count, capacity)
                emit(np.zeros((step, 2, height, width), dtype=np.uint16))
                count -= step

        def counted(end: int):
            """Buffer frames [0, end) hold counts (those no event reached are zeroed now)."""
            if end > state["zeroed"]:
                buffer[state["zeroed"]:end] = 0
                state["zeroed"] = end

        def flush():
            """Emit the completed frames still in the buffer, [emitted, first), as one batch."""
            a, b = state["emitted"] - state["base"], state["first"] - state["base"]
            if b > a:
                counted(b)
                emit(buffer[a:b])

        def rebase():
            """A fresh buffer starting at the first open frame, carrying the open frames over."""
            nonlocal buffer
            flush()
            offset = state["first"] - state["base"]
            filled = max(0, state["zeroed"] - offset)
            fresh = None
            for i in range(len(spares)):  # a buffer whose frames have all been let go of downstream
                if sys.getrefcount(spares[i]) <= 2:  # held by the list and the call's argument only
                    fresh = spares.pop(i)
                    break
            if fresh is None:  # frames are zeroed as they fill (np.zeros' lazily zeroed pages, faulted in by
                # scattered counts, measured 30% slower)
                fresh = fresh_buffers.take()
            fresh[:filled] = buffer[offset:offset + filled]
            if len(spares) < 4:
                spares.append(buffer)
            buffer = fresh
            state["base"] = state["first"]
            state["zeroed"] = filled

        def advance(new_first: int):
            """Frames [first, new_first) are complete: they leave once EMIT_FRAMES of them wait (a
            batch per few frames, not per input batch: building an Arrow batch costs as much as
            counting tens of thousands of events)."""
            first, base = state["first"], state["base"]
            if new_first <= first:
                return
            end = base + capacity
            state["first"] = min(new_first, end)
            if state["first"] - state["emitted"] >= EMIT_FRAMES or new_first > end:
                flush()
            if new_first > end:
                zeros(new_first - end)
                state["first"] = new_first
                rebase()

        def scan(t, x, y, p):
            offset = state["first"] - state["base"]
            counted(offset)  # windows skipped without an event are zero frames
            inside, saturated, before, late, beyond, k_max, zeroed = scan_into(
                t, x, y, p, state["start"], window, state["first"], buffer[offset:], max(0, state["zeroed"] - offset)
            )
            state["zeroed"] = max(state["zeroed"], offset + zeroed)
            report.framed += inside - saturated
            report.saturated_events += saturated
            report.before_start += before
            report.late += late
            return beyond, k_max

        for batch in _slices(batches, SCAN_EVENTS):
            if not batch.num_rows:
                continue
            t = batch.column("t").to_numpy(zero_copy_only=False).astype(np.int64, copy=False)
            x = batch.column("x").to_numpy(zero_copy_only=False)
            y = batch.column("y").to_numpy(zero_copy_only=False)
            p = batch.column("p").to_numpy(zero_copy_only=False)
            sch.check_events(t, x, y, p, sensor, sorted_time=False)
            if state["start"] is None:
                state["start"] = int(t[0])
            state["last_t"] = int(t[-1])
            report.events += len(t)
            if cap is not None:  # windows past --pad-to N are cut here, and counted
                past = (t - state["start"]) // window >= cap
                if past.any():
                    report.after_end += int(past.sum())
                    t, x, y, p = t[~past], x[~past], y[~past], p[~past]
            beyond, k_max = scan(t, x, y, p)
            while beyond:  # events past the buffer's end (once per buffer length): move on and count them
                windows = (t - state["start"]) // window
                rest = windows >= state["base"] + capacity
                t, x, y, p = t[rest], x[rest], y[rest], p[rest]
                advance(int(windows[rest].min()) - 1)
                if state["first"] != state["base"]:
                    rebase()
                beyond, k_max = scan(t, x, y, p)
            # frames before the latest event's window, less one window of slack, are complete
            if k_max - 1 > state["first"]:
                advance(k_max - 1)
            yield from ready
            ready.clear()

        if state["start"] is None:
            raise NeurotacError("input events table is empty: nothing to frame")
        # tonic's convention for a stream: window k is complete when it ends at or before the last
        # event's time; the partial window kept is the one holding the last event
        span = state["last_t"] - state["start"]
        n_real = 0 if span < 0 else span // window + (1 if framing.partial == "keep" else 0)
        n_total = n_real
        if cap is not None:
            n_total = cap
            n_real = min(n_real, cap)
        report.padded_frames = max(0, n_total - n_real)
        report.trials = 1
        first, base = state["first"], state["base"]
        keep_end = min(max(n_real - base, first - base), capacity)
        lost = int(buffer[keep_end:max(state["zeroed"], keep_end)].sum(dtype=np.int64))  # the partial window, when dropped
        counted(keep_end)
        emit(buffer[state["emitted"] - base:keep_end])  # the completed frames still waiting, and the last ones
        report.framed -= lost
        report.after_end += lost
        zeros(n_total - state["emitted"])
        yield from ready
        ready.clear()
        if held:
            peaks = np.zeros(2, dtype=np.int64)
            for _, frames, _ in held:
                peaks = np.maximum(peaks, frames.max(axis=(0, 2, 3)))
            scale = [float(max(peak, 1)) for peak in peaks]
            report.scale = scale
            for first, frames, phase in held:
                yield _frames_batch(out_schema, framing.trial, frames, None, phase, {}, (), window, scale, first_frame=first)

    return out_schema, generate()


def _slices(batches, size: int):
    for batch in batches:
        if batch.num_rows <= size:
            yield batch
        else:
            for offset in range(0, batch.num_rows, size):
                yield batch.slice(offset, size)


def frames_from_events_table(table: pa.Table, window_us: int, report: FramingReport | None = None, **options) -> pa.Table:
    """Frame a whole `events` table (tests and notebooks); the command streams with frame_events."""
    framing = Framing(window_us=window_us, **options)
    report = report if report is not None else FramingReport()
    schema, batches = frame_events(table.schema, table.to_batches(max_chunksize=1 << 16), framing, report)
    return pa.Table.from_batches(list(batches), schema=schema)
