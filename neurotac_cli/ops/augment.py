"""Chapter-5 augmentations of event frames (thesis 5.3): rotation, resize, background noise, frame
shifting (FS) and temporal event shifting (TES), applied to whole trials.

A trial is one (frames, 2, H, W) array of counts in frame order. Every transform is a small frozen
dataclass holding its settings (checked when it is built), called with a trial's counts and an
explicit `np.random.Generator`; it returns the new counts, the label of what it did and what it
counted. `augment_frames` applies transforms to every trial of a `frames` table and writes the
copies beside the originals with unique trial ids and `source_trial` / `augment` columns.

Conventions (docs/design.md, "augment"):
- Shifts move content J frames later for J > 0 and earlier for J < 0; labels stay in place. What is
  pushed past the first or last frame leaves the sequence and is counted.
- Rotation and resize sample the input bilinearly about the trial's contact centre (the
  count-weighted centroid of all its frames, both channels), zeros outside the frame. Integer
  counts stay integer by seeded systematic rounding, which keeps each pixel unbiased and each
  frame/channel total exact where a total is asked for.
"""

from __future__ import annotations

import dataclasses
import zlib

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, SchemaError, UsageError
from neurotac_cli.units import is_whole

COMBINES = ("independent", "hybrid")
# Hybrid copies compose methods in this order: geometry first, then timing, and the sensor's
# background noise last (it belongs to the camera, not to the grasp, so it is neither rotated nor shifted).
ORDER = ("rotate", "resize", "fs", "tes", "noise")


# ---------------------------------------------------------------- spatial: rotation and resize


def contact_centre(counts: np.ndarray) -> tuple[float, float]:
    """(y, x) of the count-weighted centroid of all frames and both channels of a trial.

    A trial without events has its centre in the middle of the frame.
    """
    image = counts.sum(axis=(0, 1), dtype=np.float64)
    height, width = image.shape
    total = image.sum()
    if total <= 0:
        return (height - 1) / 2, (width - 1) / 2
    y = float(image.sum(axis=1) @ np.arange(height)) / total
    x = float(image.sum(axis=0) @ np.arange(width)) / total
    return y, x


