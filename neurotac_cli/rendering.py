"""Pictures of tables, for a person: what the camera saw, what `frame`, `crop` and `augment` made of it.

Views (one trial at a time):
- `montage`: tiles over time. Events and recordings are cut into equal time slices (counted as
  `frame` counts them); frames are shown as they are. Under the tiles, the force trace (the force
  log of a recordings table, the per-frame force of a frames table) with the phases shaded.
- `crop`: the counts accumulated over the trial with the crop box drawn on them (the box `crop`
  would cut, found the same way: given, or centred on the contact area of the whole input).
- `augmented`: an augmented copy (a trial with `source_trial`) under its source, frame by frame.

Colours: ON counts red, OFF counts blue, on white; both on a square-root scale from 0 to the
99.5th percentile of the trial's non-zero counts (a few hot pixels do not wash the rest out), with
a colour bar per channel in events per pixel. PNG is one figure; GIF and MP4 are one picture per
tile, played at --fps. matplotlib, Pillow and imageio-ffmpeg are imported only here.
"""

import itertools
import numbers
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, SchemaError, UsageError
from neurotac_cli.units import counted, is_whole

FORMATS = {".png": "png", ".gif": "gif", ".mp4": "mp4"}
VIEWS = ("montage", "crop", "augmented")
MAX_SLICES, MAX_COLUMNS, FPS = 1000, 60, (0.1, 120.0)  # `render`'s option ranges
PHASE_COLOURS = {"grasping": "#f4c27a", "holding": "#9fd3a0", "releasing": "#a8c3e8"}
DPI = 100
MAX_TILES = 60


@dataclass(frozen=True)
class RenderSpec:
    """What to draw. Validated when built."""

    view: str = "montage"
    trial: str | None = None
    slices: int = 8
    slice_us: int | None = None
    columns: int = 8
    every: int = 1
    fps: float = 10.0
    crop: object = None  # an ops.crop.CropSpec for the crop view

    def __post_init__(self):
        if self.view not in VIEWS:
            raise NeurotacError(f"unknown view {self.view!r} (use {', '.join(VIEWS)})")
        # the command line's ranges (its click types), checked here too for the library, which passes anything
        for name, least, most in (("slices", 1, MAX_SLICES), ("columns", 1, MAX_COLUMNS), ("every", 1, None)):
            value = getattr(self, name)
            if not is_whole(value) or value < least or (most is not None and value > most):
                within = f"from {least} to {most}" if most else f"{least} or more"
                raise UsageError(f"--{name} must be a whole number {within}, got {value!r}")
        if isinstance(self.fps, bool) or not isinstance(self.fps, numbers.Real) or not FPS[0] <= self.fps <= FPS[1]:
            raise UsageError(f"--fps must be a number from {FPS[0]:g} to {FPS[1]:g}, got {self.fps!r}")
        if self.slice_us is not None and (not is_whole(self.slice_us) or self.slice_us <= 0):
            raise UsageError(f"--slice must be a positive duration, got {self.slice_us!r} µs")


def check_options(path: str, view: str, given: set) -> None:
    """Refuse options that do nothing here, as the command line does (exit 2): `given` names those
    set by the caller (fps, box, size, center), not left at their defaults."""
    if output_format(path) == "png" and "fps" in given:
        raise UsageError("--fps sets the pace of a GIF or MP4; a PNG is one picture (write -o NAME.gif to animate)")
    boxed = [f"--{name}" for name in ("box", "size", "center") if name in given]
    if boxed and view != "crop":
        raise UsageError(f"{', '.join(boxed)} draw{'s' if len(boxed) == 1 else ''} a box with --view crop; "
                         f"--view {view} draws the whole frame")


def check_slicing(kind: str, given: set) -> None:
    """Refuse --slices and --slice (in `given`) for frames, which are drawn as they are."""
    sliced = [flag for flag, name in (("--slices", "slices"), ("--slice", "slice_us")) if name in given]
    if sliced and kind == "frames":
        raise UsageError(f"{' and '.join(sliced)} cut{'s' if len(sliced) == 1 else ''} events or recordings into time "
                         "slices; frames are drawn as they are (use --every to draw fewer)")


