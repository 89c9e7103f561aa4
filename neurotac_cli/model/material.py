"""Material classifiers, one prediction per trial (thesis 3.5).

- `material-dnn` (the thesis): the accumulated ON and OFF counts of the trial, resampled to `points`
  samples each (the thesis's 2 x 30 input), into `layers` (k) x `units` (n) sigmoid layers and a
  softmax. Thesis best: k=2, n=30.
- `material-force` (the thesis's piezoresistive comparison): the same network on the measured force
  trace alone.
- `material-curves`: the accumulation curves on a log scale (log1p) beside the same curves divided by
  their final totals (their shape: *when* each polarity's events came, which carries the stiffness,
  separated from *how many*, which mostly carries the force), into one layer of 30 sigmoid units.
  Separating the two lets the network weigh the stiffness apart from the force (its accuracy
  against the thesis DNN's: docs/design.md).
- `material-timing`: when the loading's OFF events come (`dynamics`: a softer object loads more
  slowly for the same force) beside the amounts of OFF and ON events, 11 numbers, classified by linear discriminant analysis: class means and one covariance pooled
  within classes, fitted in closed form, which weighs the strongly correlated rise times against
  each other better than a small network trained on 40-odd grasps (docs/design.md). The training
  loop then fits only the scale of its logits (a temperature), which leaves its decisions alone.
- `material-rises`: the same discriminant on the six rise times alone. The amounts count events,
  which grow with the face's area and with the force: within one object size and a gripper whose
  squeeze follows the material they help, but on a size training did not hold, or with a force drawn
  apart from the material, they mislead (docs/design.md has both sides' figures).

Every input but the force reads a trial's press as the polarity that had half its events first (a
bright object presses with ON events, a dark one with OFF: `_press_first`). Inputs are standardised
with constants fitted on training trials (buffers saved in the model file).
"""

import collections
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from neurotac_cli.errors import ModelError
from neurotac_cli.model.data import Sequences, resample
from neurotac_cli.units import counted, first_few


@dataclass(frozen=True)
class Config:
    inputs: str = "events"  # events | force | curves | timing | rises
    layers: int = 2
    units: int = 30
    points: int = 30
    dropout: float = 0.0
    accumulate: bool = True  # False when the input counts are already accumulated (frame --accumulate)
    head: str = "mlp"  # mlp | lda (closed-form linear discriminant, then a fitted temperature)
    adapt_by: str | None = None  # a label whose values are domains (object sizes, sensors): features standardised per domain
    press_first: bool = True  # a trial's polarity that came first read as the press (`_press_first`; files without it: False)


PRESETS = {
    "material-dnn": Config(),
    "material-force": Config(inputs="force"),
    "material-curves": Config(inputs="curves", layers=1, units=30),
    "material-timing": Config(inputs="timing", layers=0, head="lda"),
    "material-rises": Config(inputs="rises", layers=0, head="lda"),
}
ABSENT_MEANS = {"press_first": False}  # a model file written before read its trials' polarities as framed
LDA_RIDGE = 1e-3  # added to the pooled covariance of the standardised features, so it always inverts


def features(data: Sequences, config: Config) -> np.ndarray:
    """(n_trials, n_features) inputs of the classifier."""
    if config.inputs == "force":  # an unmeasured trace would be read as a grasp of no force
        blind = [trial for trial, f in zip(data.trials, data.force) if np.isnan(f).all()]
        if blind:
            raise ModelError(f"material-force reads the measured force, and {counted(len(blind), 'trial')} "
                             f"({first_few(blind)}) have none (column force is empty)")
    return np.stack([_trial_features(c, f, config) for c, f in zip(data.counts, data.force)]).astype(np.float32)


def feature_count(config: Config) -> int:
    widths = {"events": 2 * config.points, "force": config.points, "curves": 4 * config.points, "timing": DYNAMICS, "rises": RISES}
    return widths[config.inputs]


def _trial_features(counts: np.ndarray, force: np.ndarray, config: Config) -> np.ndarray:
    points = config.points
    if config.inputs == "force":
        return resample(np.nan_to_num(force.astype(np.float64)), points)
    sums = counts.reshape(len(counts), 2, -1).sum(axis=2).astype(np.float64)
    sums = _press_first(sums, config.accumulate) if config.press_first else sums
    if config.inputs in ("timing", "rises"):
        return dynamics(sums)[: RISES if config.inputs == "rises" else DYNAMICS]
    acc = np.cumsum(sums, axis=0) if config.accumulate else sums
    if config.inputs == "events":
        return resample(acc, points).T.reshape(-1)
    totals = acc[-1] if len(acc) else np.zeros(2)
    shape = acc / np.maximum(totals, 1.0)
    return np.concatenate([np.log1p(resample(acc, points)).T.reshape(-1), resample(shape, points).T.reshape(-1)])


