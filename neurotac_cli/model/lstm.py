"""Stacked LSTM on flattened frames (thesis 4.4.1): LSTM cells operate on vectors, so each frame's
2 x H x W counts are flattened. Thesis best: 6 LSTM layers; orthogonal recurrent initialisation."""

from dataclasses import dataclass

from torch import nn

from neurotac_cli.model.base import CountScaledNet, orthogonal_recurrent


@dataclass(frozen=True)
class Config:
    layers: int = 6
    units: int = 32
    dropout: float = 0.0


class Net(CountScaledNet):
    def __init__(self, config: Config, shape):
        super().__init__(config)
        _, height, width = shape
        self.lstm = nn.LSTM(2 * height * width, config.units, num_layers=config.layers, batch_first=True,
                            dropout=config.dropout if config.layers > 1 else 0.0)
        orthogonal_recurrent(self.lstm)
        self.head = nn.Linear(config.units, 1)

    def init_state(self, batch: int):
        zeros = self.zeros(self.config.layers, batch, self.config.units)
        return {"h": zeros, "c": zeros.clone()}

    def forward(self, counts, t_s, state=None):
        batch, length = counts.shape[:2]
        state = state or self.init_state(batch)
        x = (self.scaled(counts)).reshape(batch, length, -1)
        out, (h, c) = self.lstm(x, (state["h"], state["c"]))
        return self.head(out).squeeze(-1), {"h": h, "c": c}