@dataclass
class Steps:
    """One trial as a stack of two-channel count images over time, with what goes under them."""

    trial: str
    counts: np.ndarray  # (n, 2, H, W)
    starts_ms: np.ndarray  # each image's start, ms from the trial's zero
    step_ms: float
    what: str  # "frame" or "slice"
    numbers: np.ndarray = None  # frame numbers (frames), or slice indices
    phase: list = field(default_factory=list)
    force_t_ms: np.ndarray | None = None
    force_n: np.ndarray | None = None

    def caption(self, k: int) -> str:
        if self.what == "frame":
            phase = self.phase[k] if self.phase and self.phase[k] else ""
            return f"frame {self.numbers[k]}" + (f": {phase}" if phase else "")
        digits = 1 if self.step_ms >= 0.1 else 3  # slices of a few µs: "0.0-0.0 ms" would name none apart
        return f"{self.starts_ms[k]:.{digits}f}-{self.starts_ms[k] + self.step_ms:.{digits}f} ms"


def output_format(path: str) -> str:
    import os

    suffix = os.path.splitext(path)[1].lower()
    if suffix not in FORMATS:
        raise UsageError(f"cannot tell the picture format of {path!r} from its suffix (use .png, .gif or .mp4)")
    return FORMATS[suffix]


# ---------------------------------------------------------------- data


def _trials(table: pa.Table) -> list[str]:
    """The trials, in order; an events table is one, named as `frame` names it (its camera file's stem)."""
    if "trial" in table.column_names:
        return list(dict.fromkeys(table.column("trial").to_pylist()))
    from neurotac_cli.io.camera import camera_file_stem

    return [camera_file_stem(table.schema) or "events"]


def pick_trial(table: pa.Table, trial: str | None) -> str:
    trials = _trials(table)
    if trial is None:
        return trials[0]
    if trial not in trials:
        shown = ", ".join(trials[:6]) + (", ..." if len(trials) > 6 else "")
        raise NeurotacError(f"no trial {trial!r} in the input (trials: {shown}; `neurotac info` lists them all)")
    return trial


def steps_of(table: pa.Table, trial: str, spec: RenderSpec) -> Steps:
    """The images of one trial: its frames, or equal time slices of its events."""
    kind = sch.table_kind(table.schema)
    if kind == "frames":
        return _frame_steps(table, trial)
    if kind == "recordings":
        _, (t, x, y, p), (force_t, force_n) = sch.trial_recording(table, trial)
        steps = _slice_steps(trial, t, x, y, p, _sensor(table.schema, x, y), spec)
        steps.force_t_ms = force_t / 1000.0
        steps.force_n = force_n.astype(float)
        return steps
    if kind == "events":
        t, x, y, p = (table.column(name).to_numpy() for name in ("t", "x", "y", "p"))
        return _slice_steps(trial, t - (t.min() if len(t) else 0), x, y, p, _sensor(table.schema, x, y), spec)  # from the first event
    raise SchemaError(f"render draws events, recordings or frames tables, got {kind or 'an unknown'} table"
                      " (predictions and metrics are drawn by `neurotac eval --plot`)")


def _sensor(schema: pa.Schema, x, y) -> tuple[int, int]:
    sensor = sch.sensor_of(schema)
    if sensor:
        return sensor
    return (int(x.max()) + 1, int(y.max()) + 1) if len(x) else (1, 1)


def _frame_steps(table: pa.Table, trial: str) -> Steps:
    rows = table.filter(pc.equal(table.column("trial"), trial))
    rows = rows.take(pc.sort_indices(rows.column("frame")))
    window_ms = (sch.get_meta(table.schema, sch.WINDOW) or 0) / 1000.0
    starts = rows.column("t").to_numpy() / 1000.0
    force = rows.column("force").to_numpy(zero_copy_only=False).astype(float)
    return Steps(trial=trial, counts=sch.counts_numpy(rows.column("counts")), starts_ms=starts, step_ms=window_ms,
                 what="frame", numbers=rows.column("frame").to_numpy(), phase=rows.column("phase").to_pylist(),
                 force_t_ms=starts + window_ms if np.isfinite(force).any() else None,
                 force_n=force if np.isfinite(force).any() else None)


MAX_SLICE_BYTES = 4e9  # the counts of every slice are made at once


