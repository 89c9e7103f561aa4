"""Time-delay neural network on accumulated ON/OFF counts (thesis 3.4.3).

Input per frame: the ON and OFF event counts accumulated since the trial start (no spatial
information), with `delays` previous frames (thesis: current + 3 previous), into `layers` (k)
fully connected layers of `units` (n) sigmoid neurons and a linear output. Thesis best: k=4, n=40.
"""

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from neurotac_cli.model.base import ForceNet


@dataclass(frozen=True)
class Config:
    delays: int = 3
    layers: int = 4
    units: int = 40
    accumulate: bool = True  # False when the input counts are already accumulated (frame --accumulate)


class Net(ForceNet):
    def __init__(self, config: Config, shape):
        super().__init__()
        self.config = config
        self.register_buffer("feature_scale", torch.ones(2))
        layers, width = [], 2 * (config.delays + 1)
        for _ in range(config.layers):
            layers += [nn.Linear(width, config.units), nn.Sigmoid()]
            width = config.units
        layers.append(nn.Linear(width, 1))
        self.mlp = nn.Sequential(*layers)
        for module in self.mlp:
            if isinstance(module, nn.Linear):
                nn.init.zeros_(module.bias)

    def _accumulated(self, counts, state):
        sums = counts.sum(dim=(-1, -2))  # (B, T, 2)
        if not self.config.accumulate:
            return sums, None
        acc = torch.cumsum(sums, dim=1) + state["acc"].unsqueeze(1)
        return acc, acc[:, -1]

    def init_state(self, batch: int):
        return {"acc": self.zeros(batch, 2), "past": self.zeros(batch, self.config.delays, 2)}

    def forward(self, counts, t_s, state=None):
        batch, length = counts.shape[:2]
        state = state or self.init_state(batch)
        features, acc = self._accumulated(counts, state)
        features = features / self.feature_scale
        history = torch.cat([state["past"], features], dim=1)
        delays = self.config.delays
        window = torch.cat([history[:, delays - d : delays - d + length] for d in range(delays + 1)], dim=-1)
        force = self.mlp(window).squeeze(-1)
        new = {"acc": acc if acc is not None else state["acc"], "past": history[:, history.shape[1] - delays :]}
        return force, new

    def calibrate(self, counts, t_s):
        peak = np.ones(2)
        for c in counts:
            sums = c.reshape(len(c), 2, -1).sum(axis=2).astype(np.float64)
            features = np.cumsum(sums, axis=0) if self.config.accumulate else sums
            if len(features):
                peak = np.maximum(peak, features.max(axis=0))
        self.feature_scale.copy_(torch.as_tensor(peak, dtype=torch.float32))
