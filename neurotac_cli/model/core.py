"""Building, training and running models on frames tables."""

import dataclasses
import importlib
import math
import numbers

import numpy as np
import pyarrow as pa
import torch

from neurotac_cli import schema as sch
from neurotac_cli.errors import InputError, ModelError, UsageError
from neurotac_cli.ops.forcelog import RANGE_N, RANGE_WARN_N
from neurotac_cli.model.curve import best_epoch
from neurotac_cli.model.data import (Sequences, already_accumulated, check_time_forward, choose_validation, ordered_trials,
                                     padded, parse_where, sequences)
from neurotac_cli.model.fit import FitConfig, fit, training_device
from neurotac_cli.model.names import FORCE_MODELS, FORMAT_VERSION, MATERIAL_MODELS
from neurotac_cli.units import counted, first_few

CHANNELS = ["off", "on"]
EVAL_BATCH = 16


def _module(name: str):
    if name in MATERIAL_MODELS:
        return importlib.import_module("neurotac_cli.model.material")
    if name in FORCE_MODELS:
        return importlib.import_module(f"neurotac_cli.model.{name.replace('-', '_')}")
    raise ModelError(f"unknown model {name!r} (force: {', '.join(FORCE_MODELS)}; material: {', '.join(MATERIAL_MODELS)})")


def _by_gradient(name: str) -> bool:
    """Whether the model trains by epochs of gradient steps (every one but the GP), so that the fit's options apply."""
    return name in MATERIAL_MODELS or getattr(_module(name).Net, "trained_by_gradient", True)


def _default_config(name: str):
    module = _module(name)
    return module.PRESETS[name] if name in MATERIAL_MODELS else module.Config()


def make_spec(name: str, **options) -> dict:
    """A model spec: {"model": name, architecture fields..., fit fields...}; None values take defaults."""
    config = _default_config(name)
    arch_fields = {f.name for f in dataclasses.fields(config)}
    fit_fields = {f.name for f in dataclasses.fields(FitConfig)}
    spec = {"model": name}
    for key, value in options.items():
        if value is None:
            continue
        if key not in arch_fields and key not in fit_fields:
            raise UsageError(f"model {name!r} has no option {key!r} (options: {', '.join(sorted(arch_fields | fit_fields))})")
        if key in fit_fields and not _by_gradient(name):
            raise UsageError(f"model {name!r} is fitted in closed form, not by epochs of gradient steps: {key!r} does not "
                             f"apply (its options: {', '.join(sorted(arch_fields))})")
        value = _typed(key, value, getattr(config if key in arch_fields else FitConfig(), key))
        _check_setting(key, value, name)
        spec[key] = value
    return spec


def _typed(key: str, value, default):
    """`value` as the setting's type (that of its default): a whole number where one is needed (1e3 is
    1000), a number where one is; a value of another type is refused here, not deep inside torch."""
    option = "--" + key.replace("_", "-")
    if isinstance(default, bool) or default is None or isinstance(value, bool):
        return value
    # numbers.Integral and Real hold numpy's scalars too (np.float32 is no float), as a notebook passes them
    if isinstance(default, int):
        if isinstance(value, numbers.Integral) or (isinstance(value, numbers.Real) and float(value).is_integer()):
            return int(value)
        raise UsageError(f"{option} takes a whole number, got {value!r}")
    if isinstance(default, float):
        if isinstance(value, numbers.Real):
            return float(value)
        raise UsageError(f"{option} takes a number, got {value!r}")
    return value


# The settings' ranges, (lowest, highest, whether the highest is excluded): a setting outside them
# would fail deep inside torch or train a model that cannot work, so it is refused here, where
# options, --grid values and a study's specs all pass.
# The highest sizes are far past any network of this field (the thesis's largest has 6 layers of
# 64 units), yet below what would exhaust memory or run for days before a word.
SETTING_RANGES = {
    "layers": (0, 64, False), "units": (1, 4096, False), "delays": (0, 1000, False), "filters": (1, 1024, False),
    "kernel": (1, 64, False), "dropout": (0.0, 1.0, True), "dense": (0, 4096, False), "hidden": (1, 4096, False),
    "members": (1, 64, False), "memory_frames": (0, None, False), "layout_grid": (0, None, False), "restarts": (0, 100, False),
    "max_points": (10, 20_000, False), "points": (2, None, False), "lr": (0.0, 1000.0, False), "beta1": (0.0, 1.0, True),
    "beta2": (0.0, 1.0, True), "batch_size": (1, None, False), "epochs": (1, None, False), "patience": (1, None, False),
    "weight_decay": (0.0, 1000.0, False),
}


# settings of the fit alone (the GP's subset and restarts): a loaded model never uses them again
FIT_ONLY = ("max_points", "restarts")


RECURRENT_LAYERS = ("lstm", "convlstm", "deform-gru")  # their layers are recurrent ones: at least one