def _slice_steps(trial, t, x, y, p, sensor, spec: RenderSpec) -> Steps:
    from neurotac_cli.ops.frame import count_frames

    if len(t) == 0:
        raise NeurotacError(f"trial {trial!r} has no events to draw")
    sch.check_events(t, x, y, p, sensor, where=f"trial {trial!r}", sorted_time=False)
    width, height = sensor
    first, last = int(t.min()), int(t.max())
    if spec.slice_us:
        window, n = spec.slice_us, (last - first) // spec.slice_us + 1
    else:
        n = min(spec.slices, last - first + 1)  # a span of a few µs holds no more slices of a whole µs
        window = max((last - first) // n + 1, 1)
    if n * 2 * height * width * 2 > MAX_SLICE_BYTES:  # a huge gap in the times, or a slice far too short for the span
        raise NeurotacError(f"trial {trial!r} spans {(last - first) / 1e6:,.3f} s: {n:,} slices of {window / 1000:g} ms would take "
                            f"{n * 4 * height * width / 1e9:,.0f} GB; give a longer --slice or select a shorter span")
    counts = count_frames(t.astype(np.int64), x, y, p, window, int(n), height, width, start=first)
    starts = (first + window * np.arange(n)) / 1000.0
    return Steps(trial=trial, counts=counts, starts_ms=starts, step_ms=window / 1000.0, what="slice", numbers=np.arange(n))


def shown_steps(steps: Steps, spec: RenderSpec, limit: int | None) -> tuple[list[int], int]:
    """(the steps drawn: every `spec.every`-th, at most `limit`; how many more --every picked that did not fit)."""
    shown = list(range(0, len(steps.counts), spec.every))
    return (shown[:limit], len(shown) - limit) if limit and len(shown) > limit else (shown, 0)


# ---------------------------------------------------------------- colour


def colour_top(counts: np.ndarray) -> float:
    """The count at which colours saturate: the 99.5th percentile of the non-zero counts (at least 1)."""
    nonzero = counts[counts > 0]
    return max(float(np.percentile(nonzero, 99.5)), 1.0) if nonzero.size else 1.0


def rgb(counts: np.ndarray, top: float) -> np.ndarray:
    """(2, H, W) OFF/ON counts -> (H, W, 3) floats: white background, ON red, OFF blue, both dark."""
    off = np.clip(np.sqrt(counts[0] / top), 0, 1)
    on = np.clip(np.sqrt(counts[1] / top), 0, 1)
    return np.stack([1 - off, 1 - off - on, 1 - on], axis=-1).clip(0, 1)


def _colour_bars(figure, axes, top: float, unit: str):
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import LinearSegmentedColormap, PowerNorm

    norm = PowerNorm(0.5, vmin=0, vmax=top)
    for name, colour in (("ON", "red"), ("OFF", "blue")):
        cmap = LinearSegmentedColormap.from_list(name, ["white", colour])
        bar = figure.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=axes, fraction=0.025, pad=0.01, aspect=30)
        bar.set_label(f"{name} {unit}", fontsize=7)
        bar.ax.tick_params(labelsize=6)


def _image_axis(axis, image, title: str):
    """`image` (H, W, 3) drawn in sensor pixel coordinates (`_on_screen`)."""
    height, width = image.shape[:2]
    shown = _on_screen(axis, image)
    factor = axis.neurotac_pool
    axis.imshow(shown, interpolation="nearest", extent=(-0.5, shown.shape[1] * factor - 0.5, shown.shape[0] * factor - 0.5, -0.5))
    axis.set_xlim(-0.5, width - 0.5)
    axis.set_ylim(height - 0.5, -0.5)
    axis.set_title(title, fontsize=7, pad=2)
    axis.set_xticks([])
    axis.set_yticks([])