def sampling_operator(shape: tuple[int, int], matrix: np.ndarray, centre: tuple[float, float]):
    """Bilinear sampling as a sparse (P, P) matrix, P = H*W: output pixel q reads the input at
    `centre + matrix @ (q - centre)` in (y, x), with zeros outside the frame.

    Applying it to all frames and channels of a trial is one sparse-dense product. Source
    coordinates within 1e-9 of a pixel are snapped to it, so a transform that maps pixels onto
    pixels copies their values exactly.
    """
    from scipy import sparse

    height, width = shape
    cy, cx = centre
    yy, xx = np.mgrid[0:height, 0:width]
    dy = yy.ravel() - cy
    dx = xx.ravel() - cx
    sy = _snap(cy + matrix[0, 0] * dy + matrix[0, 1] * dx)
    sx = _snap(cx + matrix[1, 0] * dy + matrix[1, 1] * dx)
    y0 = np.floor(sy)
    x0 = np.floor(sx)
    fy = sy - y0
    fx = sx - x0
    y0 = y0.astype(np.int64)
    x0 = x0.astype(np.int64)
    target = np.arange(height * width)
    rows, cols, weights = [], [], []
    for oy, ox, weight in (
        (0, 0, (1 - fy) * (1 - fx)),
        (0, 1, (1 - fy) * fx),
        (1, 0, fy * (1 - fx)),
        (1, 1, fy * fx),
    ):
        ys, xs = y0 + oy, x0 + ox
        keep = (weight > 0) & (ys >= 0) & (ys < height) & (xs >= 0) & (xs < width)
        rows.append(target[keep])
        cols.append(ys[keep] * width + xs[keep])
        weights.append(weight[keep])
    size = height * width
    return sparse.csr_matrix(
        (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(size, size)
    )


def _snap(coordinates: np.ndarray) -> np.ndarray:
    nearest = np.rint(coordinates)
    close = np.abs(coordinates - nearest) < 1e-9
    coordinates[close] = nearest[close]
    return coordinates


def rotation_matrix(degrees: float) -> np.ndarray:
    """The backward map of thesis eq. 5.2 in (y, x): output offset -> input offset.

    Eq. 5.2 rotates (x, y) by the standard matrix; in image coordinates (y down) a positive angle
    turns the picture clockwise on screen.
    """
    phi = np.deg2rad(degrees)
    cos, sin = np.cos(phi), np.sin(phi)
    # Output offset (y', x') reads the input at R(-phi) applied to it: y = cos y' - sin x', x = sin y' + cos x'.
    return np.array([[cos, -sin], [sin, cos]])


def systematic_round(values: np.ndarray, rng: np.random.Generator, totals: np.ndarray | None = None, axis: int = 1) -> np.ndarray:
    """Round non-negative `values` to integers, seeded, group by group along `axis` (a group is
    one row of a (groups, P) array with axis=1, one column of a (P, groups) array with axis=0).

    Per group: r_i = floor(S_i + u) - floor(S_{i-1} + u), S the running sum, u ~ U[0, 1) per group.
    Every r_i is floor(v_i) or ceil(v_i) with mean v_i (unbiased), the group total is its float
    total rounded the same way, and with `totals` (integers, one per group) the group sums to
    exactly that total. Integer-valued input comes back unchanged.
    """
    groups = values.shape[1 - axis]
    shape = (1, groups) if axis == 0 else (groups, 1)
    running = np.cumsum(values, axis=axis, dtype=np.float64)  # a new array: `values` is left alone
    last = (slice(-1, None), slice(None)) if axis == 0 else (slice(None), slice(-1, None))
    if totals is not None:
        totals = np.asarray(totals, dtype=np.float64).reshape(shape)
        np.minimum(running, totals, out=running)
        running[last] = totals
    # Keep u clear of 1 so that S + u never rounds up to the next integer in float64.
    offset = rng.random(shape) * (1 - 2.0**-20)
    running += offset
    np.floor(running, out=running)
    steps = np.empty_like(running)
    if axis == 0:
        steps[0] = running[0]
        np.subtract(running[1:], running[:-1], out=steps[1:])
    else:
        steps[:, 0] = running[:, 0]
        np.subtract(running[:, 1:], running[:, :-1], out=steps[:, 1:])
    return steps


def warp(counts: np.ndarray, matrix: np.ndarray, rng: np.random.Generator, preserve_total: bool = False):
    """Resample every frame and channel of a trial through `matrix` about its contact centre.

    Returns (new counts of the same dtype, events lost past the frame edges, events added by
    rescaling). Integer counts are rounded with `systematic_round`; with `preserve_total` each
    frame and channel is rescaled to its own original total first (exact for integers).
    """
    frames, channels, height, width = counts.shape
    operator = sampling_operator((height, width), matrix, contact_centre(counts))
    # (P, groups) layout: one sparse product for all frames and channels, running sums down columns.
    pixels_by_group = np.ascontiguousarray(counts.reshape(frames * channels, height * width).T, dtype=np.float64)
    values = operator @ pixels_by_group
    before = pixels_by_group.sum(axis=0)
    targets = None
    if preserve_total:
        after = values.sum(axis=0)
        scale = np.divide(before, after, out=np.zeros_like(before), where=after > 0)
        values *= scale
        targets = np.where(after > 0, before, 0.0)
    if np.issubdtype(counts.dtype, np.integer):
        values = systematic_round(values, rng, targets, axis=0)
    change = float(values.sum() - before.sum())
    result = np.empty(counts.shape, dtype=counts.dtype)
    result.reshape(frames * channels, height * width)[:] = _as_dtype(values, counts.dtype).T
    return result, max(0.0, -change), max(0.0, change)


# ---------------------------------------------------------------- temporal: FS and TES


def frame_shift(counts: np.ndarray, shift: int) -> np.ndarray:
    """Thesis eq. 5.3 with DESIGN.md's sign: content moves `shift` frames later (earlier if < 0);
    the vacated frames are zero; frames pushed past either end are dropped."""
    shifted = np.zeros_like(counts)
    frames = len(counts)
    if abs(shift) >= frames:
        return shifted
    if shift >= 0:
        shifted[shift:] = counts[: frames - shift]
    else:
        shifted[:shift] = counts[-shift:]
    return shifted


def events_to_move(counts: np.ndarray, zeta: float) -> np.ndarray:
    """round(zeta * n) for the n events of each frame and channel: (frames, 2) int64.

    round() is Python's: halves go to the even integer (0.5 * 3 events -> 2, 0.5 * 5 -> 2).
    """
    totals = counts.sum(axis=(2, 3), dtype=np.int64)
    return np.rint(zeta * totals).astype(np.int64)


DRAW_AT_ONCE = 1 << 25  # events drawn as one array (about 1.3 GB of working arrays); more are drawn group by group
EXACT_DRAW_MOST = 10**9  # numpy's hypergeometric draws stay exact below this many events


def draw_events(counts: np.ndarray, take: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draw `take[g]` of the events of each group g without replacement (multivariate hypergeometric).

    `counts` is (groups, P) of non-negative integers. Up to DRAW_AT_ONCE events, all groups are drawn
    at once: the events of all groups are shuffled together, stably sorted back into their groups (a
    radix sort on the group number), and the first `take[g]` of each group are kept, so every subset
    of the right size is equally likely. Beyond it, each group is drawn by numpy's multivariate
    hypergeometric sampler, the same law without an array of the events. Returns the drawn counts,
    (groups, P) int64.
    """
    groups, pixels = counts.shape
    flat = counts.ravel()
    if int(flat.sum(dtype=np.int64)) > DRAW_AT_ONCE:
        # more events than one array of them fits in memory: each group drawn from its pixels' counts
        rows = counts.astype(np.int64)
        if rows.sum(axis=1).max(initial=0) >= EXACT_DRAW_MOST:
            raise NeurotacError(f"a frame holds {int(rows.sum(axis=1).max()):,} events in one channel, beyond the "
                                f"{EXACT_DRAW_MOST:,} TES draws from exactly (saturated counts?)")
        return np.stack([rng.multivariate_hypergeometric(row, int(k), method="marginals") if k else np.zeros(pixels, np.int64)
                         for row, k in zip(rows, take)])
    entries = np.flatnonzero(flat)
    event_pixel = np.repeat(entries, flat[entries].astype(np.int64))
    if len(event_pixel) == 0:
        return np.zeros((groups, pixels), dtype=np.int64)
    event_group = event_pixel // pixels
    shuffled = rng.permutation(len(event_pixel))
    group_key = event_group[shuffled]
    if groups <= np.iinfo(np.uint16).max:
        group_key = group_key.astype(np.uint16)  # numpy sorts 16-bit keys stably by radix, in linear time
    in_groups = shuffled[np.argsort(group_key, kind="stable")]
    sizes = np.bincount(event_group, minlength=groups)
    rank = np.arange(len(event_pixel)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    chosen = event_pixel[in_groups[rank < np.repeat(np.asarray(take, dtype=np.int64), sizes)]]
    return np.bincount(chosen, minlength=groups * pixels).reshape(groups, pixels)


def temporal_event_shift(counts: np.ndarray, shift: int, zeta: float, rng: np.random.Generator):
    """Thesis eqs. 5.4-5.6: X'_t = X_t - Z_t + Z_{t-J}, Z_t drawn from X_t without replacement with
    exactly round(zeta * n) events per frame and channel, moved to the same pixel `shift` frames
    later (earlier if < 0).

    Returns (new counts, events moved, events pushed past the first or last frame, which leave the
    sequence, as frames do under FS).
    """
    frames, channels, height, width = counts.shape
    if np.issubdtype(counts.dtype, np.floating) and not np.array_equal(counts, np.floor(counts)):
        raise SchemaError("TES moves events, so it needs whole-number counts; apply it before any normalisation")
    whole = counts.astype(np.int64)
    take = events_to_move(whole, zeta)
    drawn = draw_events(whole.reshape(frames * channels, -1), take.ravel(), rng).reshape(whole.shape)
    arrived = frame_shift(drawn, shift)
    moved = int(take.sum())
    lost = moved - int(arrived.sum())
    return _as_dtype(whole - drawn + arrived, counts.dtype), moved, lost


# ---------------------------------------------------------------- noise


def noise_pool(noise: pa.Table, like: pa.Schema) -> list[np.ndarray]:
    """The background-noise trials of a frames table, as (frames, 2, H, W) arrays in frame order,
    after checking that they were framed with the same window and frame size as `like`."""
    shape, noise_shape = sch.frames_shape(like), sch.frames_shape(noise.schema)
    if shape != noise_shape:
        raise SchemaError(
            f"noise frames are {noise_shape[1]}x{noise_shape[0]} but the frames to augment are {shape[1]}x{shape[0]} "
            "(frame and crop the still recording exactly as the data: same --window, --size and --pool)"
        )
    window, noise_window = sch.get_meta(like, sch.WINDOW), sch.get_meta(noise.schema, sch.WINDOW)
    if window != noise_window:
        raise SchemaError(
            f"noise frames have a {_window(noise_window)} window but the frames to augment have {_window(window)} "
            "(frame the still recording with the same --window)"
        )
    if noise.num_rows == 0:
        raise SchemaError("the noise table has no frames (frame a still recording with `neurotac frame`)")
    # counts added to counts pooled or scaled otherwise (`frame --dtype`) would swamp them or vanish
    unlike = sch.made_unlike("the table to augment", like, "the noise table", noise.schema)
    if unlike:
        raise SchemaError(f"{unlike}; frame both alike (frame and crop the still recording exactly as the data)")
    counts = sch.counts_numpy(noise["counts"])
    trials, order = _trial_order(noise)
    return [counts[rows] for rows in np.split(order, np.flatnonzero(np.diff(trials[order])) + 1)]


def _window(window_us) -> str:
    return "unknown" if window_us is None else f"{window_us} µs"


def add_noise(counts: np.ndarray, pool: list[np.ndarray], rng: np.random.Generator):
    """Add background-noise frames: a noise trial drawn at random, read from a random start frame for
    as many frames as the trial has (wrapping round to its first frame if it is shorter).

    Returns (new counts, noise events added, (noise trial index, start frame)).
    """
    which = int(rng.integers(len(pool)))
    source = pool[which]
    start = int(rng.integers(len(source)))
    noise = source[(start + np.arange(len(counts))) % len(source)]
    if noise.shape[1:] != counts.shape[1:]:
        raise SchemaError(f"noise frames are {noise.shape[3]}x{noise.shape[2]} but the frames to augment are "
                          f"{counts.shape[3]}x{counts.shape[2]} (frame and crop the still recording exactly as the data)")
    if np.issubdtype(counts.dtype, np.integer):
        if not np.issubdtype(noise.dtype, np.integer) and not np.array_equal(noise, np.floor(noise)):
            raise SchemaError("noise counts are fractional but the frames hold whole counts; frame both alike")
        total = counts.astype(np.int64) + noise.astype(np.int64)
    else:
        total = counts.astype(np.float64) + noise
    return _as_dtype(total, counts.dtype), float(noise.sum(dtype=np.float64)), (which, start)


# ---------------------------------------------------------------- the methods


def check_changes(unchanged: list[str], methods: int, combine: str) -> None:
    """Refuse methods (named in `unchanged`) whose copies would equal their sources; in a hybrid, the
    other methods change the copies."""
    if unchanged and not (combine == "hybrid" and methods > len(unchanged)):
        raise UsageError(f"{unchanged[0]} changes nothing: its copies would equal the trials they come from")


@dataclasses.dataclass(frozen=True)
class Rotate:
    """Rotate every frame of a trial by one angle about its contact centre; a range draws the angle per trial."""

    low: float
    high: float | None = None
    preserve_total: bool = False
    name = "rotate"

    def __post_init__(self):
        if not all(_finite(v) for v in (self.low, self.high) if v is not None):
            raise UsageError(f"rotation angles must be finite numbers of degrees, got {self.low!r}, {self.high!r}")
        if self.high is not None and self.high < self.low:
            raise UsageError(f"rotation range {self.low:g}..{self.high:g} is empty (give the smaller angle first)")

    @property
    def unchanged(self) -> bool:
        return (self.high is None or self.high == self.low) and self.low % 360 == 0

    def __call__(self, counts, rng):
        angle = self.low if self.high is None else float(rng.uniform(self.low, self.high))
        label = f"rotate({_number(angle)})"
        if angle % 360 == 0:
            return counts.copy(), label, {}
        result, lost, gained = warp(counts, rotation_matrix(angle), rng, self.preserve_total)
        return result, label, {"events_lost": lost, "events_added": gained}


@dataclasses.dataclass(frozen=True)
class Resize:
    """Scale every frame about the contact centre by beta (> 1 larger), bilinear, zero margin."""

    beta: float
    preserve_total: bool = False
    name = "resize"

    def __post_init__(self):
        if not (_finite(self.beta) and self.beta > 0):
            raise UsageError(f"resize factor must be a finite number above 0, got {self.beta!r} (the thesis uses 1.25 and 0.83)")

    @property
    def unchanged(self) -> bool:
        return self.beta == 1

    def __call__(self, counts, rng):
        label = f"resize({_number(self.beta)})"
        if self.beta == 1:
            return counts.copy(), label, {}
        result, lost, gained = warp(counts, np.eye(2) / self.beta, rng, self.preserve_total)
        return result, label, {"events_lost": lost, "events_added": gained}


@dataclasses.dataclass(frozen=True)
class FrameShift:
    """FS: move all frames `shift` frames later (earlier if negative), zero fill, labels stay."""

    shift: int
    name = "fs"

    def __post_init__(self):
        _check_shift(self.shift, "FS")

    @property
    def unchanged(self) -> bool:
        return self.shift == 0

    def __call__(self, counts, rng):
        result = frame_shift(counts, self.shift)
        lost = float(counts.sum(dtype=np.float64) - result.sum(dtype=np.float64))
        return result, f"fs({self.shift})", {"events_lost": lost}


@dataclasses.dataclass(frozen=True)
class EventShift:
    """TES: move round(zeta * n) random events of each frame and channel `shift` frames later."""

    shift: int
    zeta: float
    name = "tes"

    def __post_init__(self):
        _check_shift(self.shift, "TES")
        if not (_finite(self.zeta) and 0 <= self.zeta <= 1):
            raise UsageError(f"TES fraction must lie in [0, 1], got {self.zeta!r} (the thesis uses 0.25, 0.5, 0.75)")

    @property
    def unchanged(self) -> bool:
        return self.shift == 0 or self.zeta == 0

    def __call__(self, counts, rng):
        result, moved, lost = temporal_event_shift(counts, self.shift, self.zeta, rng)
        return result, f"tes({self.shift},{_number(self.zeta)})", {"events_moved": moved, "events_lost": lost}


@dataclasses.dataclass(frozen=True, eq=False)
class Noise:
    """Add background-noise frames from a still recording, drawn at random per trial."""

    pool: tuple
    name = "noise"

    def __post_init__(self):
        given = "a tuple of noise trials, each a (frames, 2, H, W) array of counts (`api.counts(still, trial)`)"
        if not isinstance(self.pool, (tuple, list)):
            raise UsageError(f"Noise takes {given}, got {type(self.pool).__name__}")
        for trial in self.pool:
            counts = np.asarray(trial)
            if counts.ndim != 4 or counts.shape[1] != 2 or not np.issubdtype(counts.dtype, np.number):
                raise UsageError(f"Noise takes {given}, got an array of shape {counts.shape} and type {counts.dtype}")
            if counts.size and not (np.isfinite(counts).all() and counts.min() >= 0):  # a negative count wraps round in uint16
                raise UsageError("Noise's counts must be finite and not negative")
        if not self.pool or any(len(trial) == 0 for trial in self.pool):
            raise NeurotacError("the noise table has no frames (frame a still recording with `neurotac frame`)")

    def __call__(self, counts, rng):
        result, added, _ = add_noise(counts, list(self.pool), rng)
        return result, "noise", {"events_added": added}


def _finite(value) -> bool:
    """Whether `value` is a real number that is neither NaN nor infinite (a library caller may pass anything)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool) and bool(np.isfinite(value))


def _check_shift(shift, name: str) -> None:
    if not is_whole(shift):
        raise UsageError(f"{name} shift must be a whole number of frames, got {shift!r}")


def _number(value: float) -> str:
    value = float(value)
    # two decimals name an angle or a factor; a factor under 0.005 keeps its own digits, not "0"
    return f"{round(value, 2):g}" if value == 0 or abs(value) >= 0.005 else f"{value:.3g}"


# ---------------------------------------------------------------- frames tables


def augment_frames(
    frames: pa.Table,
    methods: list,
    copies: int = 1,
    combine: str = "independent",
    keep_original: bool = True,
    seed: int = 0,
    where: list[tuple[str, str]] | None = None,
) -> tuple[pa.Table, dict]:
    """Augment every trial of a `frames` table; returns (table, counts of what was done per method).

    independent: each method makes `copies` copies of every trial from the original.
    hybrid: `copies` copies per trial, each with all methods composed in the order of ORDER.
    Every copy keeps the rows' labels, force, phase, frame and t, and gets the id
    `<trial>~<what was done>#<copy>`, `source_trial` (the original trial) and `augment` (what was done).
    The draws of a trial's copy depend only on (seed, trial id, method, copy number).
    `where` = [(column, value), ...]: augment only the trials whose column holds one of these
    values (thesis 5.5 resizes small objects by 1.25 and large ones by 0.83); the others pass unchanged.
    """
    _check_request(methods, combine, copies, seed)
    methods = sorted(methods, key=lambda method: ORDER.index(method.name))
    counts = sch.counts_numpy(frames["counts"])
    trials, order = _trial_order(frames)
    bounds = np.flatnonzero(np.diff(trials[order])) + 1
    trial_ids = frames["trial"].to_numpy(zero_copy_only=False)
    source_ids = _column_or(frames, "source_trial", trial_ids)
    done_before = _column_or(frames, "augment", np.full(frames.num_rows, "", dtype=object))
    if any(method.name in ("fs", "tes") for method in methods):
        _check_consecutive(frames["frame"].to_numpy(), order, bounds, trial_ids)
    chosen = _chosen_rows(frames, where)
    plans = [[method] for method in methods] if combine == "independent" else [methods]
    stats = {}
    out = _Pieces(counts, (int(keep_original) + len(plans) * copies) * len(counts))
    seen = set(trial_ids.tolist())
    for trial_rows in np.split(order, bounds):
        first, trial_counts = trial_rows[0], counts[trial_rows]
        if keep_original:
            out.add(trial_rows, trial_counts, trial_ids[trial_rows], source_ids[trial_rows], done_before[trial_rows])
        for plan in plans if chosen[first] else ():
            for copy in range(1, copies + 1):
                result, done = _run_plan(plan, trial_counts, trial_ids[first], copy, seed, combine, stats)
                new_id = _unused_id(f"{trial_ids[first]}~{done}", seen)
                earlier, count = done_before[first], len(trial_rows)
                out.add(trial_rows, result, np.full(count, new_id, dtype=object),
                        np.full(count, source_ids[first], dtype=object),
                        np.full(count, f"{earlier}+{done}" if earlier else done, dtype=object))
    stats = {method: {name: int(round(value)) for name, value in entry.items()} for method, entry in stats.items()}
    return _assemble(frames, out.rows, out.counts[: out.filled], out.ids, out.sources, out.augment), stats


def _check_request(methods, combine: str, copies: int, seed: int) -> None:
    if combine not in COMBINES:
        raise UsageError(f"unknown combination {combine!r} (use independent or hybrid)")
    if not methods:
        raise UsageError("no augmentation asked for (give --rotate, --resize, --noise, --fs or --tes)")
    if copies < 1:
        raise UsageError(f"--copies must be at least 1, got {copies}")
    if seed < 0:
        raise UsageError(f"--seed must be zero or positive, got {seed}")


def _run_plan(plan, counts, trial: str, copy: int, seed: int, combine: str, stats: dict):
    """One copy of a trial's counts through every method of `plan`: (counts, `what#copy`); `stats` counts."""
    result, labels = counts, []
    for method in plan:
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=_key(trial, method.name, copy, combine)))
        entry = stats.setdefault(method.name, {"copies": 0, "events_in": 0})
        entry["copies"] += 1
        entry["events_in"] += float(result.sum(dtype=np.float64))
        result, label, counted = method(result, rng)
        labels.append(label)
        for name, value in counted.items():
            entry[name] = entry.get(name, 0) + value
    return result, f"{'+'.join(labels)}#{copy}"