def _check_setting(key: str, value, model: str = ""):
    if key not in SETTING_RANGES or isinstance(value, (str, bool)) or not isinstance(value, (int, float)):
        return
    low, high, open_high = SETTING_RANGES[key]
    if key == "layers" and model in RECURRENT_LAYERS:
        low = 1
    option = "--" + key.replace("_", "-")
    if not math.isfinite(value) or value < low or (key == "lr" and value <= 0) or (
            high is not None and (value >= high if open_high else value > high)):
        if key == "lr":
            bound = f"above 0 and at most {high:g}"
        elif high is None:
            bound = f"of at least {low:g}"
        else:
            bound = f"from {low:g} to {'below ' if open_high else ''}{high:g}"
        raise UsageError(f"{option} must be a finite number {bound}, got {value}")


def split_spec(spec: dict):
    name = spec["model"]
    config = _default_config(name)
    arch = {k: v for k, v in spec.items() if k in {f.name for f in dataclasses.fields(config)}}
    fitted = {k: v for k, v in spec.items() if k in {f.name for f in dataclasses.fields(FitConfig)}}
    fit_defaults = getattr(_module(name), "FIT_DEFAULTS", {})  # a model of ours may train longer than the thesis's protocol
    return name, dataclasses.replace(config, **arch), FitConfig(**{**fit_defaults, **fitted})


def resolved_spec(spec: dict) -> dict:
    """The spec with every setting its model would train with, defaults filled in: what a cached
    training is keyed by, so that a change of a model's defaults is not answered from the cache."""
    name, config, fit_config = split_spec(spec)
    return {"model": name, **dataclasses.asdict(config), **dataclasses.asdict(fit_config)}


class Model:
    """A trained model: the network, its config, and the input it expects."""

    def __init__(self, name, config, net, input_spec: dict, classes=None, training=None):
        self.name, self.config, self.net = name, config, net
        self.input_spec, self.classes, self.training = input_spec, classes, training or {}
        self.task = net.task
        net.eval()

    def members(self) -> list:
        """(the model of one member alone, the validation trials its early stopping watched) for each
        member of a network trained as several (deform-gru's --members), else [(self, its validation trials)]."""
        trials = self.training.get("trials", {})
        draws = [trials.get("validation") or [], *trials.get("member_validation", [])]
        if len(draws) == 1:
            return [(self, draws[0])]
        single = dataclasses.replace(self.config, members=1)
        return [(Model(self.name, single, self.net.alone(i), self.input_spec, self.classes, self.training), draw)
                for i, draw in enumerate(draws)]

    @property
    def force_scale(self) -> float:
        return float(self.input_spec["normalisation"]["force_scale"])

    def header(self) -> dict:
        return {
            "format": "neurotac-model",
            "format_version": FORMAT_VERSION,
            "model": self.name,
            "task": self.task,
            "architecture": dataclasses.asdict(self.config),
            "input": self.input_spec,
            "classes": self.classes,
            "training": self.training,
        }

    def step(self, counts: np.ndarray, t_us: np.ndarray, state=None):
        """Force (N) for frames (B, T, 2, H, W) at times (B, T) µs, continuing from `state`."""
        counts = np.asarray(counts, dtype=np.float32)
        if not counts.flags.writeable:
            counts = counts.copy()
        with torch.no_grad():
            out, state = self.net(torch.from_numpy(counts), torch.as_tensor(t_us / 1e6), state)
        force = out.numpy().astype(np.float32) * self.force_scale
        if not np.isfinite(force).all():
            raise ModelError(f"the {self.name} model gives a NaN or infinite force: its weights are damaged, or the frames "
                             "are far beyond any it learnt from (`neurotac info` on both)")
        return force, state

    def proba(self, data: Sequences, notes: list | None = None) -> np.ndarray:
        """Each trial's class probabilities; `notes` gets a line for each domain of an adapted model's
        input too small to be standardised over its own grasps."""
        from neurotac_cli.model import material

        x = material.features(data, self.config)
        adapt = self.input_spec.get("adapt")
        if adapt:  # each domain of the input over its own grasps where it has enough, else as training saw it
            domains = material.domains_of(data, adapt["by"])
            if notes is not None:
                notes += material.fallback_notes(domains, adapt, adapt["by"] in data.labels)
            stats = {domain: (np.asarray(mean), np.asarray(std)) for domain, (mean, std) in adapt["stats"].items()}
            stats.update(material.domain_stats(x, domains, least=material.MIN_DOMAIN_TRIALS))
            x = material.standardised(x, domains, stats, (np.asarray(adapt["mean"]), np.asarray(adapt["std"])))
        with torch.no_grad():
            logits = self.net(torch.as_tensor(x))
        proba = torch.softmax(logits, dim=-1).numpy()
        if not np.isfinite(proba).all():  # a class picked from NaN probabilities would be a guess written as an answer
            raise ModelError(f"the {self.name} model gives NaN class probabilities: its weights are damaged, or the frames are "
                             "far beyond any it learnt from (`neurotac info` on both)")
        return proba


