"""Kernels of the ConvLSTM's fast path (model/convlstm.py): the LSTM gate function and the joint
[x, h] input of a frame's gate convolution, on channels-last tensors flattened to (pixels, channels),
each an autograd Function with a hand-written backward; and dropout keep-masks drawn cheaply.
On a GPU the gates and the joint input are the torch operations (the loops are CPU code).

Every activation is a logistic sigmoid: tanh(x) = 2 sigmoid(2x) - 1, with the factor 2 of the g
gate folded into its convolution (`gate_scale`), because on the CPU build torch's sigmoid is
vectorised and its tanh is not (docs/design.md, "ConvLSTM on a CPU").
The per-pixel arithmetic between the sigmoids runs in small numba loops (one pass instead of a dozen
torch operations on 3-channel strided slices). The same arithmetic as torch operations that autograd
differentiates (`KERNELS = False`) is the reference the tests check the loops and their hand-written
backward against.
"""

import torch
from numba import njit

KERNELS = True  # False: the gates and the joint input as plain torch operations (the reference)

# numba's parallel loops are left out on purpose: they bring a second OpenMP runtime, whose threads
# compete with torch's for the same cores and slow torch's own kernels; the loops run on the
# calling thread.


@njit(cache=True, nogil=True)
def _cell_state(act, c_prev, c, c_doubled):  # pragma: no cover - compiled
    pixels, filters = c.shape
    for p in range(pixels):
        for k in range(filters):
            value = act[p, filters + k] * c_prev[p, k] + act[p, k] * (2.0 * act[p, 3 * filters + k] - 1.0)
            c[p, k] = value
            c_doubled[p, k] = value + value


@njit(cache=True, nogil=True)
def _cell_output(act, tanh_c, h):  # pragma: no cover - compiled
    """tanh_c holds sigmoid(2c) on entry, tanh(c) on return."""
    pixels, filters = h.shape
    for p in range(pixels):
        for k in range(filters):
            t = 2.0 * tanh_c[p, k] - 1.0
            tanh_c[p, k] = t
            h[p, k] = act[p, 2 * filters + k] * t


@njit(cache=True, nogil=True)
def _cell_backward(act, c_prev, tanh_c, dh, dc, dz, dc_prev):  # pragma: no cover - compiled
    pixels, filters = c_prev.shape
    for p in range(pixels):
        for k in range(filters):
            i = act[p, k]
            f = act[p, filters + k]
            o = act[p, 2 * filters + k]
            g2 = act[p, 3 * filters + k]
            t = tanh_c[p, k]
            d = dc[p, k] + dh[p, k] * o * (1.0 - t * t)
            dz[p, k] = d * (2.0 * g2 - 1.0) * i * (1.0 - i)
            dz[p, filters + k] = d * c_prev[p, k] * f * (1.0 - f)
            dz[p, 2 * filters + k] = dh[p, k] * t * o * (1.0 - o)
            dz[p, 3 * filters + k] = 2.0 * d * i * g2 * (1.0 - g2)
            dc_prev[p, k] = d * f


@njit(cache=True, nogil=True)
def _joint(x, h, out):  # pragma: no cover - compiled
    pixels, inputs = x.shape
    filters = h.shape[1]
    for p in range(pixels):
        for k in range(inputs):
            out[p, k] = x[p, k]
        for k in range(filters):
            out[p, inputs + k] = h[p, k]


def gate_scale(filters: int, like: torch.Tensor) -> torch.Tensor:
    """Per output channel of the gate convolution (i, f, o, g): 1, 1, 1, 2."""
    scale = torch.ones(4 * filters, dtype=like.dtype, device=like.device)
    scale[3 * filters :] = 2.0
    return scale


def _np(tensor):
    return tensor.detach().numpy()


class _Gates(torch.autograd.Function):
    """(h, c) from scaled gate pre-activations z (P, 4F) = [i, f, o, 2g] and the previous c (P, F).

    Saves the 4F activations, the previous c and tanh(c); backward is one pass over the pixels.
    """

    @staticmethod
    def forward(ctx, z, c_prev):
        act = torch.sigmoid(z)
        c, tanh_c, h = torch.empty_like(c_prev), torch.empty_like(c_prev), torch.empty_like(c_prev)
        _cell_state(_np(act), _np(c_prev), _np(c), _np(tanh_c))
        torch.sigmoid(tanh_c, out=tanh_c)
        _cell_output(_np(act), _np(tanh_c), _np(h))
        ctx.save_for_backward(act, c_prev, tanh_c)
        return h, c

    @staticmethod
    def backward(ctx, dh, dc):
        act, c_prev, tanh_c = ctx.saved_tensors
        dh = torch.zeros_like(c_prev) if dh is None else dh
        dc = torch.zeros_like(c_prev) if dc is None else dc
        dz, dc_prev = torch.empty_like(act), torch.empty_like(c_prev)
        _cell_backward(_np(act), _np(c_prev), _np(tanh_c), _np(dh), _np(dc), _np(dz), _np(dc_prev))
        return dz, dc_prev


def _torch_gates(z, c_prev):
    """`_Gates` as torch operations, differentiated by autograd: the reference."""
    i, f, o, g2 = torch.sigmoid(z).chunk(4, dim=-1)
    c = torch.addcmul(f * c_prev, i, g2 * 2.0 - 1.0)
    return o * (torch.sigmoid(c * 2.0) * 2.0 - 1.0), c


class _Joint(torch.autograd.Function):
    """[x, h] along channels (P, inputs + F), contiguous: the input of a frame's gate convolution."""

    @staticmethod
    def forward(ctx, x, h):
        ctx.inputs = x.shape[-1]
        out = torch.empty(x.shape[0], x.shape[1] + h.shape[1], dtype=x.dtype)
        _joint(_np(x), _np(h), _np(out))
        return out

    @staticmethod
    def backward(ctx, d_joint):
        return d_joint[:, : ctx.inputs], d_joint[:, ctx.inputs :]


def lstm_gates(z, c):
    """New (h, c) from scaled gate pre-activations (..., 4F) ordered i, f, o, 2g and the cell state (..., F)."""
    shape = c.shape
    filters = shape[-1]
    gates = _Gates.apply if KERNELS and z.device.type == "cpu" else _torch_gates
    h, c = gates(z.reshape(-1, 4 * filters), c.reshape(-1, filters))
    return h.view(shape), c.view(shape)


def joint_input(x, h):
    """x (..., inputs) and h (..., F) side by side along channels, contiguous."""
    if not KERNELS or x.device.type != "cpu":
        return torch.cat([x, h], dim=-1)
    shape = x.shape[:-1]
    out = _Joint.apply(x.reshape(-1, x.shape[-1]), h.reshape(-1, h.shape[-1]))
    return out.view(*shape, out.shape[-1])


def dropout_masks(shape, p: float, device=None):
    """Float masks of `shape`: 0 with probability p, else 1 / (1 - p), as nn.Dropout applies.

    Each mask element comes from 16 random bits (two elements per 32-bit draw of the default
    generator), so the keep probability is round((1 - p) * 65536) / 65536, within 8e-6 of 1 - p;
    drawing a float per element (torch.rand, bernoulli_) costs two to five times as long.
    """
    keep = 1.0 - p
    if keep <= 0:
        return torch.zeros(shape, device=device)
    count = 1
    for size in shape:
        count *= size
    bits = torch.randint(-(2**31), 2**31 - 1, ((count + 1) // 2,), dtype=torch.int32, device=device).view(torch.int16)[:count]
    threshold = round(keep * 65536) - 32768
    return (bits < threshold).view(shape).to(torch.float32).mul_(1.0 / keep)