def _unused_id(new_id: str, seen: set) -> str:
    if new_id in seen:
        raise NeurotacError(
            f"augmented trial id {new_id!r} is already taken (the input holds that copy already; "
            "augment the original trials, or use another method or --copies)"
        )
    seen.add(new_id)
    return new_id


class _Pieces:
    """The output trials as they are made: source rows, counts (into one array sized for the most
    rows there can be), trial ids, source trials and what was done."""

    def __init__(self, counts: np.ndarray, capacity: int):
        self.counts = np.empty((capacity, *counts.shape[1:]), dtype=counts.dtype)
        self.filled = 0
        self.rows, self.ids, self.sources, self.augment = [], [], [], []

    def add(self, rows, counts, ids, sources, augment):
        self.rows.append(rows)
        self.counts[self.filled : self.filled + len(rows)] = counts
        self.filled += len(rows)
        self.ids.append(ids)
        self.sources.append(sources)
        self.augment.append(augment)


def _key(trial: str, method: str, copy: int, combine: str) -> tuple[int, int, int]:
    return (zlib.crc32(trial.encode()), zlib.crc32(f"{combine}:{method}".encode()), copy)


def _trial_order(frames: pa.Table) -> tuple[np.ndarray, np.ndarray]:
    """(trial index per row in order of first appearance, rows sorted by trial then frame)."""
    encoded = frames["trial"].combine_chunks().dictionary_encode()
    indices = encoded.indices.to_numpy(zero_copy_only=False)
    first_seen = np.full(len(encoded.dictionary), len(indices), dtype=np.int64)
    np.minimum.at(first_seen, indices, np.arange(len(indices)))
    rank = np.argsort(np.argsort(first_seen))
    trials = rank[indices]
    order = np.lexsort((frames["frame"].to_numpy(), trials))
    return trials, order


