"""CNN-LSTM (thesis 4.4.3): convolutional layers extract features of each frame, an LSTM models
them over time, a dense layer gives the force. Thesis: 4 convolutional layers of 3 filters 3x3 with
zero padding, dropout 0.4 after the first three."""

from dataclasses import dataclass

from torch import nn

from neurotac_cli.model.base import CountScaledNet, orthogonal_recurrent


@dataclass(frozen=True)
class Config:
    layers: int = 4
    filters: int = 3
    kernel: int = 3
    dropout: float = 0.4
    units: int = 32


class Net(CountScaledNet):
    def __init__(self, config: Config, shape):
        super().__init__(config)
        _, height, width = shape
        blocks, channels = [], 2
        for index in range(config.layers):
            blocks += [nn.Conv2d(channels, config.filters, config.kernel, padding=config.kernel // 2), nn.ReLU()]
            if min(height, width) >= 2:
                blocks.append(nn.MaxPool2d(2))
                height, width = height // 2, width // 2
            if index < config.layers - 1 and config.dropout > 0:
                blocks.append(nn.Dropout(config.dropout))
            channels = config.filters
        self.cnn = nn.Sequential(*blocks)
        self.lstm = nn.LSTM(channels * height * width, config.units, batch_first=True)
        orthogonal_recurrent(self.lstm)
        self.head = nn.Linear(config.units, 1)

    def init_state(self, batch: int):
        zeros = self.zeros(1, batch, self.config.units)
        return {"h": zeros, "c": zeros.clone()}

    def forward(self, counts, t_s, state=None):
        batch, length = counts.shape[:2]
        state = state or self.init_state(batch)
        x = (self.scaled(counts)).reshape(batch * length, *counts.shape[2:])
        features = self.cnn(x).reshape(batch, length, -1)
        out, (h, c) = self.lstm(features, (state["h"], state["c"]))
        return self.head(out).squeeze(-1), {"h": h, "c": c}
