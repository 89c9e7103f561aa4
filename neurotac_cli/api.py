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

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.errors import NeurotacError
from neurotac_cli.units import MAX_SIDE, is_whole, parse_ints
from neurotac_cli.ops.augment import EventShift, FrameShift, Noise, Resize, Rotate  # noqa: F401  (augment's methods)

TONIC_DTYPE = np.dtype([("x", np.int16), ("y", np.int16), ("t", np.int64), ("p", np.int8)])


def _kind(table, *kinds) -> str:
    """The kind of `table`, checked as a pyarrow Table of one of `kinds` (the commands check theirs at the door)."""
    if not isinstance(table, pa.Table):
        raise NeurotacError(f"expected a pyarrow Table ({' or '.join(kinds)}), got {type(table).__name__}")
    return sch.validate(table.schema, kinds)


def _table(table, *kinds) -> pa.Table:
    """`table`, checked as `_kind` checks it."""
    _kind(table, *kinds)
    return table


def _model(model):
    """A trained model object (what `load_model` and `train` give), not its path."""
    from neurotac_cli.model.core import Model

    if not isinstance(model, Model):
        hint = " (load it with api.load_model(path))" if isinstance(model, (str, bytes)) else ""
        raise NeurotacError(f"expected a model from api.train or api.load_model, got {type(model).__name__}{hint}")
    return model


def _whole(value, what: str, least: int = 0, most: int = 2**63 - 1) -> int:
    """`value` checked as a whole number from `least` to `most` (the command line's types check theirs)."""
    if not is_whole(value) or not least <= value <= most:
        raise NeurotacError(f"{what} must be a whole number {f'>= {least}' if most == 2**63 - 1 else f'from {least} to {most}'}, got {value!r}")
    return int(value)


def _trial(trial) -> str:
    """A trial id: a string (the trial column is text), not a number that could never match."""
    if not isinstance(trial, str):
        raise NeurotacError(f"trial must be a trial id (a string), got {trial!r}")
    return trial


def _us(duration) -> int:
    from neurotac_cli.units import parse_duration_us

    return int(duration) if isinstance(duration, (int, np.integer)) else parse_duration_us(str(duration))


# ---------------------------------------------------------------- tables in and out


def read(*paths: str, kind=None) -> pa.Table:
    """Tables (Arrow IPC stream or file, Parquet) read as one, checked as `kind` when given."""
    from neurotac_cli import tables

    return tables.read(list(paths), kind=kind)


def write(table: pa.Table, path: str, step: tuple | None = None) -> None:
    """Write by suffix (.parquet, .arrow, .arrows; .csv, .json, .ndjson without tensors), atomically;
    `step` = (command, args) appends to the table's history."""
    from neurotac_cli import tables

    if path in (None, "-"):
        raise NeurotacError("give a file path: the library does not write binary tables to stdout")
    if not isinstance(table, pa.Table):
        raise NeurotacError(f"expected a pyarrow Table to write, got {type(table).__name__}")
    tables.write(path, table, step=step)


def import_camera(path: str, sensor: tuple[int, int] | None = None) -> pa.Table:
    """A camera file (AEDAT, EVT 2.0/2.1/3.0, DAT, ES, HDF5, CSV, text) as an events table, timestamps as written."""
    from neurotac_cli.io.events import read_events_table
    from neurotac_cli.units import parse_size

    if isinstance(sensor, str):
        sensor = parse_size(sensor)
    elif sensor is not None and not (isinstance(sensor, (tuple, list)) and len(sensor) == 2
                                     and all(is_whole(v) and 1 <= v <= MAX_SIDE for v in sensor)):
        raise NeurotacError(f"sensor must be (width, height), whole numbers from 1 to {MAX_SIDE}, or \"WxH\"; got {sensor!r}")
    return read_events_table(path, sensor=sensor)


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
        raise NeurotacError(f"labels must be a dict of label names to values, e.g. {{'material': 'foam'}}, got {labels!r}")
    source = Source(trial=name, events=events, force=ForceOptions().read(force), labels=dict(labels or {}))
    return sy.sync_sources([source], sy.sync_method(method))


# ---------------------------------------------------------------- frames


def frame(table: pa.Table, window="10ms", **options) -> pa.Table:
    """Frames of a recordings table (per trial, from t0) or an events table (one trial, from its first
    event). `options` as `neurotac frame`'s: partial, pad_to, force_at, phases, accumulate, dtype."""
    from neurotac_cli.ops import frame as fr

    known = {field.name for field in dataclasses.fields(fr.Framing)} - {"window_us"}
    if set(options) - known:
        raise NeurotacError(f"frame() has no option {sorted(set(options) - known)[0]!r} (options: {', '.join(sorted(known))})")
    if _kind(table, "recordings", "events") == "recordings":
        events_only = sorted({"start_us", "trial", "sort"} & set(options))
        if events_only:  # a recordings table's trials keep their ids and start at their sync instant
            raise NeurotacError(f"frame() takes {', '.join(events_only)} for a plain events table only, not a recordings table")
        return fr.frame_recordings(table, _us(window), **options)
    return fr.frames_from_events_table(table, _us(window), **options)