def _chosen_rows(frames: pa.Table, where) -> np.ndarray:
    """True for the rows of the trials to augment: all, or those matching any (column, value) of `where`."""
    if not where:
        return np.ones(frames.num_rows, dtype=bool)
    chosen = np.zeros(frames.num_rows, dtype=bool)
    for name, value in where:
        if name not in frames.column_names:
            labels = ", ".join(sch.label_columns(frames.schema)) or "none"
            raise SchemaError(f"cannot select trials by {name!r}: no such column (labels: {labels})")
        chosen |= np.array([str(v) == value for v in frames[name].to_pylist()], dtype=bool)
    if not chosen.any():
        raise NeurotacError(
            "no trial matches " + " or ".join(f"{name}={value}" for name, value in where) + " (check the label values with `neurotac info`)"
        )
    return chosen


def _column_or(frames: pa.Table, name: str, default: np.ndarray) -> np.ndarray:
    if name not in frames.column_names:
        return np.asarray(default, dtype=object)
    values = frames[name].to_numpy(zero_copy_only=False).astype(object)
    missing = np.array([value is None for value in values])
    values[missing] = np.asarray(default, dtype=object)[missing]
    return values


def _check_consecutive(frame_numbers, order, bounds, trial_ids):
    steps = np.diff(frame_numbers[order])
    inside = np.ones(len(steps), dtype=bool)
    inside[bounds - 1] = False
    bad = np.flatnonzero(inside & (steps != 1))
    if len(bad):
        row = order[bad[0]]
        raise SchemaError(
            f"frames of trial {trial_ids[row]!r} are not consecutive (frame {frame_numbers[row]} is followed by "
            f"{frame_numbers[order[bad[0] + 1]]}); shift whole trials, before selecting frames"
        )