# ---------------------------------------------------------------- input spec


def input_spec_of(schema: pa.Schema, accumulated: bool) -> dict:
    height, width = sch.frames_shape(schema)
    sensor = sch.get_meta(schema, sch.SENSOR)
    return {
        "window_us": sch.get_meta(schema, sch.WINDOW),
        "height": height,
        "width": width,
        "sensor": sensor,
        "channels": CHANNELS,
        "accumulated": accumulated,
    }


def check_input(model: Model, schema: pa.Schema, advice: str | None = None):
    """Refuse frames that differ from the training frames in window, crop or channels; `advice`: how
    to make them as the training frames were (default: with `frame` and `crop`)."""
    spec = model.input_spec
    here = input_spec_of(schema, already_accumulated(schema))

    def describe(s, made):
        window = f"{s['window_us'] / 1000:g} ms" if s.get("window_us") else "an unknown window"
        kind = "accumulated " if s.get("accumulated") else ""
        pool, scaled = made
        how = "".join([f", pooled {pool[0]}x{pool[1]}" if pool and "pooling" in problems else "",
                       f", {'scaled' if scaled else 'counted'} as {'float32' if scaled else 'uint16'}" if "counts" in problems else ""])
        return f"{s['width']}x{s['height']} {kind}frames of {window}{how}"

    problems = []
    trained, given = sch.made_by((model.training or {}).get("data_history") or []), sch.made_by(sch.get_meta(schema, sch.HISTORY, []))
    if (spec["height"], spec["width"]) != (here["height"], here["width"]):
        problems.append("crop")
    if spec.get("window_us") and here.get("window_us") and spec["window_us"] != here["window_us"]:
        problems.append("window")
    if bool(spec.get("accumulated")) != bool(here["accumulated"]):
        problems.append("accumulation")
    # pooling and scaling change what a count means even where the shape agrees (known where both histories say)
    if None not in (trained[0], given[0]) and trained[0] != given[0]:
        problems.append("pooling")
    if None not in (trained[1], given[1]) and trained[1] != given[1]:
        problems.append("counts")
    if problems:
        raise ModelError(
            f"model {model.name!r} was trained on {describe(spec, trained)}, this input has {describe(here, given)} "
            f"(different {' and '.join(problems)}); "
            + (advice or f"prepare the frames as the training frames were: `neurotac frame --window {(spec.get('window_us') or 10000) / 1000:g}ms "
               "| neurotac crop` with the training's --size, --center and --pool, and frame's --dtype (`neurotac info` of the "
               "training frames shows them)")
        )


def unstated_window(input_spec: dict, schema: pa.Schema) -> str | None:
    """A warning where the frames, or the model's training frames, do not record their window, so
    `check_input` could not compare it."""
    window = input_spec.get("window_us")
    if window and not sch.get_meta(schema, sch.WINDOW):
        return (f"the frames do not record their window (metadata {sch.WINDOW}), so it was not checked; the model "
                f"was trained on {window / 1000:g} ms frames and reads others wrongly")
    if not window:
        return ("the model does not record the window of its training frames (they lacked metadata "
                f"{sch.WINDOW}), so the window of these frames was not checked")
    return None


def input_notes(input_spec: dict, training_history: list, schema: pa.Schema) -> list[str]:
    """Warnings where frames may differ from the model's training frames in what `check_input`
    cannot compare: a window not recorded, a box elsewhere on the sensor."""
    return [note for note in (unstated_window(input_spec, schema), moved_box(training_history, schema)) if note]


def first_box(history: list) -> tuple | None:
    """The (x, y, w, h) box on the sensor that frames of this history were first cropped to, where it says."""
    for step in history:
        if step.get("command") == "crop":
            box = ((step.get("args") or {}).get("report") or {}).get("box")
            ok = isinstance(box, list) and len(box) == 4 and all(isinstance(v, int) for v in box)
            return tuple(box) if ok else None
    return None


def moved_box(training_history: list, schema: pa.Schema) -> str | None:
    """A warning where the frames were cropped to a box elsewhere on the sensor than the model's
    training frames (less than half of the two boxes shared): the same size passes `check_input`,
    but the contact lies elsewhere in the frame. Centres found by `--center auto` on different
    recordings of one rig differ by a few pixels, which is no warning."""
    trained, given = first_box(training_history or []), first_box(sch.get_meta(schema, sch.HISTORY, []))
    if trained is None or given is None:
        return None
    (ax, ay, aw, ah), (bx, by, bw, bh) = trained, given
    shared = max(0, min(ax + aw, bx + bw) - max(ax, bx)) * max(0, min(ay + ah, by + bh) - max(ay, by))
    if shared >= 0.5 * (aw * ah + bw * bh - shared):
        return None
    return (f"the frames were cropped to the box {','.join(map(str, given))} of the sensor, the model's training frames to "
            f"{','.join(map(str, trained))}: the contact lies elsewhere in these frames (crop with the training's box, "
            f"--box {','.join(map(str, trained))})")