def _press_first(sums: np.ndarray, accumulate: bool = True) -> np.ndarray:
    """A trial's OFF and ON sums per frame (accumulated already where not `accumulate`), the polarity
    its press makes first: a bright object pressed into the membrane brightens it (ON as it presses,
    OFF as it lets go), the reverse of a dark one, and a classifier of one kind's grasps reads the
    other's as another material. Told by which polarity had half its events first (an independent
    generator's 96 grasps of dark and bright objects: 93 right; ours, dark: ON never first), after
    the first frame, where a trial's sync blink falls."""
    curve = np.cumsum(sums, axis=0) if accumulate else sums
    curve = curve[1:] - curve[:1]
    if len(curve) == 0 or (curve[-1] <= 0).any():
        return sums
    off_half, on_half = (_crossing(curve[:, k], (0.5,))[0] for k in (0, 1))
    return sums[:, ::-1] if on_half < off_half else sums


DYNAMICS = 11  # features of `dynamics`
RISES = 6  # its first six: the loading's rise times

# Per-domain standardisation (`Config.adapt_by`). The features that name a material on one object
# size or sensor move with the size or sensor as a whole (a larger face is stiffer at the same
# material, a stiffer membrane makes every rise faster): standardised within each domain, what is
# left is how the grasps of that domain differ from one another, which the material carries. It is
# transductive: a domain's statistics come from its own grasps, so the input must hold enough of
# them, about balanced across the classes (docs/design.md, "Materials on a domain training never saw").
MIN_DOMAIN_TRIALS = 8  # a domain with fewer grasps in the input takes its training figures (the pooled ones if training lacked it)


def domains_of(data: Sequences, label: str) -> np.ndarray:
    """Each trial's domain: its value of `label`, or one domain for all where the input has no such label.
    A trial without a value is refused: it would be standardised with grasps of another domain."""
    values = data.labels.get(label)
    if values is None:
        return np.asarray(["all"] * len(data), dtype=object)
    missing = [trial for trial, value in zip(data.trials, values) if value is None or not str(value).strip()]
    if missing:
        raise ModelError(f"{len(missing)} trial(s) with no {label} ({first_few(missing)}); "
                         f"a model adapted by {label} standardises each {label} apart: label them, or leave them out")
    return np.asarray([str(v) for v in values], dtype=object)


def fallback_notes(domains: np.ndarray, adapt: dict, labelled: bool) -> list[str]:
    """A line for each domain of the input too small to be standardised over its own grasps, saying
    whose figures it took instead (`Model.proba`)."""
    notes = []
    for domain, count in collections.Counter(domains.tolist()).items():
        if count >= MIN_DOMAIN_TRIALS:
            continue
        what = f"{adapt['by']} {domain}" if labelled else f"the input (no {adapt['by']} column: one domain)"
        whose = f"the training's figures for {domain}" if domain in adapt["stats"] else "the training grasps' figures, pooled"
        notes.append(f"{what}: {count} trial(s), fewer than the {MIN_DOMAIN_TRIALS} to standardise over its own, so {whose}; "
                     "give a new size's or sensor's grasps together, about balanced across the classes")
    return notes


def domain_stats(x: np.ndarray, domains: np.ndarray, least: int = 1) -> dict:
    """{domain: (mean, std)} of the features of each domain with at least `least` trials."""
    stats = {}
    for domain in dict.fromkeys(domains.tolist()):
        rows = x[domains == domain]
        if len(rows) >= least:
            stats[domain] = (rows.mean(axis=0), np.maximum(rows.std(axis=0), 1e-6))
    return stats


def standardised(x: np.ndarray, domains: np.ndarray, stats: dict, pooled: tuple) -> np.ndarray:
    """Each trial's features standardised by its domain's (mean, std), or by `pooled` where its domain has none."""
    out = (x - pooled[0]) / pooled[1]
    for domain, (mean, std) in stats.items():
        mine = domains == domain
        out[mine] = (x[mine] - mean) / std
    return out.astype(np.float32)


def _crossing(curve: np.ndarray, shares) -> np.ndarray:
    """Fractional frame at which an accumulating curve first reaches each share of its final value."""
    total = curve[-1] if len(curve) else 0.0
    if total <= 0:
        return np.zeros(len(shares))
    return np.interp(np.asarray(shares) * total, curve, np.arange(len(curve), dtype=np.float64))