def _assemble(frames, rows, counts, new_ids, new_sources, new_augment) -> pa.Table:
    counts_field = frames.schema.get_field_index("counts")
    taken = frames.remove_column(counts_field).take(pa.array(np.concatenate(rows)))
    taken = taken.add_column(counts_field, "counts", sch.counts_array(counts))
    columns = {
        "trial": pa.array(np.concatenate(new_ids), pa.string()),
        "source_trial": pa.array(np.concatenate(new_sources), pa.string()),
        "augment": pa.array(np.concatenate(new_augment), pa.string()),
    }
    for name, column in columns.items():
        index = taken.schema.get_field_index(name)
        if index < 0:
            taken = taken.append_column(pa.field(name, column.type), column)
        else:
            taken = taken.set_column(index, pa.field(name, column.type), column)
    return taken.replace_schema_metadata(frames.schema.metadata)


def _as_dtype(values: np.ndarray, dtype) -> np.ndarray:
    dtype = np.dtype(dtype)
    if np.issubdtype(dtype, np.integer):
        top = np.iinfo(dtype).max
        if values.size and values.max() > top:
            raise SchemaError(
                f"augmented counts reach {int(values.max())}, more than {dtype} holds ({top}); "
                "frame with a shorter window or pool less"
            )
        return values.astype(dtype)  # callers hand over whole numbers (rounded or integer arithmetic)
    return values.astype(dtype)


