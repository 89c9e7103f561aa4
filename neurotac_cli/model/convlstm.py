"""ConvLSTM (thesis 4.4.2): LSTM gates computed by convolutions, so hidden states keep the frame's
spatial layout. Thesis: 4 ConvLSTM layers of 3 filters 3x3 with zero padding, dropout 0.4 after
the first three, a dense head; orthogonal initialisation of the recurrent kernels.

The parameters are those of the plain formulation (`reference_forward`: an input convolution over
the whole sequence, a recurrent convolution per frame, layer after layer). `Net.forward` computes
the same function faster on a CPU (docs/design.md, "ConvLSTM on a CPU"): channels-last tensors, one
convolution per frame and layer over the input and the previous hidden state together, all layers
advanced frame by frame, a fused gate function, and cheaper dropout masks.
"""

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

from neurotac_cli.model.base import CountScaledNet
from neurotac_cli.model.convlstm_ops import dropout_masks, gate_scale, joint_input, lstm_gates


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

    def joint_kernel(self):
        """Input and recurrent kernels as one (convolving [x, h] gives both convolutions summed) and the
        bias, with the g gate's outputs doubled for `lstm_gates`."""
        scale = gate_scale(self.filters, self.input_conv.weight)
        weight = torch.cat([self.input_conv.weight, self.recurrent_conv.weight], dim=1) * scale.view(-1, 1, 1, 1)
        return weight, self.input_conv.bias * scale

    def step(self, x, h, c, kernel):
        """One frame, channels last: x (B, H, W, inputs), h and c (B, H, W, filters) -> new h, c."""
        joint = joint_input(x, h).permute(0, 3, 1, 2)  # NCHW view of channels-last memory
        gates = F.conv2d(joint, *kernel, padding=self.input_conv.padding).permute(0, 2, 3, 1)
        return lstm_gates(gates, c)

    def forward(self, x, h, c):
        """The plain formulation (x: B, T, inputs, H, W; h, c: B, filters, H, W), the reference of `step`."""
        batch, length = x.shape[:2]
        gates_x = self.input_conv(x.reshape(batch * length, *x.shape[2:])).reshape(batch, length, 4 * self.filters, *x.shape[3:])
        outputs = []
        for gates_in in gates_x.unbind(1):
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
        zeros = self.zeros(batch, self.config.filters, *self.shape)
        return {f"{kind}{index}": zeros.clone() for index in range(self.config.layers) for kind in "hc"}

    def forward(self, counts, t_s, state=None):
        batch, length = counts.shape[:2]
        layers = len(self.cells)
        state = state or self.init_state(batch)
        x = self.scaled(counts).permute(1, 0, 3, 4, 2).contiguous()  # (T, B, H, W, 2)
        h = [state[f"h{index}"].permute(0, 2, 3, 1).contiguous() for index in range(layers)]
        c = [state[f"c{index}"].permute(0, 2, 3, 1).contiguous() for index in range(layers)]
        kernels = [cell.joint_kernel() for cell in self.cells]
        masks = None
        if self.training and self.dropout.p > 0 and layers > 1:
            masks = dropout_masks((layers - 1, length, batch, *self.shape, self.config.filters), self.dropout.p, x.device)
        head_weight, head_bias, rest = self._head_parts()
        outputs = []
        for t in range(length):
            inputs = x[t]
            for index, cell in enumerate(self.cells):
                h[index], c[index] = cell.step(inputs, h[index], c[index], kernels[index])
                inputs = h[index] if masks is None or index == layers - 1 else h[index] * masks[index, t]
            outputs.append(F.linear(inputs.reshape(batch, -1), head_weight, head_bias))
        out = rest(torch.stack(outputs, dim=1)) if outputs else self.zeros(batch, 0, 1)
        new = {}
        for index in range(layers):
            new[f"h{index}"], new[f"c{index}"] = h[index].permute(0, 3, 1, 2), c[index].permute(0, 3, 1, 2)
        return out.squeeze(-1), new

    def _head_parts(self):
        """The head's first linear layer (weight in channels-last flattening order, bias) and the rest."""
        first = self.head if isinstance(self.head, nn.Linear) else self.head[0]
        rest = nn.Identity() if isinstance(self.head, nn.Linear) else self.head[1:]
        units = first.weight.shape[0]
        weight = first.weight.view(units, self.config.filters, *self.shape).permute(0, 2, 3, 1).reshape(units, -1)
        return weight, first.bias, rest


def reference_forward(net: Net, counts, t_s, state=None):
    """`Net.forward` in its plain formulation (nn.Conv2d layer by layer, nn.Dropout): the numerical
    reference of the fast path, kept for tests and benchmarks."""
    batch, length = counts.shape[:2]
    state = state or net.init_state(batch)
    x = net.scaled(counts)
    new = {}
    for index, cell in enumerate(net.cells):
        x, h, c = cell(x, state[f"h{index}"], state[f"c{index}"])
        new[f"h{index}"], new[f"c{index}"] = h, c
        if index < len(net.cells) - 1:
            x = net.dropout(x)
    return net.head(x.reshape(batch, length, -1)).squeeze(-1), new