def crop(table: pa.Table, box=None, size=None, center=None, pool=None) -> pa.Table:
    """Crop and sum-pool frames, recordings or events: box=(x, y, w, h), or size=(w, h) with
    center=(x, y) or "auto"; pool=(k, l) or "all"."""
    from neurotac_cli.ops import crop as cr

    _table(table, "frames", "recordings", "events")
    if isinstance(center, str) and center != "auto":  # "X,Y", as the command line writes it
        try:
            center = parse_ints(center, 2)
        except NeurotacError:
            raise NeurotacError("center must be (x, y), \"X,Y\" or \"auto\"") from None
    return cr.crop_table(table, cr.CropSpec(box=box, size=size, center=center, pool=pool))


def augment(frames: pa.Table, *methods, copies: int = 1, combine: str = "independent", seed: int = 0,
            keep_original: bool = True) -> pa.Table:
    """Augmented copies of every trial, e.g. augment(frames, api.Rotate(0, 45), api.FrameShift(-1))."""
    from neurotac_cli.ops.augment import augment_frames

    if not _table(frames, "frames").num_rows:
        raise NeurotacError("the frames table is empty: nothing to augment")
    if not methods or not all(isinstance(method, (Rotate, Resize, FrameShift, EventShift, Noise)) for method in methods):
        raise NeurotacError("give augmentation methods as objects, e.g. api.Rotate(0, 45), api.FrameShift(-1)")
    table, _ = augment_frames(frames, list(methods), copies=_whole(copies, "copies", 1), combine=combine,
                              keep_original=keep_original, seed=_whole(seed, "seed"))
    return table


def counts(frames: pa.Table, trial: str | None = None) -> np.ndarray:
    """The counts of all frames, or of one trial in frame order, as (frames, 2, H, W) numpy."""
    import pyarrow.compute as pc

    _table(frames, "frames")
    if trial is not None:
        frames = frames.filter(pc.equal(frames.column("trial"), _trial(trial)))
        if not frames.num_rows:
            raise NeurotacError(f"no trial {trial!r} in the frames")
        frames = frames.take(pc.sort_indices(frames.column("frame")))
    return sch.counts_numpy(frames.column("counts"))


# ---------------------------------------------------------------- models


def train(frames: pa.Table, model: str = "tdnn", seed: int = 0, val_fraction: float | None = 0.1, **options):
    """Train a model (`neurotac train --model NAME`); `options` are its hyperparameters (epochs, layers, ...)."""
    from neurotac_cli import model as models

    _table(frames, "frames")
    if val_fraction is not None and not 0 <= val_fraction < 1:
        raise NeurotacError(f"val_fraction must lie in [0, 1), got {val_fraction}")
    return models.train(frames, models.make_spec(model, **options), val_fraction=val_fraction, seed=_whole(seed, "seed"))


def evaluate(model, frames: pa.Table, nonzero: bool = False) -> tuple[pa.Table, pa.Table]:
    """(predictions, metrics) of a model on frames, as `neurotac eval --model`."""
    from neurotac_cli.metrics import metrics_table
    from neurotac_cli.model import evaluate as ev

    predictions, rows = ev.evaluate_model(_model(model), _table(frames, "frames"), nonzero=nonzero)
    return predictions, metrics_table(rows, model.name)


def load_model(path: str):
    from neurotac_cli import model as models

    return models.load(path)


def save_model(model, path: str) -> None:
    from neurotac_cli import model as models

    models.save(_model(model), path)


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
        shape = (2, self.model.input_spec["height"], self.model.input_spec["width"])
        if counts.shape[-3:] != shape or counts.ndim not in (3, 4):
            raise NeurotacError(f"expected frames of shape {shape} (or (n, {', '.join(map(str, shape))})), got {counts.shape}")
        many = counts.ndim == 4
        t = np.atleast_1d(np.asarray(t_us, dtype=np.int64))
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
        raise NeurotacError("expected a tonic structured array with fields t, x, y, p")
    x, y, p = np.asarray(array["x"]), np.asarray(array["y"]), np.asarray(array["p"])
    width, height = int(sensor_size[0]), int(sensor_size[1])
    if len(x) and (x.min() < 0 or y.min() < 0 or x.max() >= width or y.max() >= height):
        raise NeurotacError(f"events lie outside the {width}x{height} sensor (x {x.min()}..{x.max()}, y {y.min()}..{y.max()})")
    return sch.events_table(np.asarray(array["t"], np.int64), x.astype(np.uint16), y.astype(np.uint16),
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


def render(table: pa.Table, path: str, **spec) -> dict:
    """Draw a table into a PNG, GIF or MP4, as `neurotac render` (spec: view, trial, slices, every, ...)."""
    from neurotac_cli import rendering as rd

    _table(table, "frames", "recordings", "events")
    if not table.num_rows:
        raise NeurotacError("the table is empty: nothing to draw")
    try:
        made = rd.RenderSpec(**spec)
    except TypeError as error:
        raise NeurotacError(f"render: {error}") from None
    return rd.render(table, path, made)