# ---------------------------------------------------------------- the command's request

LOSS_WARNING = 0.05  # warn when a method pushes out more than this share of its input events


@dataclasses.dataclass(frozen=True)
class Augmentation:
    """What `neurotac augment` asks for: the methods' settings and how copies are made."""

    rotate: float | None = None
    rotate_range: tuple | None = None
    resize: float | None = None
    preserve_total: bool = False
    fs: int | None = None
    tes: tuple | None = None
    combine: str = "independent"
    copies: int = 1
    where: tuple = ()
    keep_original: bool = True
    seed: int = 0
    noise: str | None = None  # the background-noise file the command reads (see `augment`)

    def __post_init__(self):
        if all(value is None for value in (self.rotate, self.rotate_range, self.resize, self.fs, self.tes, self.noise)):
            raise UsageError("give at least one of --rotate, --rotate-range, --resize, --noise, --fs, --tes")
        if self.rotate is not None and self.rotate_range:
            raise UsageError("give --rotate or --rotate-range, not both")
        if self.rotate_range and self.rotate_range[1] < self.rotate_range[0]:
            raise UsageError(f"--rotate-range {self.rotate_range[0]:g} {self.rotate_range[1]:g} is empty; give the smaller angle first")

    def methods(self, noise_frames: tuple | None = None) -> list:
        """The transforms asked for; `noise_frames` (see `noise_pool`) adds background noise."""
        chosen = [
            Rotate(self.rotate, preserve_total=self.preserve_total) if self.rotate is not None else None,
            Rotate(*self.rotate_range, preserve_total=self.preserve_total) if self.rotate_range else None,
            Resize(self.resize, preserve_total=self.preserve_total) if self.resize is not None else None,
            FrameShift(self.fs) if self.fs is not None else None,
            EventShift(*self.tes) if self.tes is not None else None,
            Noise(tuple(noise_frames)) if noise_frames is not None else None,
        ]
        return [method for method in chosen if method is not None]


