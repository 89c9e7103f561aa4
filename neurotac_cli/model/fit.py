"""The training protocol (thesis 4.5.3): Adam (lr 1e-3, betas 0.9/0.999), minibatches, early stopping
after `patience` epochs without validation improvement, restoring the best weights."""

import contextlib
import contextvars
import copy
import math
import os
import time
from dataclasses import dataclass

import torch

from neurotac_cli.errors import ModelError, UsageError
from neurotac_cli.model.curve import IMPROVEMENT
from neurotac_cli.study import DEVICE_VARIABLE  # the cache keys read it too


@dataclass(frozen=True)
class FitConfig:
    lr: float = 1e-3
    beta1: float = 0.9
    beta2: float = 0.999
    batch_size: int = 8
    epochs: int = 500
    patience: int = 20
    weight_decay: float = 0.0


_STOPS = contextvars.ContextVar("stops", default=None)


@contextlib.contextmanager
def kept_on_interrupt():
    """Within it, an interrupt (Ctrl-C, SIGTERM) during a fit's epochs ends that fit with its best
    weights so far, as early stopping would, instead of throwing hours of training away: the list it
    yields gets (label, epochs done, the interrupt), for the caller to write the model and then
    raise the interrupt. A fit begun after one was interrupted (a model's next member) raises it at
    once: a model of untrained members is no model. A fit interrupted before its first epoch ends
    raises it too. Studies do not use it: an interrupted run there is resumed, not kept."""
    stops = []
    token = _STOPS.set(stops)
    try:
        yield stops
    finally:
        _STOPS.reset(token)


def fit(net, batch_loss, n_train: int, val_loss, config: FitConfig, generator: torch.Generator, progress=None, label="train"):
    """Train `net` in place; return the training curve (one dict per epoch).

    `batch_loss(indices)` is the loss on those training samples (net in train mode); `val_loss()`
    the validation loss (no grad, eval mode) or None when there is no validation set, in which case
    early stopping watches the training loss.
    """
    stops = _STOPS.get()
    if stops:
        raise stops[0][2]
    optimiser = torch.optim.Adam(net.parameters(), lr=config.lr, betas=(config.beta1, config.beta2),
                                 weight_decay=config.weight_decay)
    best, best_state, since, curve = math.inf, copy.deepcopy(net.state_dict()), 0, []
    started = time.monotonic()
    done = 0  # epochs whose weights and curve are both in: what an interrupt keeps
    for epoch in range(1, config.epochs + 1):
        try:
            train, val = _epoch(net, optimiser, batch_loss, n_train, val_loss, config, generator)
            watched = train if val is None else val
            if not math.isfinite(watched):  # NaN weights never come back: better no model than the untrained one
                raise ModelError(f"{label}: the training diverged at epoch {epoch} (its {'training' if val is None else 'validation'} "
                                 f"loss is {watched}); lower --lr (now {config.lr:g})")
            curve.append({"epoch": epoch, "train_loss": train, "val_loss": math.nan if val is None else float(val)})
            if watched < best - IMPROVEMENT:
                best, best_state, since = watched, copy.deepcopy(net.state_dict()), 0
            else:
                since += 1
            done = epoch
            if progress:
                val_text = "" if val is None else f" val {val:.4g}"
                progress(f"{label}: epoch {epoch} loss {train:.4g}{val_text} best {best:.4g} "
                         f"({since}/{config.patience} without improvement, {time.monotonic() - started:.0f}s)")
        except KeyboardInterrupt as stop:
            if stops is None or not done:
                raise
            del curve[done:]
            stops.append((label, done, stop))
            break
        if since >= config.patience:
            break
    net.load_state_dict(best_state)
    net.eval()
    return curve


def _epoch(net, optimiser, batch_loss, n_train: int, val_loss, config: FitConfig, generator) -> tuple:
    """One epoch of minibatches in a random order: (the mean training loss, the validation loss or None)."""
    net.train()
    order = torch.randperm(n_train, generator=generator)
    total, seen = 0.0, 0
    for start in range(0, n_train, config.batch_size):
        indices = order[start : start + config.batch_size]
        optimiser.zero_grad()
        loss = batch_loss(indices)
        loss.backward()
        optimiser.step()
        total += float(loss.detach()) * len(indices)
        seen += len(indices)
    net.eval()
    with torch.no_grad():
        val = val_loss()
    return total / max(seen, 1), val


def training_device() -> torch.device:
    """Where gradient-trained force models train: $NEUROTAC_DEVICE (`--device` sets it for the
    command and the worker processes it starts), the CPU when unset."""
    name = os.environ.get(DEVICE_VARIABLE, "").strip() or "cpu"
    try:
        device = torch.device(name)
    except RuntimeError:
        raise UsageError(f"unknown device {name!r} (cpu, cuda or cuda:N)") from None
    if device.type == "cpu":
        return device
    if device.type != "cuda":
        raise UsageError(f"device {name!r}: neurotac trains on cpu or cuda")
    if not torch.cuda.is_available():
        raise ModelError(f"device {name!r}: this torch ({torch.__version__}) sees no CUDA GPU; train on cpu")
    if device.index is not None and device.index >= torch.cuda.device_count():
        raise ModelError(f"device {name!r}: this machine has {torch.cuda.device_count()} CUDA GPU(s)")
    return device
