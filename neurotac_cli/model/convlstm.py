"""ConvLSTM (thesis 4.4.2): LSTM gates computed by convolutions, so hidden states keep the frame's
spatial layout. Thesis: 4 ConvLSTM layers of 3 filters 3x3 with zero padding, dropout 0.4 after
the first three, a dense head; orthogonal initialisation of the recurrent kernels.

Each layer convolves its whole input sequence at once (one batched call) and only the recurrent
convolution runs frame by frame.
"""

from dataclasses import dataclass

import torch
from torch import nn

from neurotac_cli.model.base import CountScaledNet


@dataclass(frozen=True)
class Config:
    layers: int = 4
    filters: int = 3
    kernel: int = 3
    dropout: float = 0.4
    dense: int = 0  # hidden units of the dense head; 0 = one linear layer on the flattened last state


class Cell(nn.Module):
    def __init__(self, inputs: int, filters: int, kernel: int):
        super().__init__()
        self.filters = filters
        self.input_conv = nn.Conv2d(inputs, 4 * filters, kernel, padding=kernel // 2)
        self.recurrent_conv = nn.Conv2d(filters, 4 * filters, kernel, padding=kernel // 2, bias=False)
        nn.init.orthogonal_(self.recurrent_conv.weight)
        with torch.no_grad():  # forget-gate bias 1, as Keras's unit_forget_bias
            self.input_conv.bias.zero_()
            self.input_conv.bias[filters : 2 * filters] = 1.0

    def forward(self, x, h, c):
        batch, length = x.shape[:2]
        gates_x = self.input_conv(x.reshape(batch * length, *x.shape[2:])).reshape(batch, length, 4 * self.filters, *x.shape[3:])
        outputs = []
        for gates_in in gates_x.unbind(1):  # unbind, not indexing: one backward copy instead of one per frame
            gates = gates_in + self.recurrent_conv(h)
            i, f, o, g = torch.split(gates, self.filters, dim=1)
            c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
            h = torch.sigmoid(o) * torch.tanh(c)
            outputs.append(h)
        return torch.stack(outputs, dim=1), h, c


class Net(CountScaledNet):
    def __init__(self, config: Config, shape):
        super().__init__(config)
        _, height, width = shape
        self.shape = (height, width)
        self.cells = nn.ModuleList(
            Cell(2 if index == 0 else config.filters, config.filters, config.kernel) for index in range(config.layers)
        )
        self.dropout = nn.Dropout(config.dropout)
        flat = config.filters * height * width
        if config.dense:
            self.head = nn.Sequential(nn.Linear(flat, config.dense), nn.ReLU(), nn.Linear(config.dense, 1))
        else:
            self.head = nn.Linear(flat, 1)

    def init_state(self, batch: int):
        zeros = torch.zeros(batch, self.config.filters, *self.shape)
        return {f"{kind}{index}": zeros.clone() for index in range(self.config.layers) for kind in "hc"}

    def forward(self, counts, t_s, state=None):
        batch, length = counts.shape[:2]
        state = state or self.init_state(batch)
        x = self.scaled(counts)
        new = {}
        for index, cell in enumerate(self.cells):
            x, h, c = cell(x, state[f"h{index}"], state[f"c{index}"])
            new[f"h{index}"], new[f"c{index}"] = h, c
            if index < len(self.cells) - 1:
                x = self.dropout(x)
        return self.head(x.reshape(batch, length, -1)).squeeze(-1), new
