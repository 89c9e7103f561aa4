"""neurotac as a library: the functions the commands call, for notebooks and scripts (docs/python.md).

Tables are pyarrow Tables of the kinds of docs/formats.md (events, recordings, frames, predictions,
metrics); counts come out as numpy arrays (frames, 2, H, W), channel 0 = OFF, 1 = ON. Durations are
integer microseconds or strings with their unit ("10ms"). Errors are `neurotac_cli.errors.NeurotacError`
with the message the command line would print. Nothing here prints or exits.

    from neurotac_cli import api
    recordings = api.simulate("ch4", trials=4, seed=1)
    frames = api.crop(api.frame(recordings, "10ms"), size=(60, 60), center="auto", pool=(2, 2))
    model = api.train(frames, "tdnn", epochs=5)
    predictions, metrics = api.evaluate(model, frames)
"""

import dataclasses
import numbers
import os
import warnings

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError, NeurotacWarning, UsageError
from neurotac_cli.units import MAX_SIDE, is_whole, parse_ints, parse_size
from neurotac_cli.ops.augment import EventShift, FrameShift, Noise, Resize, Rotate  # noqa: F401  (augment's methods)

# x and y as a wider signed type than tonic's int16 datasets: sensor coordinates reach 65535, and
# tonic's transforms subtract from them (flips, shifts), which an unsigned type would wrap
TONIC_DTYPE = np.dtype([("x", np.int32), ("y", np.int32), ("t", np.int64), ("p", np.int8)])


def _input(table, *kinds):
    """`table` opened as a command opens its input (tables.Input): kind, columns, nulls, a trial or
    frame given twice and an empty table are refused with the command line's words."""
    from neurotac_cli import tables

    if not isinstance(table, pa.Table):
        raise UsageError(f"expected a pyarrow Table ({' or '.join(kinds)}), got {type(table).__name__}")
    return tables.open_table(table, kinds)


def _table(table, *kinds) -> pa.Table:
    """`table`, checked as `_input` checks it."""
    return _input(table, *kinds).read_all()


def _warn(lines, marked: bool = False) -> None:
    """The command line's stderr warnings for the same input, as NeurotacWarning: a library has no
    stderr of its own, and a notebook shows warnings (a script can turn them into errors).
    `marked`: of `lines`, only those starting `warning: ` (the others are counts for a person)."""
    for line in filter(None, lines):
        if not marked or line.startswith("warning: "):
            warnings.warn(line.removeprefix("warning: "), NeurotacWarning, stacklevel=3)


def _model(model):
    """A trained model object (what `load_model` and `train` give), not its path."""
    from neurotac_cli.model.core import Model

    if not isinstance(model, Model):
        hint = " (load it with api.load_model(path))" if isinstance(model, (str, bytes)) else ""
        raise UsageError(f"expected a model from api.train or api.load_model, got {type(model).__name__}{hint}")
    return model


def _whole(value, what: str, least: int | None = 0, most: int = 2**63 - 1) -> int:
    """`value` checked as a whole number from `least` (None: no bound) to `most` (the command line's
    types check theirs)."""
    if not is_whole(value) or not (least is None or least <= value) or not value <= most:
        bound = "" if least is None else f" >= {least}" if most == 2**63 - 1 else f" from {least} to {most}"
        raise UsageError(f"{what} must be a whole number{bound}, got {value!r}")
    return int(value)


def _flag(value, what: str) -> bool:
    """A yes/no setting: True or False only ("no" is a true string, 1 may be meant as a number)."""
    if not isinstance(value, (bool, np.bool_)):
        raise UsageError(f"{what} is a flag: give True or False, got {value!r}")
    return bool(value)


def _plain(value):
    """numpy scalars and arrays as Python's numbers and tuples, so they pass the checks Python's do."""
    if isinstance(value, np.ndarray):
        return tuple(value.tolist())
    return value.item() if isinstance(value, np.generic) else value