def augment(frames: pa.Table, request: Augmentation, noise: pa.Table | None = None) -> tuple[pa.Table, dict, list]:
    """`neurotac augment`: (augmented frames, what each method counted, warnings for stderr).
    `noise`: a frames table of a still recording, framed and cropped like `frames`."""
    pool = tuple(noise_pool(noise, frames.schema)) if noise is not None else None
    methods = request.methods(pool)
    table, counted = augment_frames(frames, methods, copies=request.copies, combine=request.combine,
                                    keep_original=request.keep_original, seed=request.seed, where=list(request.where))
    idle = [name for name, entry in counted.items() if name == "tes" and entry["events_in"] and not entry.get("events_moved")]
    said = [f"--tes {request.tes[0]} {request.tes[1]:g} moved no event: ZETA times each frame's count rounds to none" for _ in idle]
    if said and (request.combine != "hybrid" or len(methods) == 1):  # copies equal to their trials, as --tes J 0's
        raise NeurotacError(f"{said[0]}, so its copies would equal the trials they come from; give a larger ZETA")
    return table, counted, loss_warnings(counted) + [f"{line} (the other methods changed the copies)" for line in said]


def loss_warnings(counted: dict) -> list[str]:
    """Warnings for the methods that pushed more than LOSS_WARNING of their events out of the frames
    (`counted`: what `augment_frames` counted per method)."""
    return [f"{name} pushed {entry.get('events_lost', 0)} of {entry['events_in']} events out of the frames"
            for name, entry in counted.items()
            if entry["events_in"] and entry.get("events_lost", 0) > LOSS_WARNING * entry["events_in"]]