# ---------------------------------------------------------------- training


def train(table: pa.Table, spec: dict, *, val_trials=None, val_fraction=None, val_where=None, per=None,
          seed: int = 0, progress=None, label: str = "material", unit: str = "trial") -> Model:
    """Train the model of `spec` on a frames table, validation chosen as asked (never leaking copies).
    `unit`: what one sequence is, as the progress line counts them (a trial, or a session's contact).

    `per`: the label whose values each get a share of the validation trials; default `object` (the
    thesis draws one per size) for force models, the class label for classifiers (stratified).
    """
    sch.validate(table.schema, "frames")
    name, config, fit_config = split_spec(spec)
    data = sequences(table)
    if per is not None and per not in data.labels:
        raise ModelError(f"--val-per {per}: no label column {per!r} in the frames (labels: {', '.join(data.labels) or 'none'})")
    per = per or (label if name in MATERIAL_MODELS else "object")
    if name in MATERIAL_MODELS:
        _check_classes(data, label)
    else:
        data = _with_force(data, unit, progress, val_trials)
    rng = np.random.default_rng(seed)
    where = parse_where(val_where) if isinstance(val_where, str) else val_where
    # Each member of an ensemble validates on a draw of its own, so that together they learn from
    # every trial and stop at epochs of their own (docs/design.md)
    splits = [choose_validation(data, trials=val_trials, fraction=val_fraction, where=where, per=per, rng=rng, unit=unit)
              for _ in range(getattr(config, "members", 1))]
    in_val = splits[0]
    # normalisation and the checks see the first member's training trials, as a one-GRU model's do
    train_set, val_set = data.subset(np.flatnonzero(~in_val)), data.subset(np.flatnonzero(in_val))
    accumulated = already_accumulated(table.schema)
    input_spec = input_spec_of(table.schema, accumulated)
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)
    largest = _check_training_set(name, config, train_set, label)
    if largest > RANGE_WARN_N and progress:  # as `sync` warns of a log
        progress(f"warning: the training frames carry forces up to {largest:.4g} N, beyond {RANGE_N:g} N (the largest "
                 "FlexiForce range): a log in another unit (mN, g)? the model will read in those units")
    delays = progress and _delays_note(config, train_set)
    if delays:
        progress(delays)
    if val_fraction and not in_val.any() and progress:
        progress(f"warning: --val-fraction {val_fraction:g}: no {per} value has two source trials to draw from, so no trial "
                 "is held out for validation (early stopping follows the training loss)")
    if progress:
        progress(f"{name}: {counted(len(train_set), 'training ' + unit)}, {counted(len(val_set), 'validation ' + unit)}")
    training = {
        "spec": spec,
        "fit": dataclasses.asdict(fit_config),
        "seed": seed,
        "trials": {"train": train_set.trials, "validation": val_set.trials,
                   **({"member_validation": [[data.trials[i] for i in np.flatnonzero(m)] for m in splits[1:]]} if len(splits) > 1 else {})},
        "data_history": sch.get_meta(table.schema, sch.HISTORY, []),
    }
    if hasattr(config, "accumulate") and accumulated:
        config = dataclasses.replace(config, accumulate=False)
    if name in MATERIAL_MODELS:
        return _train_material(name, config, fit_config, train_set, val_set, input_spec, training, generator, progress, label)
    return _train_force(name, config, fit_config, data, splits, train_set, input_spec, training, generator, rng, progress, largest)


def _with_force(data: Sequences, unit: str, progress=None, val_trials=None) -> Sequences:
    """A force model's sequences less those with no measured force at all (null on every frame):
    they give nothing to learn from, and a validation trial without one would score 0 and stop
    training at its first epoch. Frames without force inside the others are masked out of every
    loss (their counts still feed the model's state). Both are counted on stderr."""
    known = [int((~np.isnan(f)).sum()) for f in data.force]
    empty = [trial for trial, n in zip(data.trials, known) if n == 0]
    if len(empty) == len(data):
        return data  # refused by _check_training_set, in the words of a table without force
    asked = [trial for trial in empty if trial in set(val_trials or ())]
    if asked:
        raise ModelError(f"validation trial {asked[0]!r} has no measured force (null on every frame), so nothing to score; "
                         "check --val-trials, or the trial's force log")
    frames = sum(len(f) for f, n in zip(data.force, known) if n) - sum(known)
    if empty and progress:
        progress(f"warning: {counted(len(empty), unit)} without a measured force (null on every frame) left out of "
                 f"training and validation ({first_few(empty)})")
    if frames and progress:
        progress(f"warning: {counted(frames, 'frame')} without a measured force (null) left out of the loss; their "
                 f"events still feed the model's state")
    return data.subset([i for i, n in enumerate(known) if n]) if empty else data


