"""Data shaping: frames tables -> per-trial sequences, splits that never leak, padded tensors.

A trial is one learning sample. Augmented copies carry `source_trial` (the original's id); every
split here works on source groups, so a trial and its copies always fall on the same side.
"""

from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from neurotac_cli import schema as sch
from neurotac_cli.errors import ModelError, SchemaError, UsageError
from neurotac_cli.units import counted


@dataclass
class Sequences:
    """Frames grouped by trial, in order of first appearance, each trial sorted by frame."""

    trials: list
    counts: list  # (T, 2, H, W) arrays, raw counts
    t: list  # (T,) int64 µs from the trial's t0
    frame: list  # (T,) int32
    force: list  # (T,) float32, NaN where unknown
    phase: list  # (T,) object (str or None)
    labels: dict = field(default_factory=dict)  # label -> list of one value per trial
    source: list = field(default_factory=list)  # source trial per trial (itself for originals)
    augmented: list = field(default_factory=list)  # bool per trial

    def __len__(self):
        return len(self.trials)

    def subset(self, indices) -> "Sequences":
        indices = list(indices)
        pick = lambda values: [values[i] for i in indices]  # noqa: E731
        return Sequences(
            trials=pick(self.trials), counts=pick(self.counts), t=pick(self.t), frame=pick(self.frame),
            force=pick(self.force), phase=pick(self.phase),
            labels={name: pick(values) for name, values in self.labels.items()},
            source=pick(self.source), augmented=pick(self.augmented),
        )

    @property
    def shape(self) -> tuple:
        return tuple(self.counts[0].shape[1:]) if self.counts else (2, 0, 0)

    def max_length(self) -> int:
        return max((len(c) for c in self.counts), default=0)


def sequences(table: pa.Table) -> Sequences:
    """Group a frames table into per-trial sequences (vectorised: one sort, one split)."""
    if table.num_rows == 0:
        raise ModelError("the frames table is empty (no rows); did the command before it fail?")
    codes, names, order, frame, t = ordered_trials(table)
    bounds = np.flatnonzero(np.diff(codes)) + 1
    starts = np.concatenate([[0], bounds])
    counts = sch.counts_numpy(table.column("counts"))[order]
    force_column = table.column("force").cast(pa.float32())
    sch.check_force(pc.drop_null(force_column).to_numpy(), "the frames' force column")  # null = unknown; NaN is an error
    force = force_column.fill_null(np.nan).to_numpy(zero_copy_only=False)[order]
    phase = np.asarray(table.column("phase").to_pylist(), dtype=object)[order]
    frames = frame.astype(np.int32)
    split = lambda values: np.split(values, bounds)  # noqa: E731
    trials = [names[c] for c in codes[starts]]
    label_names = sch.label_columns(table.schema)
    # a session's trial holds many grasps, whose labels (object, material) may change with them
    session = "grasp" in table.schema.names and pa.types.is_integer(table.schema.field("grasp").type)
    for name in label_names if not session else ():
        _check_one_value_per_trial(table.column(name), order, codes, names, name)
    labels = {name: _first_per_trial(table.column(name), order, starts) for name in label_names}
    if "source_trial" in table.schema.names:
        source = [s if s else trial for s, trial in zip(_first_per_trial(table.column("source_trial"), order, starts), trials)]
    else:
        source = list(trials)
    if "augment" in table.schema.names:
        augmented = [bool(a) for a in _first_per_trial(table.column("augment"), order, starts)]
    else:
        augmented = [s != trial for s, trial in zip(source, trials)]
    return Sequences(
        trials=trials, counts=split(counts), t=split(t), frame=split(frames), force=split(force),
        phase=split(phase), labels=labels, source=source, augmented=augmented,
    )