def _parsed(parse, text: str, what: str):
    """`text` read as the command line reads it; its error named after the argument."""
    try:
        return parse(text)
    except NeurotacError as error:
        raise UsageError(f"{what}: {error}") from None


def _numbers(value, what: str, count: int, parse):
    """(count) whole numbers given as a tuple, list or numpy array, or as the command line writes
    them (`parse`: "60x60", "100,90"); anything else is left to the core's own check."""
    if isinstance(value, str) and value != "all" and value != "auto":
        return _parsed(parse, value, what)
    value = _plain(value)
    return tuple(_plain(v) for v in value) if isinstance(value, (tuple, list)) and len(value) == count else value


def _path(path, what: str = "path") -> str:
    """A file path given as text (or os.PathLike), not empty and not a folder."""
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise UsageError(f"{what} must be a file path, got {path!r}")
    path = os.fspath(path)
    if os.path.isdir(path):
        raise UsageError(f"{path} is a folder; give a file path in it")
    return path


def _trial(trial) -> str:
    """A trial id: a string (the trial column is text), not a number that could never match."""
    if not isinstance(trial, str):
        raise UsageError(f"trial must be a trial id (a string), got {trial!r}")
    return trial


def _us(duration, what: str = "duration") -> int:
    """Microseconds: a whole number (not a bool), or a duration with its unit ("10ms")."""
    from neurotac_cli.units import parse_duration_us

    if is_whole(duration):
        return int(duration)
    if not isinstance(duration, str):
        raise UsageError(f"{what} must be whole microseconds or a duration with its unit (\"10ms\"), got {duration!r}")
    return _parsed(parse_duration_us, duration, what)


def _sensor(value, what: str, polarities: bool = False) -> tuple[int, int]:
    """(width, height) from a tuple, list or array (tonic's (W, H, 2) where `polarities`) or "WxH"."""
    if isinstance(value, str):
        return _parsed(parse_size, value, what)
    value = _plain(value) if isinstance(value, np.ndarray) else value
    sides = tuple(value)[:2] if isinstance(value, (tuple, list)) and len(value) in ((2, 3) if polarities else (2,)) else ()
    if len(sides) != 2 or not all(is_whole(v) and 1 <= v <= MAX_SIDE for v in sides):
        shape = "(width, height, polarities)" if polarities else "(width, height)"
        raise UsageError(f"{what} must be {shape}, whole sides from 1 to {MAX_SIDE}, or \"WxH\"; got {value!r}")
    return int(sides[0]), int(sides[1])


# ---------------------------------------------------------------- tables in and out


def read(*paths: str, kind=None) -> pa.Table:
    """Tables (Arrow IPC stream or file, Parquet) read as one, checked as `kind` when given (one of
    events, recordings, frames, predictions, metrics, or a tuple of them). "-" reads stdin."""
    from neurotac_cli import tables

    if not paths:  # stdin would be read: in a notebook that waits for ever
        raise UsageError('give the paths of the tables to read ("-" reads stdin)')
    kinds = (kind,) if isinstance(kind, str) else kind
    if kinds is not None and (not isinstance(kinds, tuple) or not kinds or not set(kinds) <= set(sch.KINDS)):
        raise UsageError(f"kind must be one of {', '.join(sch.KINDS)} (or a tuple of them), got {kind!r}")
    return tables.read([path if path == "-" else _path(path) for path in paths], kind=kind)


def write(table: pa.Table, path: str, step: tuple | None = None) -> None:
    """Write by suffix (.parquet, .arrow, .arrows; .csv, .json, .ndjson without tensors), atomically;
    `step` = (command, args) appends to the table's history."""
    from neurotac_cli import tables

    if path in (None, "-"):
        raise UsageError("give a file path: the library does not write binary tables to stdout")
    if not isinstance(table, pa.Table):
        raise UsageError(f"expected a pyarrow Table to write, got {type(table).__name__}")
    if step is not None and not (isinstance(step, (tuple, list)) and len(step) == 2
                                 and isinstance(step[0], str) and isinstance(step[1], dict)):
        raise UsageError(f"step must be (command, args): a name and a dict of its arguments, got {step!r}"[:300])
    tables.write(_path(path), table, step=step)


