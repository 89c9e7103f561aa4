"""One training epoch of the thesis ConvLSTM on ch4-shaped data (run on demand: `make bench` or
`pytest -s tests/bench/bench_convlstm_train.py`): the fast path (`Net.forward`) against the plain
nn.Conv2d formulation (`convlstm.reference_forward`), same weights, same batches, 2 threads.

ch4 shape: 32 training trials of 41 frames of 2x115x115, batch 8, Adam (the `fit` protocol).
NEUROTAC_BENCH_TRIALS changes the number of trials (the plain epoch takes over a minute).
"""

import os
import time

import torch

from neurotac_cli.model import convlstm
from neurotac_cli.model.fit import FitConfig, fit

SIZE, LENGTH = 115, 41
TRIALS = int(os.environ.get("NEUROTAC_BENCH_TRIALS", "32"))


def _data(seed=0):
    generator = torch.Generator().manual_seed(seed)
    counts = torch.poisson(torch.full((TRIALS, LENGTH, 2, SIZE, SIZE), 0.05), generator=generator)
    force = torch.rand(TRIALS, LENGTH, generator=generator)
    return counts, force


def _epoch_seconds(forward, counts, force):
    torch.manual_seed(0)
    net = convlstm.Net(convlstm.Config(), (2, SIZE, SIZE))
    net.count_scale.copy_(torch.tensor([4.0, 4.0]))
    t_s = torch.zeros(counts.shape[:2])

    def batch_loss(indices):
        out, _ = forward(net, counts[indices], t_s[indices])
        return ((out - force[indices]) ** 2).mean()

    start = time.perf_counter()
    fit(net, batch_loss, len(counts), lambda: None, FitConfig(epochs=1), torch.Generator().manual_seed(0))
    return time.perf_counter() - start


def test_convlstm_epoch_fast_path_against_plain_convolutions():
    torch.set_num_threads(2)
    counts, force = _data()
    _epoch_seconds(lambda net, c, t: net(c, t), counts[:8], force[:8])  # warm-up: numba kernels, allocator
    fast = _epoch_seconds(lambda net, c, t: net(c, t), counts, force)
    plain = _epoch_seconds(convlstm.reference_forward, counts, force)
    print(f"\nconvlstm, one epoch of {TRIALS} trials x {LENGTH} frames of 2x{SIZE}x{SIZE}, batch 8, 2 threads: "
          f"fast path {fast:.1f} s, plain nn.Conv2d {plain:.1f} s, plain / fast x{plain / fast:.1f}")
    assert fast < plain