FORCE_SCALE_FLOOR_N = 1e-6  # the smallest force scale, and the least force range a model is trained on


def _delays_note(config, train_set) -> str | None:
    """A warning where a time-delay network's window reaches past the start of every training trial:
    its inputs are then mostly the zeros before a trial, whatever the trial did."""
    delays, longest = getattr(config, "delays", 0), train_set.max_length()
    if delays and delays >= longest:
        return (f"warning: --delays {delays} reaches past the start of every training trial (the longest has "
                f"{counted(longest, 'frame')}): each frame's input is mostly the zeros before its trial; give fewer delays")
    return None


def _check_classes(data, label: str):
    """Every trial has a class to learn: a missing or empty label would become a class of its own, or fail later."""
    if label not in data.labels:
        return  # told by _check_training_set, with the labels there are
    missing = [trial for trial, value in zip(data.trials, data.labels[label]) if value is None or not value.strip()]
    if missing:
        raise ModelError(f"{counted(len(missing), 'trial')} with no {label} ({first_few(missing)})"
                         f"; label them, or leave them out (`neurotac select`)")


def _check_training_set(name, config, train_set, label) -> float:
    """What the training trials must hold, checked before the first progress line so that a refusal
    is the only line on stderr. Returns a force model's largest |force| in training (0 for a classifier)."""
    if name not in MATERIAL_MODELS:
        forces = np.concatenate(train_set.force)
        known = forces[~np.isnan(forces)]
        if not len(known):
            raise ModelError("the training frames carry no force (column force is empty); frame recordings that have a force log")
        sch.check_force_range(known)
        if known.min() == known.max():
            raise ModelError(f"the training frames' force is {known[0]:g} N on every frame: there is no force to learn "
                             "(did the force sensor record?)")
        if known.max() - known.min() < FORCE_SCALE_FLOOR_N:
            raise ModelError(f"the training frames' force varies over {known.max() - known.min():.3g} N only, below the "
                             f"{FORCE_SCALE_FLOOR_N:g} N a model resolves: a log in another unit (kN, MN)? give the force in newtons")
        return float(np.abs(known).max())
    if label not in train_set.labels:
        raise ModelError(f"classification needs a {label!r} label column in the frames (labels: {', '.join(train_set.labels) or 'none'})")
    classes = {v for v in train_set.labels[label] if v is not None}
    if len(classes) < 2:
        raise ModelError(f"the training trials hold {len(classes)} {label} class(es); a classifier needs at least two")
    if config.head == "lda":
        from neurotac_cli.model.material import check_discriminant_classes

        check_discriminant_classes(train_set.labels[label], name, label)
    if config.inputs == "force" and np.isnan(np.concatenate(train_set.force)).all():
        raise ModelError("material-force needs the measured force in the frames (column force is empty)")
    return 0.0


def _seconds(data):
    return [t / 1e6 for t in data.t]


def _train_force(name, config, fit_config, data, splits, train_set, input_spec, training, generator, rng, progress, largest):
    force_scale = max(largest, FORCE_SCALE_FLOOR_N)
    # kept so that `predict` can name frames busier than any it learnt from (model.predict.Outside)
    training["events_per_frame_max"] = float(max(c.reshape(len(c), -1).sum(axis=1, dtype=np.float64).max(initial=0.0)
                                                 for c in train_set.counts))
    net = _module(name).Net(config, train_set.shape)
    net.calibrate(train_set.counts, _seconds(train_set))
    if not getattr(net, "trained_by_gradient", True):
        curve = net.fit(train_set.counts, _seconds(train_set), [f / force_scale for f in train_set.force], rng, progress)
        held_out = np.flatnonzero(splits[0])
        if len(held_out):  # a closed-form fit stops on nothing, but its held-out error is still worth reading
            val = _force_tensors(data.subset(held_out), force_scale)
            with torch.no_grad():
                curve[0]["val_loss"] = float(_masked_mse(net(val["counts"], val["t"])[0], val["force"], val["mask"]))
    else:
        # fixed features (deform-gru) are computed once for every trial, not once per epoch and member
        features = net.encode(torch.as_tensor(padded(data.counts)), None) if hasattr(net, "encode") else None
        device = training_device()
        if device.type != "cpu":  # a GPU: the network and every tensor it trains on move there, and back after
            net.to(device)
            training["device"] = str(device)
        curves = [_fit_member(net, i, len(splits), data, in_val, features, force_scale, fit_config, generator, progress, name, device)
                  for i, in_val in enumerate(splits)]
        curve = curves[0]
        if len(curves) > 1:  # "curve" stays the first member's, as files of one-member models hold it
            training["member_best_epochs"] = [best_epoch(c)["epoch"] for c in curves]
            training["member_curves"] = curves
        net.to("cpu")
    input_spec = dict(input_spec, normalisation=dict(_small_buffers(net), force_scale=force_scale))
    training["curve"] = curve
    return Model(name, config, net, input_spec, None, training)