def import_camera(path: str, sensor: tuple[int, int] | None = None) -> pa.Table:
    """A camera file (AEDAT, EVT 2.0/2.1/3.0, DAT, ES, HDF5, CSV, text) as an events table, timestamps
    as written; "-" reads stdin."""
    from neurotac_cli.io.events import read_events_table

    sensor = None if sensor is None else _sensor(sensor, "sensor")
    return read_events_table(path if path == "-" else _path(path, "the camera file"), sensor=sensor)


def simulate(preset: str = "ch4", trials: int | None = None, seed: int = 0, **overrides) -> pa.Table:
    """Simulated grasps as a recordings table, cut at the true LED-off instant (`simulate --synced`)."""
    from neurotac_cli.sim.config import preset_config
    from neurotac_cli.sim.run import recordings, simulate as run

    trials = None if trials is None else _whole(trials, "trials", 1)
    return recordings(run(preset_config(preset, **overrides), seed=_whole(seed, "seed"), trials=trials))


def sync(camera, force: str, method: str = "led", trial: str | None = None, labels: dict | None = None) -> pa.Table:
    """One camera recording (a path or an events table) and its force log as a recordings table."""
    from neurotac_cli.io.camera import trial_name
    from neurotac_cli.io.manifest import ForceOptions, Source
    from neurotac_cli.ops import sync as sy

    events = import_camera(camera) if isinstance(camera, str) else _table(camera, "events")
    name = trial or (trial_name(camera) if isinstance(camera, str) else "trial")
    if labels is not None and not isinstance(labels, dict):
        raise UsageError(f"labels must be a dict of label names to values, e.g. {{'material': 'foam'}}, got {labels!r}")
    source = Source(trial=name, events=events, force=ForceOptions().read(_path(force, "force")), labels=dict(labels or {}))
    recordings, lines = sy.sync([source], sy.sync_method(method))
    _warn(lines)
    return recordings


# ---------------------------------------------------------------- frames


def frame(table: pa.Table, window="10ms", **options) -> pa.Table:
    """Frames of a recordings table (per trial, from t0) or an events table (one trial, from its first
    event). `options` as `neurotac frame`'s: partial, pad_to, force_at, zero, phases, accumulate,
    dtype, scale, max_frames; start_us, trial, sort for an events table. Warns (NeurotacWarning) where
    the command line warns."""
    from neurotac_cli.io.camera import camera_file_stem
    from neurotac_cli.ops import frame as fr

    known = {field.name for field in dataclasses.fields(fr.Framing)} - {"window_us", "slips", "frame_options"}
    if set(options) - known:
        raise UsageError(f"frame() has no option {sorted(set(options) - known)[0]!r} (options: {', '.join(sorted(known))})")
    options = {name: _plain(value) for name, value in options.items()}
    if options.get("start_us") is not None:
        options["start_us"] = _whole(options["start_us"], "start_us", least=None)
    for name in ("accumulate", "sort"):
        if name in options:
            options[name] = _flag(options[name], name)
    window_us = _us(window, "window")
    source = _input(table, "recordings", "events")
    fr.check_for_kind(source.kind, sorted({"start_us", "trial", "sort"} & set(options)), options.get("phases"), options.get("zero", "log"))
    if source.kind == "events":
        options.setdefault("trial", camera_file_stem(source.schema) or "events")
    schema, batches, report, _ = fr.frame(source, fr.Framing(window_us=window_us, **options))
    _warn([fr.size_note(schema, report.frames)])
    frames = pa.Table.from_batches(list(batches), schema=schema)
    _warn(report.messages(lead_in_expected=source.kind == "recordings"), marked=True)
    return frames