def ordered_trials(table: pa.Table) -> tuple:
    """(each row's trial code, the trial names, the order, frame and t), rows in trial-then-frame
    order; a trial whose time goes back is refused (`check_time_forward`)."""
    encoded = pc.dictionary_encode(table.column("trial")).combine_chunks()
    codes = encoded.indices.to_numpy(zero_copy_only=False).astype(np.int64)
    names = encoded.dictionary.to_pylist()
    frame = table.column("frame").to_numpy().astype(np.int64)
    order = np.lexsort((frame, codes))
    codes, frame, t = codes[order], frame[order], table.column("t").to_numpy().astype(np.int64)[order]
    check_time_forward(codes, names, frame, t)
    return codes, names, order, frame, t


def check_time_forward(codes: np.ndarray, names, frame: np.ndarray, t: np.ndarray) -> None:
    """Refuse a trial whose window start `t` falls from one frame to the next (rows grouped by trial
    code, each trial in frame order): the models read each frame's time from `t` (the GP's time input,
    the gap between recurrent steps) and the scores time their drift by it, so time running back
    would turn their trends round without a word."""
    back = np.flatnonzero((t[1:] < t[:-1]) & (codes[1:] == codes[:-1]))
    if len(back):
        k = int(back[0])
        raise SchemaError(f"trial {names[codes[k]]!r}: t goes back from {int(t[k])} µs at frame {int(frame[k])} to "
                          f"{int(t[k + 1])} µs at frame {int(frame[k + 1])}; each frame's window starts after the one "
                          "before it (make the frames again with `neurotac frame`, or correct t)")


def _check_one_value_per_trial(column, order, codes, names, label: str):
    """Refuse a label whose value changes inside a trial: a trial is one sample with one label, and
    reading its first frame's would train on (or score against) a value the rest of it contradicts."""
    encoded = pc.dictionary_encode(column).combine_chunks()
    values = encoded.indices.fill_null(-1).to_numpy(zero_copy_only=False)[order]
    changed = np.flatnonzero((values[1:] != values[:-1]) & (codes[1:] == codes[:-1]))
    if len(changed):
        trial = names[codes[changed[0]]]
        inside = np.asarray(column.to_pylist(), dtype=object)[order][codes == codes[changed[0]]]
        seen = sorted({str(v) for v in inside if v is not None})
        if len(seen) == 1:  # one value, and frames without it
            missing = sum(v is None for v in inside)
            raise ModelError(f"trial {trial!r}: {label} is {seen[0]!r} on some frames and missing (null) on {counted(missing, 'frame')}; "
                             "a label holds one value per trial: fill it in")
        raise ModelError(f"trial {trial!r} has more than one {label} ({', '.join(seen[:4])}); a label holds one value "
                         "per trial: correct it, or give the parts trial ids of their own")


def _first_per_trial(column, order, starts) -> list:
    values = np.asarray(column.to_pylist(), dtype=object)[order]
    return [None if v is None else str(v) for v in values[starts]]


# ---------------------------------------------------------------- splits


def parse_where(text: str) -> tuple[str, str]:
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise ModelError(f"expected LABEL=VALUE such as object=bolt15, got {text!r}")
    return name.strip(), value.strip()


def rows_where(data: Sequences, where: tuple[str, str]) -> np.ndarray:
    name, value = where
    if name not in data.labels:
        raise ModelError(
            f"no label column {name!r} in the frames (labels: {', '.join(data.labels) or 'none'}); "
            "choose one of them"
        )
    return np.array([v == value for v in data.labels[name]], dtype=bool)


def check_no_leak(data: Sequences, in_val: np.ndarray, what: str = "validation"):
    """Refuse a split where a trial and any augmented copy (same source_trial) fall on both sides."""
    sources = np.asarray(data.source, dtype=object)
    held = set(sources[in_val])
    kept = set(sources[~in_val])
    both = sorted(held & kept)
    if both:
        raise ModelError(
            f"trial {both[0]!r} and its augmented copies fall on both sides of the {what} split "
            f"({len(both)} source trials leak); choose {what} trials by source trial (all copies on one side), "
            "e.g. with --val-fraction or --val-where"
        )


