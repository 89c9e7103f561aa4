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

Inputs are standardised with constants fitted on training trials (buffers saved in the model file).
"""

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from neurotac_cli.model.data import Sequences, resample


@dataclass(frozen=True)
class Config:
    inputs: str = "events"  # events | force | curves
    layers: int = 2
    units: int = 30
    points: int = 30
    dropout: float = 0.0
    accumulate: bool = True  # False when the input counts are already accumulated (frame --accumulate)


PRESETS = {
    "material-dnn": Config(),
    "material-force": Config(inputs="force"),
    "material-curves": Config(inputs="curves", layers=1, units=30),
}


def features(data: Sequences, config: Config) -> np.ndarray:
    """(n_trials, n_features) inputs of the classifier."""
    return np.stack([_trial_features(c, f, config) for c, f in zip(data.counts, data.force)]).astype(np.float32)


def feature_count(config: Config) -> int:
    return {"events": 2 * config.points, "force": config.points, "curves": 4 * config.points}[config.inputs]


def _trial_features(counts: np.ndarray, force: np.ndarray, config: Config) -> np.ndarray:
    points = config.points
    if config.inputs == "force":
        return resample(np.nan_to_num(force.astype(np.float64)), points)
    sums = counts.reshape(len(counts), 2, -1).sum(axis=2).astype(np.float64)
    acc = np.cumsum(sums, axis=0) if config.accumulate else sums
    if config.inputs == "events":
        return resample(acc, points).T.reshape(-1)
    totals = acc[-1] if len(acc) else np.zeros(2)
    shape = acc / np.maximum(totals, 1.0)
    return np.concatenate([np.log1p(resample(acc, points)).T.reshape(-1), resample(shape, points).T.reshape(-1)])


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

    def calibrate(self, x: np.ndarray):
        x = torch.as_tensor(x)
        self.feature_mean.copy_(x.mean(dim=0))
        self.feature_std.copy_(x.std(dim=0, unbiased=False).clamp_min(1e-6))

    def forward(self, x):
        return self.mlp((x - self.feature_mean) / self.feature_std)

    def prepare_for(self, tensors):
        pass