def _crop_numbers(box, size, center) -> dict:
    """A crop's box, size and centre as tuples, from tuples, numpy or the command line's text forms."""
    return {"box": _numbers(box, "box", 4, lambda text: parse_ints(text, 4)), "size": _numbers(size, "size", 2, parse_size),
            "center": _numbers(center, "center", 2, lambda text: parse_ints(text, 2))}


def crop(table: pa.Table, box=None, size=None, center=None, pool=None) -> pa.Table:
    """Crop and sum-pool frames, recordings or events: box=(x, y, w, h) or "X,Y,W,H", or size=(w, h)
    or "WxH" with center=(x, y), "X,Y" or "auto"; pool=(k, l), "KxL" or "all". Numpy arrays and
    scalars are taken as the tuples and numbers they hold."""
    from neurotac_cli.ops import crop as cr

    spec = cr.CropSpec(**_crop_numbers(box, size, center), pool=_numbers(pool, "pool", 2, parse_size))
    source = _input(table, "frames", "recordings", "events")
    schema, cropped, report = cr.crop(source.schema, source.batches, spec)
    out = cropped if isinstance(cropped, pa.Table) else pa.Table.from_batches(list(cropped), schema=schema)
    _warn(report.warnings(0.9))  # `crop --warn-above`'s default
    return out


def augment(frames: pa.Table, *methods, copies: int = 1, combine: str = "independent", seed: int = 0,
            keep_original: bool = True) -> pa.Table:
    """Augmented copies of every trial, e.g. augment(frames, api.Rotate(0, 45), api.FrameShift(-1)).
    Warns (NeurotacWarning) where a method pushes most events out of the frames, as the command does."""
    from neurotac_cli.ops.augment import augment_frames, check_changes, loss_warnings

    frames = _table(frames, "frames")
    if not methods or not all(isinstance(method, (Rotate, Resize, FrameShift, EventShift, Noise)) for method in methods):
        raise UsageError("give augmentation methods as objects, e.g. api.Rotate(0, 45), api.FrameShift(-1)")
    check_changes([repr(method) for method in methods if getattr(method, "unchanged", False)], len(methods), combine)
    table, counted = augment_frames(frames, list(methods), copies=_whole(copies, "copies", 1), combine=combine,
                                    keep_original=_flag(keep_original, "keep_original"), seed=_whole(seed, "seed"))
    _warn(loss_warnings(counted))
    return table


def counts(frames: pa.Table, trial: str | None = None) -> np.ndarray:
    """The counts of all frames, or of one trial in frame order, as (frames, 2, H, W) numpy."""
    import pyarrow.compute as pc

    frames = _table(frames, "frames")
    if trial is not None:
        frames = frames.filter(pc.equal(frames.column("trial"), _trial(trial)))
        if not frames.num_rows:
            raise NeurotacError(f"no trial {trial!r} in the frames")
        frames = frames.take(pc.sort_indices(frames.column("frame")))
    return sch.counts_numpy(frames.column("counts"))


# ---------------------------------------------------------------- models


def _progress_warnings(line: str) -> None:
    """A training or scoring progress callback that passes on the command line's warnings alone."""
    _warn([line], marked=True)


def train(frames: pa.Table, model: str = "tdnn", seed: int = 0, val_fraction: float | None = 0.1, **options):
    """Train a model (`neurotac train --model NAME`); `options` are its hyperparameters (epochs, layers, ...)."""
    from neurotac_cli import model as models

    frames = _table(frames, "frames")
    if val_fraction is not None and (isinstance(val_fraction, bool) or not isinstance(val_fraction, numbers.Real)
                                     or not 0 <= val_fraction < 1):
        raise UsageError(f"val_fraction must be a number in [0, 1), got {val_fraction!r}")
    spec = models.make_spec(model, **{name: _plain(value) for name, value in options.items()})
    _warn(models.training_input_notes(frames, spec["model"] in models.FORCE_MODELS), marked=True)
    return models.train(frames, spec, val_fraction=None if val_fraction is None else float(val_fraction),
                        seed=_whole(seed, "seed"), progress=_progress_warnings)