def _fit_member(net, member, members, data, in_val, features, force_scale, fit_config, generator, progress, name, device):
    """Train one member of `net` (the whole network where it has one) on the trials outside `in_val`,
    stopping early on those inside it; returns its training curve."""
    groups = []
    for indices in (np.flatnonzero(~in_val), np.flatnonzero(in_val)):
        if not len(indices):
            groups.append(None)
            continue
        part = data.subset(indices)
        group = _force_tensors(part, force_scale, counts=features is None)
        if features is not None:
            group["features"] = features[indices, : part.max_length()]
        groups.append({key: value.to(device) for key, value in group.items()})
    tensors, val_tensors = groups
    chosen = member if members > 1 else None

    def run(group, indices=slice(None)):
        if features is not None:
            return net.forward_encoded(group["features"][indices], member=chosen)
        return net(group["counts"][indices], group["t"][indices])[0]

    def batch_loss(indices):
        return _masked_mse(run(tensors, indices), tensors["force"][indices], tensors["mask"][indices])

    def val_loss():
        if val_tensors is None:
            return None
        return float(_masked_mse(run(val_tensors), val_tensors["force"], val_tensors["mask"]))

    module = net.member(member) if members > 1 else net
    label = f"{name} member {member + 1}/{members}" if members > 1 else name
    return fit(module, batch_loss, len(tensors["force"]), val_loss, fit_config, generator, progress, label=label)


def _force_tensors(data, force_scale, counts: bool = True):
    length = data.max_length()
    force = padded(data.force, length, fill=np.nan)
    mask = ~np.isnan(force)
    return {
        **({"counts": torch.as_tensor(padded(data.counts, length))} if counts else {}),
        "t": torch.as_tensor(padded(_seconds(data), length, dtype=np.float64)),
        "force": torch.as_tensor(np.nan_to_num(force) / force_scale, dtype=torch.float32),
        "mask": torch.as_tensor(mask, dtype=torch.float32),
    }


def _masked_mse(out, target, mask):
    return ((out - target) ** 2 * mask).sum() / mask.sum().clamp_min(1.0)


def _small_buffers(net) -> dict:
    """Normalisation constants (small buffers) for the readable header; the file's tensors are authoritative."""
    return {name: buf.flatten().tolist() for name, buf in net.named_buffers()
            if buf.numel() <= 64 and ("scale" in name or "mean" in name or "std" in name)}


def _train_material(name, config, fit_config, train_set, val_set, input_spec, training, generator, progress, label):
    from neurotac_cli.model import material

    classes = sorted({v for v in train_set.labels[label] if v is not None})
    index = {c: i for i, c in enumerate(classes)}

    def encode(data):
        unknown = sorted({v for v in data.labels[label] if v not in index})
        if unknown:
            raise ModelError(f"validation {label} {unknown[0]!r} does not occur in training; choose validation trials per class")
        return torch.as_tensor([index[v] for v in data.labels[label]])

    x = material.features(train_set, config)
    val_x = material.features(val_set, config) if len(val_set) else None
    if config.adapt_by:
        if config.adapt_by == label:
            raise UsageError(f"--adapt-by {label}: that is the label the classifier predicts; adapt by what sets the "
                             "grasps apart otherwise (an object size, a sensor: e.g. object, rig)")
        if config.adapt_by not in train_set.labels:
            raise ModelError(f"--adapt-by {config.adapt_by}: the training frames have no {config.adapt_by!r} label column "
                             f"(labels: {', '.join(sorted(train_set.labels)) or 'none'})")
        # validation grasps are few per domain: they take the statistics of their domain's training grasps
        pooled = (x.mean(axis=0), np.maximum(x.std(axis=0), 1e-6))
        domains = material.domains_of(train_set, config.adapt_by)
        stats = material.domain_stats(x, domains)
        x = material.standardised(x, domains, stats, pooled)
        if val_x is not None:
            val_x = material.standardised(val_x, material.domains_of(val_set, config.adapt_by), stats, pooled)
        input_spec = dict(input_spec, adapt={"by": config.adapt_by, "mean": pooled[0].tolist(), "std": pooled[1].tolist(),
                                             "stats": {domain: [mean.tolist(), std.tolist()] for domain, (mean, std) in stats.items()}})
    x, val_x = torch.as_tensor(x), None if val_x is None else torch.as_tensor(val_x)
    y = encode(train_set)
    net = material.Net(config, len(classes))
    net.calibrate(x.numpy(), y.numpy())
    val_y = encode(val_set) if len(val_set) else None
    loss = torch.nn.CrossEntropyLoss()
    curve = fit(net, lambda idx: loss(net(x[idx]), y[idx]), len(x),
                lambda: None if val_x is None else float(loss(net(val_x), val_y)), fit_config, generator, progress, label=name)
    training["curve"] = curve
    training["label"] = label
    # the features summarise a whole grasp: `classify` names trials much shorter than any learnt from
    training["trial_frames"] = [min(map(len, train_set.counts)), max(map(len, train_set.counts))]
    input_spec = dict(input_spec, normalisation={"feature_mean": net.feature_mean.tolist(), "feature_std": net.feature_std.tolist()})
    return Model(name, config, net, input_spec, classes, training)