def _on_screen(axis, image: np.ndarray) -> np.ndarray:
    """`image` as the tile shows it: where the tile has fewer screen pixels than the image, each block
    of sensor pixels shows its darkest (busiest) pixel, in that pixel's own colour, since a plain
    downsample skips whole rows and columns, and an isolated event with them (a darkest value per
    colour would mix a block's ON and OFF pixels into a grey no pixel has). Every picture of an
    animation goes through it."""
    height, width = image.shape[:2]
    factor = getattr(axis, "neurotac_pool", None)  # chosen at the first picture: the later ones fill its extent
    if factor is None:
        figure = axis.figure
        across = max(int(0.9 * axis.get_position().width * figure.get_figwidth() * figure.dpi), 16)
        factor = axis.neurotac_pool = -(-width // across)
    if factor <= 1:
        return image
    padded = np.ones((-(-height // factor) * factor, -(-width // factor) * factor, 3))
    padded[:height, :width] = image
    rows, columns = padded.shape[0] // factor, padded.shape[1] // factor
    blocks = padded.reshape(rows, factor, columns, factor, 3).transpose(0, 2, 1, 3, 4).reshape(rows, columns, factor * factor, 3)
    darkest = blocks.sum(axis=3).argmin(axis=2)
    return np.take_along_axis(blocks, darkest[..., None, None], axis=2)[:, :, 0]


def _force_strip(axis, steps: Steps):
    """The force trace under the tiles, phases shaded (frames), in ms from the trial's zero."""
    if steps.phase and any(steps.phase):
        start = 0
        for k in range(1, len(steps.phase) + 1):
            if k == len(steps.phase) or steps.phase[k] != steps.phase[start]:
                colour = PHASE_COLOURS.get(steps.phase[start] or "", "#ffffff")
                axis.axvspan(steps.starts_ms[start], steps.starts_ms[k - 1] + steps.step_ms, color=colour, lw=0)
                start = k
        present = [name for name in PHASE_COLOURS if name in steps.phase]  # the legend names what is shaded
        if present:
            axis.legend([_patch(PHASE_COLOURS[name]) for name in present], present, loc="upper right", fontsize=6, ncol=3)
    axis.plot(steps.force_t_ms, steps.force_n, "k.-" if steps.what == "frame" else "k-", lw=1, ms=2)
    start, end = steps.starts_ms[0], steps.starts_ms[-1] + steps.step_ms
    margin = 0.02 * (end - start)  # a force sampled at the last window's close is drawn whole, not on the frame
    axis.set_xlim(start - margin, end + margin)
    force = np.asarray(steps.force_n, dtype=float)
    if np.isfinite(force).any() and np.ptp(force[np.isfinite(force)]) < 0.01:  # a flat force: a scale of 1e-3 N says nothing
        middle = float(np.nanmean(force))
        axis.set_ylim(middle - 0.5, middle + 0.5)
    axis.set_xlabel("time from the trial's zero t0 (ms)", fontsize=7)
    axis.set_ylabel("force (N)", fontsize=7)
    axis.tick_params(labelsize=6)


def _patch(colour):
    return _pyplot().Rectangle((0, 0), 1, 1, color=colour)


def _pyplot():
    from neurotac_cli.model.plots import pyplot  # the one place that imports matplotlib, quietly

    return pyplot()


# ---------------------------------------------------------------- views


def _tile_inches(counts: np.ndarray, animated: bool) -> tuple[float, float]:
    height, width = counts.shape[2:]
    tile_w = 5.0 if animated else 1.5
    return tile_w, max(tile_w * height / width, 0.3)


MIN_FIGURE_INCHES = 2.6


def _figure(rows: int, columns: int, tile: tuple[float, float], strip: bool):
    """A figure of rows x columns image tiles, with a force strip under them when asked."""
    plt = _pyplot()
    tile_w, tile_h = tile
    # at least the height of the colour bars' labels: one row of wide tiles (a 1280x720 sensor) cut them off
    height = max(rows * (tile_h + 0.3) + (1.9 if strip else 0) + 0.6, MIN_FIGURE_INCHES)
    figure = plt.figure(figsize=(columns * tile_w + 1.4, height), dpi=DPI, layout="constrained")
    grid = figure.add_gridspec(rows + strip, columns, height_ratios=[tile_h + 0.3] * rows + [1.6] * strip)
    return figure, grid


def montage(steps: Steps, spec: RenderSpec, animated: bool):
    """Tiles over time (or one tile per picture when animated), the force strip under them."""
    top = colour_top(steps.counts)
    shown, left_out = shown_steps(steps, spec, None if animated else MAX_TILES)
    columns = 1 if animated else min(spec.columns, len(shown))
    rows = 1 if animated else -(-len(shown) // columns)
    strip = steps.force_n is not None
    figure, grid = _figure(rows, columns, _tile_inches(steps.counts, animated), strip)
    axes = []
    for i, k in enumerate(shown[:1] if animated else shown):
        axis = figure.add_subplot(grid[i // columns, i % columns])
        _image_axis(axis, rgb(steps.counts[k], top), steps.caption(k))
        axes.append(axis)
    _colour_bars(figure, axes, top, f"events per pixel per {steps.what}")
    cursor = None
    if strip:
        axis = figure.add_subplot(grid[rows, :])
        _force_strip(axis, steps)
        for k in [] if animated else shown:
            axis.axvline(steps.starts_ms[k] + steps.step_ms / 2, color="#777777", lw=0.5, ls=":")
        cursor = axis.axvline(steps.starts_ms[shown[0]], color="black", lw=1.2) if animated else None
    what = f"{steps.step_ms:g} ms frames" if steps.what == "frame" else f"{counted(len(steps.counts), 'slice')} of {steps.step_ms:.3g} ms"
    part = f", every {spec.every}" if spec.every > 1 else ""
    part += f", the first {len(shown)} of {len(steps.counts)}" if len(shown) * spec.every < len(steps.counts) else ""
    figure.suptitle(f"{steps.trial}: {what}{part} (ON red, OFF blue)" + (" and force" if strip else ""), fontsize=9)

    def update(i):
        k = shown[i]
        axes[0].images[0].set_data(_on_screen(axes[0], rgb(steps.counts[k], top)))
        axes[0].set_title(steps.caption(k), fontsize=7, pad=2)
        if cursor is None:
            return [axes[0]]
        cursor.set_xdata([steps.starts_ms[k] + steps.step_ms / 2] * 2)
        return [axes[0], cursor]

    return figure, update, len(shown) if animated else 1, left_out


def crop_box(table: pa.Table, steps: Steps, crop_spec) -> tuple[tuple, str]:
    """The box `neurotac crop` would cut with these options, and how its centre was found."""
    from neurotac_cli.ops import crop as cr

    if crop_spec is None or (crop_spec.box is None and crop_spec.size is None):
        raise NeurotacError("the crop view needs the box: --box X,Y,W,H, or --size WxH with --center X,Y|auto")
    height, width = steps.counts.shape[2:]
    activity = cr.activity_map(table) if crop_spec.center == "auto" else None
    report = cr.CropReport()
    box = cr.resolve_box(crop_spec, (width, height), activity, report)
    if crop_spec.box is not None:
        return box, "given"
    found, kept = tuple(report.center), (box[0] + box[2] // 2, box[1] + box[3] // 2)
    # a centre too near the edge is moved so the box fits: the title names where the drawn box stands
    moved = "" if kept == found else f", moved from {found[0]},{found[1]} to fit the sensor"
    return box, f"centre {kept[0]},{kept[1]} ({report.center_from}{moved})"


def crop_view(table: pa.Table, steps: Steps, spec: RenderSpec, animated: bool):
    """The trial's counts accumulated (or each picture's, when animated) with the crop box on them."""
    plt = _pyplot()
    box, how = crop_box(table, steps, spec.crop)
    total = steps.counts.sum(axis=0, dtype=np.float64)
    shown = shown_steps(steps, spec, None)[0] if animated else [None]
    images = [total] if not animated else None
    top = colour_top(total if not animated else steps.counts)
    figure, grid = _figure(1, 1, _tile_inches(steps.counts, True), False)
    axis = figure.add_subplot(grid[0, 0])
    _image_axis(axis, rgb(images[0] if images else steps.counts[shown[0]], top),
                "all of the trial" if not animated else steps.caption(shown[0]))
    x, y, w, h = box
    axis.add_patch(plt.Rectangle((x - 0.5, y - 0.5), w, h, fill=False, edgecolor="#00a000", lw=1.5))
    axis.text(x, y - 2, f"crop {w}x{h} at {x},{y}", color="#00a000", fontsize=7, va="bottom")
    height, width = steps.counts.shape[2:]
    axis.set_xlabel(f"x (pixels of the {width}x{height} input, origin top-left)", fontsize=7)
    _colour_bars(figure, [axis], top, "events per pixel" + (f" per {steps.what}" if animated else " in the trial"))
    inside = total[:, y : y + h, x : x + w].sum() / max(total.sum(), 1)
    figure.suptitle(f"{steps.trial}: crop box {w}x{h}, {how}; it keeps {100 * inside:.0f}% of the trial's events", fontsize=9)

    def update(i):
        axis.images[0].set_data(_on_screen(axis, rgb(steps.counts[shown[i]], top)))
        axis.set_title(steps.caption(shown[i]), fontsize=7, pad=2)
        return [axis]

    return figure, update, len(shown) if animated else 1, 0


def augmented_pair(table: pa.Table, trial: str | None) -> tuple[str, str, str]:
    """(source, copy, what was done) for the copy named `trial`, the first copy of the source named
    `trial`, or the input's first copy."""
    if "source_trial" not in table.column_names:
        raise NeurotacError("the augmented view needs a frames table from `neurotac augment` (it has no source_trial column)")
    ids = table.column("trial").to_pylist()
    sources = table.column("source_trial").to_pylist()
    done = table.column("augment").to_pylist() if "augment" in table.column_names else [""] * len(ids)
    copies = {copy: (source, what) for copy, source, what in zip(ids, sources, done) if source and copy != source}
    if not copies:
        raise NeurotacError("the input holds no augmented copies (every trial is its own source)")
    if trial is None:
        copy = next(iter(copies))
    elif trial in copies:
        copy = trial
    else:
        copy = next((c for c, (source, _) in copies.items() if source == trial), None)
        if copy is None:
            raise NeurotacError(f"no augmented copy of trial {trial!r} in the input (copies: {', '.join(list(copies)[:4])}...)")
    source, what = copies[copy]
    if source not in set(ids):
        raise NeurotacError(f"the source {source!r} of {copy!r} is not in the input (augment with its originals kept)")
    return source, copy, what


def augmented_view(table: pa.Table, spec: RenderSpec, animated: bool):
    """The copy's frames under its source's, on one colour scale."""
    source, copy, what = augmented_pair(table, spec.trial)
    pair = [_frame_steps(table, source), _frame_steps(table, copy)]
    top = colour_top(np.concatenate([pair[0].counts, pair[1].counts]))
    shown, left_out = shown_steps(pair[0], spec, None if animated else min(spec.columns, MAX_TILES // 2))
    columns = 2 if animated else len(shown)
    figure, grid = _figure(1 if animated else 2, columns, _tile_inches(pair[0].counts, animated), False)
    axes = []
    for row, steps in enumerate(pair):
        for i, k in enumerate(shown[:1] if animated else shown):
            axis = figure.add_subplot(grid[0, row] if animated else grid[row, i])
            name = "source" if row == 0 else what
            _image_axis(axis, rgb(steps.counts[k], top), f"{name}, {steps.caption(k)}" if animated or i == 0 else steps.caption(k))
            axes.append(axis)
    _colour_bars(figure, axes, top, "events per pixel per frame")
    figure.suptitle(f"augmented copy {copy} (below) under its source {source} (above), on one colour scale", fontsize=9)

    def update(i):
        for axis, steps in zip(axes, pair):
            axis.images[0].set_data(_on_screen(axis, rgb(steps.counts[shown[i]], top)))
            axis.set_title(f"{'source' if steps is pair[0] else what}, {steps.caption(shown[i])}", fontsize=7, pad=2)
        return axes

    return figure, update, len(shown) if animated else 1, left_out


# ---------------------------------------------------------------- writing


def render(table: pa.Table, path: str, spec: RenderSpec) -> dict:
    """Draw `table` as `spec` asks into `path` (.png, .gif or .mp4); returns what was drawn."""
    fmt = output_format(path)
    animated = fmt != "png"
    if spec.view == "augmented":
        figure, update, n, left_out = augmented_view(table, spec, animated)
        trial = augmented_pair(table, spec.trial)[1]
    else:
        trial = pick_trial(table, spec.trial)
        steps = steps_of(table, trial, spec)
        view = crop_view if spec.view == "crop" else montage
        figure, update, n, left_out = view(table, steps, spec, animated) if view is crop_view else view(steps, spec, animated)
    try:
        pictures = _pictures(figure, update, n, f"{fmt} pictures") if animated else None
        size = _write(figure, pictures, fmt, path, spec.fps)
    finally:
        _pyplot().close(figure)
    return {"path": path, "format": fmt, "view": spec.view, "trial": trial, "pictures": n, "width": size[0], "height": size[1],
            "left_out": left_out}


def _pictures(figure, update, n: int, label: str):
    """The n pictures of an animation, one at a time, with progress on stderr. A full draw of the
    figure re-runs its constrained layout and redraws every tick label and colour bar: about 0.15 s a
    picture, minutes for a thousand slices. So the figure is laid out and drawn once without the
    artists that `update` changes (the tiles, their titles, the force cursor), its positions are
    kept, and each picture restores that drawing and draws only those artists again (blitting)."""
    from neurotac_cli.study import Progress

    canvas = figure.canvas
    for artist in update(0):
        artist.set_animated(True)
    canvas.draw()
    figure.set_layout_engine("none")  # the positions of that one layout, for every picture
    background = canvas.copy_from_bbox(figure.bbox)
    meter = Progress(n, label=label)
    try:
        for i in range(n):
            moving = update(i)
            canvas.restore_region(background)
            for artist in moving:
                figure.draw_artist(artist)
            yield np.asarray(canvas.buffer_rgba())[..., :3].copy()
            meter.advance()
    finally:
        meter.close()


def _write(figure, pictures, fmt: str, path: str, fps: float) -> tuple[int, int]:
    from neurotac_cli.tables import atomic_file

    with atomic_file(path) as temporary:
        if fmt == "png":
            # the whole drawing, the colour bars' labels included, whatever the tiles' shape left for them
            figure.savefig(temporary, format="png", dpi=DPI, bbox_inches="tight", pad_inches=0.05)
            from PIL import Image

            with Image.open(temporary) as image:
                return image.size
        if fmt == "gif":
            from PIL import Image

            # one picture drawn at a time as Pillow asks for it; Pillow keeps each at one byte a pixel
            # until it writes, a third of holding a thousand RGB pictures
            images = (Image.fromarray(picture) for picture in pictures)
            first = next(images)
            first.save(temporary, format="GIF", save_all=True, append_images=images, duration=round(1000 / fps), loop=0)
            return first.size
        return _write_mp4(pictures, temporary, fps, path)


def _write_mp4(pictures, path: str, fps: float, name: str) -> tuple[int, int]:
    """H.264 through the ffmpeg that imageio-ffmpeg ships, run here rather than through its
    `write_frames`, which never looks at ffmpeg's exit: on a full disk a cut video replaced the old
    one and the run said "wrote". Pictures are padded with white to a multiple of 16 pixels (H.264's
    macro block), so ffmpeg does not rescale them. `name`: the output as given, for the error."""
    import subprocess
    import tempfile
    from fractions import Fraction

    import imageio_ffmpeg

    pictures = iter(pictures)
    first = next(pictures)
    height, width = first.shape[:2]
    padded = (-(-width // 16) * 16, -(-height // 16) * 16)
    # imageio-ffmpeg's settings: its default quality 5 is CRF 25
    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-v", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
               "-s", f"{padded[0]}x{padded[1]}", "-r", str(Fraction(fps).limit_denominator()), "-i", "-", "-an",
               "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", "25", "-f", "mp4", path]
    with tempfile.TemporaryFile() as said:  # ffmpeg's own words, for the one line if it fails
        encoder = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=said)
        try:
            for picture in itertools.chain([first], pictures):
                frame = np.full((padded[1], padded[0], 3), 255, dtype=np.uint8)
                frame[:height, :width] = picture
                encoder.stdin.write(frame.tobytes())
        except BrokenPipeError:
            pass  # ffmpeg stopped early: its exit status and its words say why
        except BaseException:
            encoder.kill()  # interrupted, or a drawing failed: no video to finish
            raise
        finally:
            try:
                encoder.stdin.close()
            except BrokenPipeError:
                pass
            encoder.wait()
        said.seek(0)
        lines = [line.strip() for line in said.read().decode("utf-8", "replace").splitlines() if line.strip()]
    if encoder.returncode != 0:
        raise _encoder_error(name, encoder.returncode, lines)
    return padded


def _encoder_error(name: str, status: int, lines: list[str]) -> Exception:
    """ffmpeg's failure as the error of writing a file where its exit or words name one (a full disk,
    a file too large), which `atomic_file` words as every other output's; else its last line."""
    import errno
    import os
    import signal

    from neurotac_cli.errors import OutputError

    if status == -signal.SIGXFSZ:  # a file-size limit (`ulimit -f`) kills a process that passes it
        return OSError(errno.EFBIG, os.strerror(errno.EFBIG))
    for number in OutputError.WHY:
        if any(os.strerror(number) in line for line in lines):
            return OSError(number, os.strerror(number))
    return OutputError(f"cannot write {name} (ffmpeg failed: {lines[-1] if lines else 'no message'})")
