"""Gaussian process on accumulated ON, OFF counts and time (thesis 3.4.4).

Kernel: ARD squared exponential (one length scale per input) times a signal variance, plus white
noise; hyperparameters maximise the log marginal likelihood with random restarts (scikit-learn's
GaussianProcessRegressor; the thesis used Matlab with Bayesian optimisation of the length scales).
The fitted GP is stored as arrays (training inputs, dual coefficients, length scales, variances),
and prediction is the posterior mean computed from them, so loading executes no code.
"""

from dataclasses import dataclass

import numpy as np
import torch

from neurotac_cli.model.base import ForceNet


@dataclass(frozen=True)
class Config:
    restarts: int = 3
    max_points: int = 1500  # training frames kept (random subset): exact GP cost grows as n^3
    accumulate: bool = True


def first_outside(values, low: float, high: float) -> float:
    values = values.reshape(-1)
    return float(values[(values < low * 0.999) | (values > high * 1.001)][0])


class Net(ForceNet):
    trained_by_gradient = False

    def __init__(self, config: Config, shape):
        super().__init__()
        self.config = config
        self.register_buffer("x_mean", torch.zeros(3, dtype=torch.float64))
        self.register_buffer("x_scale", torch.ones(3, dtype=torch.float64))
        self.register_buffer("inputs", torch.zeros(0, 3, dtype=torch.float64))
        self.register_buffer("dual", torch.zeros(0, dtype=torch.float64))
        self.register_buffer("length_scale", torch.ones(3, dtype=torch.float64))
        self.register_buffer("signal_variance", torch.ones(1, dtype=torch.float64))
        self.register_buffer("noise_variance", torch.ones(1, dtype=torch.float64))

    def prepare_for(self, tensors):
        self.inputs = torch.zeros_like(tensors["inputs"])
        self.dual = torch.zeros_like(tensors["dual"])

    # the optimiser's bounds on the kernel's hyperparameters (`fit`); `implausible` allows for rounding
    BOUNDS = {"length_scale": (1e-2, 1e3), "signal_variance": (1e-3, 1e3), "noise_variance": (1e-6, 1.0)}

    def implausible(self, tensors) -> str | None:
        """What in a loaded GP no fit can give (a damaged file): a GP out of its bounds estimates 0
        or nonsense without a word."""
        for name, (low, high) in self.BOUNDS.items():
            values = tensors[name].to(torch.float64)
            if values.numel() and not bool(((values >= low * 0.999) & (values <= high * 1.001)).all()):
                return f"the GP's {name.replace('_', ' ')} {first_outside(values, low, high):.3g} is outside {low:g}..{high:g}"
        if not bool((tensors["x_scale"] > 0).all()):
            return "the GP's input scale is not above 0"
        return None

    def init_state(self, batch: int):
        return {"acc": torch.zeros(batch, 2, dtype=torch.float64)}

    def _features(self, counts, t_s, acc):
        sums = counts.sum(dim=(-1, -2)).to(torch.float64)
        if self.config.accumulate:
            sums = torch.cumsum(sums, dim=1) + acc.unsqueeze(1)
        return torch.cat([sums, t_s.to(torch.float64).unsqueeze(-1)], dim=-1), sums[:, -1] if self.config.accumulate else acc

    def forward(self, counts, t_s, state=None):
        batch, length = counts.shape[:2]
        state = state or self.init_state(batch)
        x, acc = self._features(counts, t_s, state["acc"])
        z = ((x - self.x_mean) / self.x_scale).reshape(-1, 3) / self.length_scale
        anchors = self.inputs / self.length_scale
        distance = (z * z).sum(1, keepdim=True) - 2 * z @ anchors.T + (anchors * anchors).sum(1)
        kernel = self.signal_variance * torch.exp(-0.5 * distance.clamp_min(0))
        mean = (kernel @ self.dual).reshape(batch, length)
        return mean.to(torch.float32), {"acc": acc}

    def fit(self, counts: list, t_s: list, force: list, rng: np.random.Generator, progress=None):
        """Fit on training trials; `force` normalised, NaN where unknown."""
        import warnings

        from sklearn.exceptions import ConvergenceWarning
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

        rows, targets = [], []
        with torch.no_grad():
            for c, t, f in zip(counts, t_s, force):
                x, _ = self._features(torch.as_tensor(c[None], dtype=torch.float64), torch.as_tensor(t[None]), torch.zeros(1, 2, dtype=torch.float64))
                rows.append(x[0].numpy())
                targets.append(f)
        x, y = np.concatenate(rows), np.concatenate(targets).astype(np.float64)
        keep = ~np.isnan(y)
        x, y = x[keep], y[keep]
        if len(x) > self.config.max_points:
            pick = np.sort(rng.choice(len(x), self.config.max_points, replace=False))
            x, y = x[pick], y[pick]
        mean, scale = x.mean(axis=0), x.std(axis=0)
        scale[scale == 0] = 1.0
        z = (x - mean) / scale
        bounds = self.BOUNDS
        kernel = (ConstantKernel(1.0, bounds["signal_variance"]) * RBF(np.ones(3), bounds["length_scale"])
                  + WhiteKernel(1e-2, bounds["noise_variance"]))
        if progress:
            progress(f"gp: fitting {len(z)} frames, {self.config.restarts} restarts")
        gp = GaussianProcessRegressor(kernel, n_restarts_optimizer=self.config.restarts, normalize_y=False,
                                      random_state=int(rng.integers(2**31 - 1)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)  # a length scale at its bound: that input is irrelevant
            gp.fit(z, y)
        fitted = gp.kernel_
        self.x_mean = torch.as_tensor(mean)
        self.x_scale = torch.as_tensor(scale)
        self.inputs = torch.as_tensor(z)
        self.dual = torch.as_tensor(np.asarray(gp.alpha_).reshape(-1))
        self.length_scale = torch.as_tensor(np.atleast_1d(fitted.k1.k2.length_scale).astype(np.float64))
        self.signal_variance = torch.as_tensor([float(fitted.k1.k1.constant_value)], dtype=torch.float64)
        self.noise_variance = torch.as_tensor([float(fitted.k2.noise_level)], dtype=torch.float64)
        if progress:
            progress(f"gp: log marginal likelihood {gp.log_marginal_likelihood_value_:.2f}, length scales "
                     + ", ".join(f"{v:.3g}" for v in self.length_scale.tolist()))
        return [{"epoch": 0, "train_loss": float(np.mean((gp.predict(z) - y) ** 2)), "val_loss": float("nan")}]
