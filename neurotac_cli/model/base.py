"""What every force network shares: raw counts in, force (normalised) out, state carried between calls.

`forward(counts, t_s, state)` takes raw counts (B, T, 2, H, W) and frame times in seconds (B, T),
returns the normalised force (B, T) and the state after the last frame. Calling it on a sequence in
pieces, passing the state along, gives what one call on the whole sequence gives: that is how
`predict` streams. Normalisation constants are buffers, fitted by `calibrate` on training trials only.
"""

import torch
from torch import nn


class ForceNet(nn.Module):
    task = "force"

    def zeros(self, *shape):
        """Zeros on the device the network is on (a start state; training may run on a GPU)."""
        return torch.zeros(*shape, device=next(self.buffers()).device)

    def calibrate(self, counts: list, t_s: list):
        """Fit normalisation buffers on the training trials (lists of (T, 2, H, W) and (T,) arrays)."""

    def prepare_for(self, tensors: dict):
        """Resize buffers whose shape depends on the training data before loading (the GP's arrays)."""


class CountScaledNet(ForceNet):
    """A network fed raw counts divided per channel by their training maximum (lstm, cnnlstm, convlstm)."""

    def __init__(self, config):
        super().__init__()
        self.config = config
        self.register_buffer("count_scale", torch.ones(2))

    def scaled(self, counts):
        return counts / self.count_scale.view(1, 1, 2, 1, 1)

    def calibrate(self, counts, t_s):
        self.count_scale.copy_(channel_scale(counts))


def channel_scale(counts: list) -> torch.Tensor:
    """Per-channel maximum pixel count over the training frames (the thesis's max normalisation), >= 1."""
    peak = torch.ones(2)
    for c in counts:
        if len(c):
            peak = torch.maximum(peak, torch.as_tensor(c.reshape(len(c), 2, -1).max(axis=(0, 2)), dtype=torch.float32))
    return peak


def orthogonal_recurrent(lstm: nn.LSTM):
    for name, weight in lstm.named_parameters():
        if name.startswith("weight_hh"):
            nn.init.orthogonal_(weight)
        elif name.startswith("bias"):
            nn.init.zeros_(weight)