# ---------------------------------------------------------------- running


def _predictions_schema(table_schema: pa.Schema, fields, model: Model):
    labels = sch.label_columns(table_schema)
    schema = pa.schema(list(fields) + [(name, pa.string()) for name in labels])
    entries = {"kind": "predictions", "model": {"name": model.name, "task": model.task},
               "history": sch.get_meta(table_schema, sch.HISTORY, [])}
    window = sch.get_meta(table_schema, sch.WINDOW)
    if window:
        entries["window_us"] = window
    return sch.set_meta(schema, **entries), labels


FORCE_FIELDS = [("trial", pa.string()), ("frame", pa.int32()), ("t", pa.int64()), ("phase", pa.string()),
                ("force", pa.float32()), ("force_pred", pa.float32())]


def predict_trials(model: Model, table: pa.Table) -> pa.Table:
    """Force estimates for every frame of a frames table (trials batched, each run from its start)."""
    if model.task != "force":
        raise ModelError(f"model {model.name!r} classifies materials; use `neurotac classify` or `neurotac eval`")
    check_input(model, table.schema)
    data = sequences(table)
    outputs = []
    for start in range(0, len(data), EVAL_BATCH):
        part = data.subset(range(start, min(start + EVAL_BATCH, len(data))))
        length = part.max_length()
        force, _ = model.step(padded(part.counts, length), padded(part.t, length, dtype=np.int64))
        outputs += [force[i, : len(c)] for i, c in enumerate(part.counts)]
    schema, labels = _predictions_schema(table.schema, FORCE_FIELDS, model)
    columns = {
        "trial": np.repeat(np.asarray(data.trials, dtype=object), [len(c) for c in data.counts]),
        "frame": np.concatenate(data.frame),
        "t": np.concatenate(data.t),
        "phase": np.concatenate(data.phase),
        "force": np.concatenate(data.force),
        "force_pred": np.concatenate(outputs),
    }
    for name in labels:
        columns[name] = np.repeat(np.asarray(data.labels[name], dtype=object), [len(c) for c in data.counts])
    arrays = [pa.array(columns[f.name].tolist() if f.type == pa.string() else columns[f.name], type=f.type,
                       from_pandas=True) for f in schema]
    return pa.Table.from_arrays(arrays, schema=schema)


def check_streams(model: Model):
    """`predict` and `sense` stream force models; a classifier names a contact's material beside one."""
    if model.task != "force":
        raise ModelError(f"model {model.name!r} classifies materials; `predict` and `sense` stream force models "
                         "(a classifier goes to --material-model)")


def stream_trials(model: Model, schema: pa.Schema, batches, advice: str | None = None, notes: list | None = None):
    """Predictions batch by batch as frames arrive; each trial's state is carried from frame to frame
    (`advice` as `check_input`'s; `notes` gets a line on the frames missing inside trials, once the
    batches end: the state runs over such a gap as if its frames had come).

    Returns (predictions schema, iterator of record batches).
    """
    check_streams(model)
    check_input(model, schema, advice)
    out_schema, labels = _predictions_schema(schema, FORCE_FIELDS, model)
    states, last, missing = {}, {}, {}
    # a first step pays its one-off costs (allocations, kernel choices) now, not on the first frame
    model.step(np.zeros((1, 1, len(CHANNELS), *sch.frames_shape(schema)), np.float32), np.zeros((1, 1), np.int64))

    def run():
        for batch in batches:
            if batch.num_rows == 0:
                continue
            trials = batch.column("trial").to_pylist()
            counts = sch.counts_numpy(batch.column("counts"))
            t = batch.column("t").to_numpy().astype(np.int64)
            numbers = batch.column("frame").to_numpy(zero_copy_only=False).astype(np.int64)
            prediction = np.empty(batch.num_rows, dtype=np.float32)
            edges = [0] + [i for i in range(1, len(trials)) if trials[i] != trials[i - 1]] + [len(trials)]
            for begin, end in zip(edges[:-1], edges[1:]):
                trial = trials[begin]
                before = last.get(trial)
                last[trial] = _in_order(trial, before, numbers[begin:end], t[begin:end])
                # frames strictly rising (`_in_order`): the ones skipped are the span less those given
                start = int(numbers[begin]) if before is None else before[0] + 1
                missing[trial] = missing.get(trial, 0) + int(numbers[end - 1]) - start + 1 - (end - begin)
                force, states[trial] = model.step(counts[None, begin:end], t[None, begin:end], states.get(trial))
                prediction[begin:end] = force[0]
            columns = {
                "trial": batch.column("trial"), "frame": batch.column("frame").cast(pa.int32()), "t": batch.column("t"),
                "phase": batch.column("phase"), "force": batch.column("force").cast(pa.float32()),
                "force_pred": pa.array(prediction),
            }
            for name in labels:
                columns[name] = batch.column(name)
            yield pa.RecordBatch.from_arrays([columns[f.name] for f in out_schema], schema=out_schema)
        if notes is not None:
            notes.extend(filter(None, [gaps_note(missing)]))

    return out_schema, run()