def dynamics(rates: np.ndarray) -> np.ndarray:
    """How a grasp's loading unfolds in time, as numbers that depend on the material more than on
    the force: the loading's OFF burst (the membrane darkens as it is pressed) rises more slowly into
    a softer object (the gripper travels further for the same force: travel = force / stiffness of
    membrane and object in series), so the frames at which the OFF events reach 10-70% of their
    total, counted from 5%, carry the stiffness. Beside them the amounts (log totals and peak rates
    of OFF and, after the loading's peak, ON events) and the ON/OFF ratio, which carry the force the
    rise times are read against. The release's fall times, the share of events while held and the
    contact's extent were tried and left out: they separated no materials and made the discriminant
    noisier (docs/journal.md).

    `rates`: (T, 2) OFF and ON events per frame (the frames' channel order).
    """
    press, lift = rates[:, 0], rates[:, 1]
    if not len(press) or press.sum() <= 0:
        return np.zeros(DYNAMICS)
    late_on = np.where(np.arange(len(lift)) >= int(np.argmax(press)), lift, 0.0)  # the sync LED's ON events come before
    rise = _crossing(np.cumsum(press), (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.7))
    log = np.log1p
    return np.concatenate([
        log(rise[1:] - rise[0]),
        log([press.sum(), late_on.sum(), press.max(), late_on.max()]),
        [log(late_on.sum()) - log(press.sum())],
    ])


def discriminant(z: np.ndarray, y: np.ndarray, classes: int) -> tuple:
    """Linear discriminant analysis: the weights and biases of the linear logits
    w_k = S^-1 mu_k, b_k = -mu_k S^-1 mu_k / 2 + log prior_k, with S the covariance pooled within
    classes (plus a small ridge). A class absent from `y` gets a logit that never wins."""
    weight, bias = np.zeros((classes, z.shape[1])), np.full(classes, -1e9)
    centred = np.concatenate([z[y == k] - z[y == k].mean(axis=0) for k in range(classes) if (y == k).any()])
    pooled = centred.T @ centred / max(len(z) - classes, 1) + LDA_RIDGE * np.eye(z.shape[1])
    for k in range(classes):
        if (y == k).any():
            mean = z[y == k].mean(axis=0)
            weight[k] = np.linalg.solve(pooled, mean)
            bias[k] = -0.5 * mean @ weight[k] + np.log((y == k).mean())
    return weight, bias


def check_discriminant_classes(values: list, name: str, label: str):
    """Refuse a discriminant where no class has two training trials (`values`: each training trial's
    class): the covariance is pooled within classes, so then it holds no spread but the ridge, and the
    fit is certain (probabilities exactly 0 and 1) and wrong on any other grasp. A class of one trial
    beside classes of several is placed by its one grasp against the others' spread."""
    counts = collections.Counter(v for v in values if v is not None)
    if counts and max(counts.values()) < 2:
        raise ModelError(f"{name} pools a spread within each {label} and needs a {label} with at least 2 training "
                         f"trials; training holds one of each ({first_few(sorted(counts))}): give more trials, or hold "
                         "fewer out (--val-fraction 0, --val-trials)")


class Net(nn.Module):
    task = "material"

    def __init__(self, config: Config, classes: int):
        super().__init__()
        self.config = config
        width = feature_count(config)
        self.register_buffer("feature_mean", torch.zeros(width))
        self.register_buffer("feature_std", torch.ones(width))
        layers = []
        for _ in range(config.layers):
            layers += [nn.Linear(width, config.units), nn.Sigmoid()]
            if config.dropout:
                layers.append(nn.Dropout(config.dropout))
            width = config.units
        layers.append(nn.Linear(width, classes))
        self.mlp = nn.Sequential(*layers)
        if config.head == "lda":
            self.mlp.requires_grad_(False)
            self.log_temperature = nn.Parameter(torch.zeros(()))

    def calibrate(self, x: np.ndarray, y: np.ndarray | None = None):
        x = torch.as_tensor(x)
        self.feature_mean.copy_(x.mean(dim=0))
        self.feature_std.copy_(x.std(dim=0, unbiased=False).clamp_min(1e-6))
        if self.config.head == "lda":
            z = ((x - self.feature_mean) / self.feature_std).double().numpy()
            weight, bias = discriminant(z, np.asarray(y), self.mlp[-1].out_features)
            self.mlp[-1].weight.copy_(torch.as_tensor(weight))
            self.mlp[-1].bias.copy_(torch.as_tensor(bias))

    def forward(self, x):
        logits = self.mlp((x - self.feature_mean) / self.feature_std)
        return logits * self.log_temperature.exp() if self.config.head == "lda" else logits

    def prepare_for(self, tensors):
        pass