def evaluate(model, frames: pa.Table, nonzero: bool = False) -> tuple[pa.Table, pa.Table]:
    """(predictions, metrics) of a model on frames, as `neurotac eval --model`."""
    from neurotac_cli import model as models
    from neurotac_cli.metrics import check_nonzero, metrics_table
    from neurotac_cli.model import evaluate as ev

    model, nonzero = _model(model), _flag(nonzero, "nonzero")
    check_nonzero(nonzero, model.task == "material")
    frames = _table(frames, "frames")
    notes = models.scoring_input_notes(model.input_spec, model.training, model.task, frames)
    predictions, rows = ev.evaluate_model(model, frames, nonzero=nonzero, notes=notes)
    _warn(notes)
    return predictions, metrics_table(rows, model.name)


def load_model(path: str):
    """A model file written by `neurotac train` or `save_model`."""
    from neurotac_cli import model as models

    return models.load(_path(path, "the model file"))


def save_model(model, path: str) -> None:
    """Write a model file (atomically), as `neurotac train -o PATH`."""
    from neurotac_cli import model as models

    models.save(_model(model), _path(path, "the model file"))


class Stepper:
    """A force model fed frame by frame, as `neurotac predict` does: its state carried between calls."""

    def __init__(self, model):
        if _model(model).task != "force":
            raise NeurotacError(f"model {model.name!r} classifies materials; only force models are stepped")
        from neurotac_cli.model.session import is_session_model

        if is_session_model(model):
            raise NeurotacError(f"model {model.name!r} was trained on contacts (train --contacts) and needs its contact "
                                "detector: feed it through neurotac_cli.model.stream, as `neurotac predict` does")
        self.model, self.state = model, None

    def step(self, counts: np.ndarray, t_us) -> np.ndarray:
        """Force (N) for one frame (2, H, W) or several in order (n, 2, H, W), at their start times in µs."""
        counts = np.asarray(counts)
        if not np.issubdtype(counts.dtype, np.number) or counts.dtype == bool:
            raise UsageError(f"counts must be numbers (event counts per pixel), got an array of {counts.dtype}")
        shape = (2, self.model.input_spec["height"], self.model.input_spec["width"])
        if counts.shape[-3:] != shape or counts.ndim not in (3, 4):
            raise UsageError(f"expected frames of shape {shape} (or (n, {', '.join(map(str, shape))})), got {counts.shape}")
        many = counts.ndim == 4
        t = np.asarray(t_us)
        if many and not len(counts):
            raise UsageError("no frames to step: give one frame (2, H, W) or several (n, 2, H, W)")
        if t.dtype == bool or not np.issubdtype(t.dtype, np.integer) or t.ndim != int(many):
            want = "a 1-d array of whole µs, one per frame" if many else "one whole number of µs"
            raise UsageError(f"t_us must be the frames' start times, {want}; got {t_us!r}"[:300])
        t = np.atleast_1d(t.astype(np.int64))
        if len(t) != (len(counts) if many else 1):
            raise UsageError(f"{len(counts)} frames need as many start times, got {len(t)}")
        force, self.state = self.model.step(counts[None] if many else counts[None, None], t[None], self.state)
        return force[0] if many else force[0, 0]

    def reset(self) -> None:
        self.state = None


# ---------------------------------------------------------------- other tools


def to_tonic(events: pa.Table) -> np.ndarray:
    """An events table as the structured array tonic's transforms take (fields x, y, t µs, p 0/1)."""
    _table(events, "events")
    out = np.empty(events.num_rows, dtype=TONIC_DTYPE)
    for name in ("x", "y", "t", "p"):
        out[name] = events.column(name).to_numpy()
    return out