def gaps_note(missing: dict, runs: str = "ran") -> str | None:
    """A warning for frames missing inside trials ({trial: frames missing}): a model of whole trials
    carries its state over each gap as if the missing frames had come."""
    gaps = {trial: count for trial, count in missing.items() if count}
    if not gaps:
        return None
    trial, count = max(gaps.items(), key=lambda item: item[1])
    return (f"warning: {counted(sum(gaps.values()), 'frame')} missing inside {counted(len(gaps), 'trial')} ({trial}: "
            f"{count}): the model's state {runs} over each gap as if its frames had come")


def missing_frames(table: pa.Table) -> dict:
    """{trial: frame numbers missing between its first and last frame} of a frames table. A trial whose
    t goes back is refused first, as `sequences` refuses it, so that the refusal is the only line
    (not a warning about its frame numbers before it)."""
    codes, names, _, frame, _ = ordered_trials(table)  # rows by trial, then frame
    starts = np.flatnonzero(np.r_[True, np.diff(codes) != 0])
    ends = np.r_[starts[1:], len(codes)] - 1
    new = np.r_[True, (np.diff(frame) != 0) | (np.diff(codes) != 0)]  # a frame number not seen just before in its trial
    distinct = np.add.reduceat(new.astype(np.int64), starts)
    return {names[code]: int(high - low + 1 - count) for code, low, high, count in zip(codes[starts], frame[starts], frame[ends], distinct)}


def _in_order(trial: str, last: tuple | None, frames: np.ndarray, t: np.ndarray) -> tuple:
    """The (frame, t) of the last of a trial's frames, refusing frames that come before one already
    read: a stream carries each trial's state from one frame to the next, so frames out of order would
    give other estimates than `eval` (which sorts each trial's frames). Time is checked as `eval` checks it."""
    given = frames if last is None else np.concatenate([[last[0]], frames])
    times = t if last is None else np.concatenate([[last[1]], t])
    back = np.flatnonzero(np.diff(given) <= 0)
    if len(back):
        k = int(back[0])
        raise InputError(f"trial {trial!r}: frame {int(given[k + 1])} comes after frame {int(given[k])}; a stream reads each "
                         "trial's frames in the order `frame` writes them (sort the frames by trial and frame, or score the "
                         "table with `neurotac eval`, which sorts them)")
    check_time_forward(np.zeros(len(given), np.int64), [trial], given, times)
    return int(given[-1]), int(times[-1])


SHORT_SHARE = 0.5  # a trial under this share of the shortest training trial is named by `classify`


def classify_table(model: Model, table: pa.Table, notes: list | None = None) -> pa.Table:
    """One row per trial: the true class where known, the predicted class and every class's probability;
    `notes` gets what an adapted model could not standardise over the input's own grasps (`Model.proba`)."""
    if model.task != "material":
        raise ModelError(f"model {model.name!r} estimates force; use `neurotac eval` or `neurotac predict`")
    check_input(model, table.schema)
    data = sequences(table)
    shortest = (model.training.get("trial_frames") or [0])[0]
    short = [trial for trial, counts in zip(data.trials, data.counts) if len(counts) < SHORT_SHARE * shortest]
    if short and notes is not None:
        notes.append(f"{counted(len(short), 'trial')} ({first_few(short)}) hold fewer than "
                     f"half the frames of the shortest training trial ({shortest}): a part of a grasp, whose class is a guess")
    proba = model.proba(data, notes)
    label = model.training.get("label", "material")
    fields = [("trial", pa.string())]
    columns = [pa.array(data.trials, pa.string())]
    if label in data.labels:
        fields.append((label, pa.string()))
        columns.append(pa.array(data.labels[label], pa.string()))
    fields.append((f"{label}_pred", pa.string()))
    columns.append(pa.array([model.classes[i] for i in proba.argmax(axis=1)], pa.string()))
    for i, name in enumerate(model.classes):
        fields.append((f"prob_{name}", pa.float32()))
        columns.append(pa.array(proba[:, i].astype(np.float32)))
    schema = sch.set_meta(pa.schema(fields), kind="predictions", model={"name": model.name, "task": "material", "label": label},
                          history=sch.get_meta(table.schema, sch.HISTORY, []))
    return pa.Table.from_arrays(columns, schema=schema)
