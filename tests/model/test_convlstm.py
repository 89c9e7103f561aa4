"""The ConvLSTM's fast path (channels-last joint convolutions, fused gates, cheap dropout masks)
computes the plain formulation's function: outputs, states and gradients, with dropout too."""

import numpy as np
import pytest
import torch

from neurotac_cli import model as models
from neurotac_cli.model.data import sequences
from neurotac_cli.model import convlstm
from neurotac_cli.model import convlstm_ops as ops
from tests.model.helpers import tiny_frames

SHAPE = (2, 9, 11)
PARAMETER_NAMES = [  # the model file's tensor names: files written before the fast path still load
    "count_scale",
    *[f"cells.{i}.{name}" for i in range(4) for name in ("input_conv.weight", "input_conv.bias", "recurrent_conv.weight")],
    "head.weight", "head.bias",
]


def _net(dense=0, dropout=0.0, seed=0):
    torch.manual_seed(seed)
    net = convlstm.Net(convlstm.Config(dense=dense, dropout=dropout), SHAPE)
    net.count_scale.copy_(torch.tensor([3.0, 5.0]))
    return net


def _counts(batch=3, length=6, seed=1):
    generator = torch.Generator().manual_seed(seed)
    return torch.poisson(torch.full((batch, length, *SHAPE), 1.5), generator=generator)


def _close(a, b, rtol=1e-4, atol=1e-6):
    torch.testing.assert_close(a, b, rtol=rtol, atol=atol)


@pytest.mark.parametrize("dense", [0, 5])
def test_fast_path_equals_plain_convolutions_in_outputs_states_and_gradients(dense):
    net = _net(dense=dense).train()
    counts, t_s = _counts(), torch.zeros(3, 6)
    out, state = net(counts, t_s)
    ref, ref_state = convlstm.reference_forward(net, counts, t_s)
    _close(out, ref)
    assert state.keys() == ref_state.keys()
    for key in state:
        _close(state[key], ref_state[key])
    upstream = torch.randn_like(out)
    grads = torch.autograd.grad(out, list(net.parameters()), upstream)
    ref_grads = torch.autograd.grad(ref, list(net.parameters()), upstream)
    for (name, _), grad, ref_grad in zip(net.named_parameters(), grads, ref_grads):
        _close(grad, ref_grad, rtol=1e-4, atol=5e-5 * float(ref_grad.abs().max()) + 1e-7)


def test_fast_path_equals_plain_dropout_given_the_same_masks(monkeypatch):
    net = _net(dropout=0.4).train()
    counts, t_s = _counts(batch=2, length=4), torch.zeros(2, 4)
    masks = ops.dropout_masks((3, 4, 2, *SHAPE[1:], 3), 0.4)
    monkeypatch.setattr(convlstm, "dropout_masks", lambda shape, p, device=None: masks)
    out, _ = net(counts, t_s)
    # the plain formulation drops (B, T, F, H, W) sequences, layer after layer
    net.dropout = _GivenMasks(masks.permute(0, 2, 1, 5, 3, 4))
    ref, _ = convlstm.reference_forward(net, counts, t_s)
    _close(out, ref)


class _GivenMasks(torch.nn.Module):
    def __init__(self, masks):
        super().__init__()
        self.masks = iter(masks)

    def forward(self, x):
        return x * next(self.masks)


def test_kernels_and_their_torch_fallback_agree(monkeypatch):
    net = _net().train()
    counts, t_s = _counts(), torch.zeros(3, 6)
    out, _ = net(counts, t_s)
    grads = torch.autograd.grad(out.square().sum(), list(net.parameters()))
    monkeypatch.setattr(ops, "KERNELS", False)
    plain, _ = net(counts, t_s)
    plain_grads = torch.autograd.grad(plain.square().sum(), list(net.parameters()))
    _close(out, plain, rtol=1e-5, atol=1e-7)
    for grad, plain_grad in zip(grads, plain_grads):
        _close(grad, plain_grad, rtol=1e-5, atol=1e-6 * float(plain_grad.abs().max()) + 1e-7)


def test_state_carried_in_pieces_equals_one_call():
    net = _net().eval()
    counts, t_s = _counts(length=7), torch.zeros(3, 7)
    with torch.no_grad():
        whole, whole_state = net(counts, t_s)
        state, parts = None, []
        for start in (0, 1, 4):
            out, state = net(counts[:, start : {0: 1, 1: 4, 4: 7}[start]], t_s[:, :1], state)
            parts.append(out)
        ref, _ = convlstm.reference_forward(net, counts, t_s)
    _close(torch.cat(parts, dim=1), whole, rtol=1e-6, atol=1e-7)
    _close(whole, ref)
    for key in whole_state:
        _close(state[key], whole_state[key], rtol=1e-6, atol=1e-7)


def test_parameter_names_are_those_of_the_model_file_format():
    assert list(_net().state_dict()) == PARAMETER_NAMES


def test_saved_model_predicts_as_the_plain_formulation(tmp_path):
    frames = tiny_frames(trials=4)
    model = models.train(frames, models.make_spec("convlstm", epochs=1), seed=0)
    models.save(model, str(tmp_path / "c.model"))
    loaded = models.load(str(tmp_path / "c.model"))
    data = sequences(frames)
    counts = torch.as_tensor(np.stack(data.counts), dtype=torch.float32)
    with torch.no_grad():
        ref, _ = convlstm.reference_forward(loaded.net, counts, torch.zeros(counts.shape[:2]))
    predicted = models.predict_table(loaded, frames).column("force_pred").to_numpy()
    np.testing.assert_allclose(predicted, ref.numpy().ravel() * loaded.force_scale, rtol=1e-4, atol=1e-6)


def test_dropout_masks_keep_at_the_rate_and_scale_of_nn_dropout():
    torch.manual_seed(3)
    masks = ops.dropout_masks((4, 50, 50, 3), 0.4)
    torch.manual_seed(3)
    again = ops.dropout_masks((4, 50, 50, 3), 0.4)
    assert torch.equal(masks, again)
    assert masks.unique().tolist() == pytest.approx([0.0, 1 / 0.6])
    assert abs(float((masks > 0).float().mean()) - 0.6) < 0.01
    assert torch.equal(ops.dropout_masks((2, 3), 1.0), torch.zeros(2, 3))