def from_tonic(array: np.ndarray, sensor_size: tuple) -> pa.Table:
    """A tonic structured array (t in µs, p 0/1 or -1/1 or bool) as an events table; sensor_size is
    tonic's (W, H, polarities)."""
    if getattr(array, "dtype", None) is None or array.dtype.names is None or not {"t", "x", "y", "p"} <= set(array.dtype.names):
        raise UsageError("expected a tonic structured array with fields t, x, y, p")
    width, height = _sensor(sensor_size, "sensor_size", polarities=True)
    x, y, p, t = (np.asarray(array[name]) for name in ("x", "y", "p", "t"))
    for name, values in (("t", t), ("x", x), ("y", y)):  # a cast to whole numbers would drop fractions, NaN read as -2^63
        if values.dtype.kind == "f" and len(values) and not (np.isfinite(values).all() and (values == np.round(values)).all()):
            raise NeurotacError(f"field {name} holds values that are not whole numbers (NaN, infinite or fractional); "
                                f"tonic's {name} is whole {'µs' if name == 't' else 'pixels'}")
    if len(x) and (x.min() < 0 or y.min() < 0 or x.max() >= width or y.max() >= height):
        raise NeurotacError(f"events lie outside the {width}x{height} sensor (x {x.min()}..{x.max()}, y {y.min()}..{y.max()})")
    return sch.events_table(t.astype(np.int64), x.astype(np.uint16), y.astype(np.uint16),
                            (p > 0).astype(np.uint8), width=width, height=height)


def tonic_sensor_size(events: pa.Table) -> tuple[int, int, int]:
    """tonic's sensor_size (W, H, 2) of an events table."""
    sensor = sch.sensor_of(_table(events, "events").schema)
    if sensor is None:
        raise NeurotacError("the events table does not say its sensor size (import it with --sensor WxH)")
    return sensor[0], sensor[1], 2


def events_of(recordings: pa.Table, trial: str) -> pa.Table:
    """One trial of a recordings table as an events table, times relative to its t0."""
    _table(recordings, "recordings")
    found = sch.trial_recording(recordings, _trial(trial))
    if found is None:
        raise NeurotacError(f"no trial {trial!r} in the recordings")
    sensor = sch.sensor_of(recordings.schema) or (None, None)
    return sch.events_table(*found[1], width=sensor[0], height=sensor[1])


def render(table: pa.Table, path: str, view: str = "montage", trial: str | None = None, slices: int | None = None,
           slice_us=None, columns: int = 8, every: int = 1, fps: float | None = None, box=None, size=None, center=None,
           **unknown) -> dict:
    """Draw a table into a PNG, GIF or MP4, as `neurotac render` (its options by name; slice_us a
    duration; box, size, center as `crop` takes them, for view="crop"). Options that would do
    nothing are refused, as the command line refuses them."""
    from neurotac_cli import rendering as rd
    from neurotac_cli.ops.crop import CropSpec

    if unknown:
        raise UsageError(f"render() has no option {sorted(unknown)[0]!r}")
    path = _path(path, "the picture")
    given = {name for name, value in (("slices", slices), ("slice_us", slice_us), ("fps", fps), ("box", box),
                                      ("size", size), ("center", center)) if value is not None}
    rd.check_options(path, view, given)
    spec = rd.RenderSpec(view=view, trial=None if trial is None else _trial(trial), slices=8 if slices is None else _plain(slices),
                         slice_us=None if slice_us is None else _us(slice_us, "slice_us"), columns=_plain(columns),
                         every=_plain(every), fps=10.0 if fps is None else _plain(fps),
                         crop=CropSpec(**_crop_numbers(box, size, center)) if box is not None or size is not None else None)
    table = _table(table, "frames", "recordings", "events")
    rd.check_slicing(sch.table_kind(table.schema), given)
    return rd.render(table, path, spec)