def choose_validation(data: Sequences, *, trials=None, fraction=None, where=None, per="object",
                      rng: np.random.Generator | None = None, unit: str = "trial") -> np.ndarray:
    """A boolean mask of validation trials: by ids, by a label value, or a fraction drawn per `per` label.
    `unit`: what one sequence is, as the errors name it (a trial, or a session's contact).

    Validation always holds whole source groups; explicit choices that split a group are refused.
    """
    n = len(data)
    given = [flag for flag, value in (("--val-trials", trials), ("--val-where", where), ("--val-fraction", fraction)) if value]
    if len(given) > 1:
        raise UsageError(f"{' and '.join(given)} each choose the validation trials; give one of them")
    if trials:
        wanted = set(trials)
        unknown = wanted - set(data.trials) - set(data.source)
        if unknown:
            raise ModelError(f"validation trial {sorted(unknown)[0]!r} is not in the frames; check --val-trials")
        mask = np.array([t in wanted for t in data.trials], dtype=bool)
        check_no_leak(data, mask)
    elif where is not None:
        mask = rows_where(data, where)
        if not mask.any():
            values = sorted({str(v) for v in data.labels[where[0]]})
            raise ModelError(f"no trial has {where[0]}={where[1]} to validate on ({where[0]}: {', '.join(values[:8])}); check --val-where")
        check_no_leak(data, mask)
    elif fraction:
        mask = _fraction_per_group(data, fraction, per, rng or np.random.default_rng(0))
    else:
        mask = np.zeros(n, dtype=bool)
    if mask.all():
        raise ModelError(f"every {unit} would be in validation, leaving none to train on; choose fewer validation {unit}s")
    return mask


def _fraction_per_group(data: Sequences, fraction: float, per: str, rng) -> np.ndarray:
    """Draw round(fraction * n) source groups (at least one) per value of the `per` label (thesis 4.5.3)."""
    sources = np.asarray(data.source, dtype=object)
    groups = data.labels.get(per) or ["all"] * len(data)
    chosen = set()
    for value in sorted(set(groups), key=str):
        candidates = sorted({s for s, g in zip(sources, groups) if g == value})
        if len(candidates) < 2:
            continue
        take = max(1, int(round(fraction * len(candidates))))
        take = min(take, len(candidates) - 1)
        chosen.update(rng.choice(candidates, size=take, replace=False).tolist())
    return np.array([s in chosen for s in sources], dtype=bool)


# ---------------------------------------------------------------- tensors


def padded(arrays: list, length: int | None = None, fill=0.0, dtype=np.float32) -> np.ndarray:
    """Stack variable-length arrays (T_i, ...) into (N, T, ...) padded at the end."""
    length = length or max(len(a) for a in arrays)
    out = np.full((len(arrays), length, *arrays[0].shape[1:]), fill, dtype=dtype)
    for i, a in enumerate(arrays):
        out[i, : len(a)] = a[:length]
    return out


def resample(curve: np.ndarray, points: int) -> np.ndarray:
    """A curve (T, ...) resampled to `points` samples by linear interpolation over its length."""
    curve = np.asarray(curve, dtype=np.float64)
    if len(curve) == 0:
        return np.zeros((points, *curve.shape[1:]))
    if len(curve) == 1:
        return np.repeat(curve, points, axis=0)
    where = np.linspace(0, len(curve) - 1, points)
    left = np.floor(where).astype(int)
    right = np.minimum(left + 1, len(curve) - 1)
    share = (where - left).reshape(-1, *([1] * (curve.ndim - 1)))
    return curve[left] * (1 - share) + curve[right] * share


def already_accumulated(schema: pa.Schema) -> bool:
    """True when a step of the table's history accumulated counts since the trial start (frame --accumulate)."""
    for step in sch.get_meta(schema, sch.HISTORY, []) or []:
        args = step.get("args", {}) if isinstance(step, dict) else {}
        if args.get("accumulate"):
            return True
    return False
