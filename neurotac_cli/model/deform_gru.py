"""Our force model: size-robust event statistics per frame into small GRUs.

Why: the ConvLSTM learns pixel patterns of the object sizes it saw, so an unseen size is a new
image; and it costs four 3x3 convolutions over the full frame per layer and frame. The contact
force is better described by a few physical quantities that change smoothly with object size:

- per channel, the frame's event count and the number of active pixels (log scale);
- per channel, the counts accumulated since the trial start (the chapter-3 input);
- a per-pixel *deformation map*, the running sum of OFF minus ON events (OFF fires as force grows,
  ON as it falls): its positive mass, its negative mass, the area where it is positive, and its
  radial extent (the second moment around its centroid), i.e. the contact patch's size;
- the areas where the deformation map reaches each of `levels` depths (fractions of its 99.5th
  percentile on the training trials): the membrane's pixels saturate, so the patch's area stops
  growing with the force while how much of the patch reaches which depth keeps telling it
  (docs/design.md has the correlations);
- with `excess`, the map's mass above each of those depths: a pixel's pressure grows faster than
  its depth as it nears saturation, so sums of the excess over a level carry the force a deep
  patch adds after its area and depths stop changing;
- a coarse `layout_grid` x `layout_grid` layout of the deformation map and of the frame's events, as shares of
  their totals (so they do not scale with object size).

With `memory_frames` the deformation map and counts leak (a time constant in frames), so a stream
that never rests keeps them bounded; the default (0) sums since the trial start, as the thesis does.

The features are standardised with constants fitted on training trials, then `members` GRUs of
`hidden` units, each with a linear head and trained with a validation draw of its own, give the
force as the mean of their estimates. State per trial: the deformation map, the accumulated counts
and the GRUs' states, so streaming costs O(H x W) per frame plus a tiny GRU step per member.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from neurotac_cli.model.base import ForceNet


# Its validation error still falls, slowly, after 20 epochs without a new best; waiting 40 lowers
# the held-out error (docs/journal.md).
FIT_DEFAULTS = {"patience": 40}


@dataclass(frozen=True)
class Config:
    hidden: int = 32
    layers: int = 1
    levels: int = 8  # depth levels of the deformation map whose areas are features
    layout_grid: int = 0  # 0 = none: a layout learns where the seen sizes press, which an unseen size does not share
    dropout: float = 0.0
    memory_frames: int = 0  # time constant of the deformation map and counts, in frames (0: sums since the start)
    excess: bool = True  # the map's mass above each depth level
    members: int = 3  # GRUs (and heads) on the same features, each validated on its own draw, their estimates averaged


# Values of the per-level depth maps made at once (64 MB of float32; `Net.features`).
FEATURE_VALUES = 1 << 24

# What a setting missing from an older model file's header meant when that file was written.
ABSENT_MEANS = {"excess": False, "members": 1}


class Net(ForceNet):
    def __init__(self, config: Config, shape):
        super().__init__()
        self.config = config
        _, height, width = shape
        self.shape = (height, width)
        width_features = 10 + config.levels * (2 if config.excess else 1) + 4 * config.layout_grid * config.layout_grid
        self.register_buffer("feature_mean", torch.zeros(width_features))
        self.register_buffer("feature_std", torch.ones(width_features))
        self.register_buffer("level_unit", torch.ones(1))
        # How far a frame's features lie from the training frames' (`distances`); zeros: not fitted
        self.register_buffer("feature_precision", torch.zeros(width_features, width_features))
        self.register_buffer("distance_p99", torch.zeros(1))
        self.distance_log = None  # a list to which each forward appends its frames' distances (model.predict.Outside)
        self.register_buffer("x_coord", torch.arange(width, dtype=torch.float32).view(1, 1, 1, width) / max(width, 1))
        self.register_buffer("y_coord", torch.arange(height, dtype=torch.float32).view(1, 1, height, 1) / max(height, 1))
        self.gru, self.head = self._recurrent(width_features), nn.Linear(config.hidden, 1)
        # Members after the first; the first keeps the names of a one-GRU model's weights, so a file
        # of one GRU loads as a model of one member
        self.more = nn.ModuleList(nn.ModuleDict({"gru": self._recurrent(width_features), "head": nn.Linear(config.hidden, 1)})
                                  for _ in range(config.members - 1))

    def _recurrent(self, width_features):
        gru = nn.GRU(width_features, self.config.hidden, num_layers=self.config.layers, batch_first=True,
                     dropout=self.config.dropout if self.config.layers > 1 else 0.0)
        for name, weight in gru.named_parameters():
            if name.startswith("weight_hh"):
                nn.init.orthogonal_(weight)
        return gru

    def members(self):
        """(GRU, head) of each member."""
        return [(self.gru, self.head), *((member["gru"], member["head"]) for member in self.more)]

    def member(self, i: int) -> nn.Module:
        """Member i's parameters as a module of their own, for training it alone."""
        gru, head = self.members()[i]
        return nn.ModuleDict({"gru": gru, "head": head})

    def alone(self, i: int) -> "Net":
        """Member i as a one-GRU network, its weights shared: the others trained on the trials its own
        early stopping watched, so its validation error is its estimate's, not the mean's."""
        single = Net(dataclasses.replace(self.config, members=1), (2, *self.shape))
        for name, buffer in self.named_buffers(recurse=False):
            getattr(single, name).copy_(buffer)
        single.gru, single.head = self.members()[i]
        return single

    def init_state(self, batch: int):
        return {
            "deformation": self.zeros(batch, *self.shape),
            "acc": self.zeros(batch, 2),
            "h": self.zeros(self.config.layers * self.config.members, batch, self.config.hidden),
        }

    def features(self, counts, state):
        """(features (B, T, F), the state after the last frame). A long run of large frames is taken
        in pieces of time, the state carried from one to the next: the per-level depth maps of a whole
        contact at full sensor size would take gigabytes at once."""
        batch, length = counts.shape[:2]
        step = max(1, FEATURE_VALUES // max(1, batch * self.shape[0] * self.shape[1] * max(self.config.levels, 1)))
        if length <= step:
            return self._features(counts, state)
        parts = []
        for start in range(0, length, step):
            part, new = self._features(counts[:, start : start + step], state)
            state = {**state, **new}
            parts.append(part)
        return torch.cat(parts, dim=1), new

    def _features(self, counts, state):
        batch, length = counts.shape[:2]
        counts = counts.float()
        sums = counts.sum(dim=(-1, -2))  # (B, T, 2)
        active = (counts > 0).sum(dim=(-1, -2)).float()
        acc = accumulate(sums, state["acc"], self.config.memory_frames)
        deformation = accumulate(counts[:, :, 0] - counts[:, :, 1], state["deformation"], self.config.memory_frames)
        positive, negative = deformation.clamp_min(0), (-deformation).clamp_min(0)
        mass = positive.sum(dim=(-1, -2))
        area = (deformation > 0.5).sum(dim=(-1, -2)).float()
        safe = mass.clamp_min(1e-6).unsqueeze(-1).unsqueeze(-1)
        weights = positive / safe
        cx = (weights * self.x_coord).sum(dim=(-1, -2), keepdim=True)
        cy = (weights * self.y_coord).sum(dim=(-1, -2), keepdim=True)
        extent = torch.sqrt((weights * ((self.x_coord - cx) ** 2 + (self.y_coord - cy) ** 2)).sum(dim=(-1, -2)) + 1e-8)
        parts = [
            torch.log1p(sums), torch.log1p(active), torch.log1p(acc),
            torch.log1p(mass).unsqueeze(-1), torch.log1p(negative.sum(dim=(-1, -2))).unsqueeze(-1),
            torch.log1p(area).unsqueeze(-1), extent.unsqueeze(-1),
        ]
        if self.config.levels:
            steps = torch.arange(1, self.config.levels + 1, dtype=torch.float32, device=counts.device) / self.config.levels * self.level_unit
            depth_over = deformation.unsqueeze(2) - steps.view(1, 1, -1, 1, 1)  # one map per level, shared by both features
            parts.append(torch.log1p((depth_over >= 0).sum(dim=(-1, -2)).float()))
            if self.config.excess:
                parts.append(torch.log1p(depth_over.clamp_min(0).sum(dim=(-1, -2))))
        grid = self.config.layout_grid
        if grid:
            flat = lambda x: x.reshape(batch * length, -1, *self.shape)  # noqa: E731
            layout = torch.cat([flat(positive), flat(negative), flat(counts)], dim=1)
            pooled = F.adaptive_avg_pool2d(layout, grid).reshape(batch, length, 4, grid * grid)
            pooled = pooled / pooled.sum(dim=-1, keepdim=True).clamp_min(1e-6)
            parts.append(pooled.reshape(batch, length, -1))
        new = {"deformation": deformation[:, -1], "acc": acc[:, -1]}
        return torch.cat(parts, dim=-1), new

    def encode(self, counts, t_s, chunk: int = 8):
        """The features of whole sequences from their start. They hold no trained parameter, so
        training computes them once instead of once per epoch (tens of times faster at 115x115)."""
        with torch.no_grad():
            parts = [self.features(counts[i : i + chunk], self.init_state(len(counts[i : i + chunk])))[0]
                     for i in range(0, counts.shape[0], chunk)]
        return torch.cat(parts) if parts else torch.zeros(0)

    def forward_encoded(self, features, member: int | None = None):
        """forward() from features made by encode(), for whole sequences from their start: the
        members' mean, or one member's estimate (training fits each on its own)."""
        x = (features - self.feature_mean) / self.feature_std
        return self._run(x, self.init_state(features.shape[0])["h"], None if member is None else [member])[0]

    def _run(self, x, h, chosen=None):
        """The mean estimate (B, T) of the `chosen` members (default all) from standardised features,
        and their states after."""
        layers, members, outs, states = self.config.layers, self.members(), [], []
        for i in range(len(members)) if chosen is None else chosen:
            gru, head = members[i]
            out, state = gru(x, h[i * layers : (i + 1) * layers])
            outs.append(head(out).squeeze(-1))
            states.append(state)
        return torch.stack(outs).mean(dim=0), torch.cat(states)

    def forward(self, counts, t_s, state=None):
        batch = counts.shape[0]
        state = state or self.init_state(batch)
        features, new = self.features(counts, state)
        x = (features - self.feature_mean) / self.feature_std
        if self.distance_log is not None:
            self.distance_log.append(self.distance(x).numpy())
        out, new["h"] = self._run(x, state["h"])
        return out, new

    def distance(self, x):
        """Each frame's Mahalanobis distance from the training frames, from its standardised
        features x (B, T, F): how unlike anything it learnt from a frame is, whatever the force it
        reads there."""
        return torch.einsum("btf,fg,btg->bt", x, self.feature_precision, x).clamp_min(0).sqrt()

    def prepare_for(self, tensors: dict):
        if "level_unit" not in tensors:  # a file written before the depth levels: unused there (levels 0)
            tensors["level_unit"] = self.level_unit.clone()
        for name in ("feature_precision", "distance_p99"):  # a file written before the distance: no check
            tensors.setdefault(name, getattr(self, name).clone())

    def _depths(self, counts: np.ndarray) -> np.ndarray:
        """The deformation map of one trial's counts (T, 2, H, W) over its frames."""
        change = counts[:, 0].astype(np.float32) - counts[:, 1]
        if not self.config.memory_frames:
            return np.cumsum(change, axis=0)
        return accumulate(torch.as_tensor(change[None]), torch.zeros(1, *change.shape[1:]), self.config.memory_frames)[0].numpy()

    def calibrate(self, counts, t_s):
        depths = [self._depths(c).ravel() for c in counts]
        depths = np.concatenate(depths) if depths else np.ones(1)
        positive = depths[depths > 0]
        self.level_unit.fill_(float(np.percentile(positive, 99.5)) if len(positive) else 1.0)
        rows = []
        with torch.no_grad():
            for c in counts:
                features, _ = self.features(torch.as_tensor(c[None], dtype=torch.float32), self.init_state(1))
                rows.append(features[0])
        rows = torch.cat(rows)
        self.feature_mean.copy_(rows.mean(dim=0))
        self.feature_std.copy_(rows.std(dim=0).clamp_min(1e-3))
        if len(rows) > rows.shape[1]:  # the features' covariance needs more frames than features
            z = ((rows - self.feature_mean) / self.feature_std).double()
            covariance = z.T @ z / len(z) + DISTANCE_RIDGE * torch.eye(z.shape[1], dtype=torch.float64)
            precision = torch.linalg.inv(covariance)
            self.feature_precision.copy_(precision)
            self.distance_p99.fill_(float(torch.quantile(self.distance(z[None].float())[0], 0.99)))


DISTANCE_RIDGE = 1e-3  # added to the standardised features' covariance, so it always inverts


def accumulate(x, start, memory_frames: int):
    """Running sums over time (dim 1) of x (B, T, ...) from `start` (B, ...): plain sums, or with
    `memory_frames` > 0 leaky ones (each frame keeps exp(-1 / memory_frames) of the last), which stay
    bounded by the largest frame times about `memory_frames` however long the stream."""
    if not memory_frames:
        return torch.cumsum(x, dim=1) + start.unsqueeze(1)
    keep = float(np.exp(-1.0 / memory_frames))
    out, total = [], start
    for frame in x.unbind(1):
        total = total * keep + frame
        out.append(total)
    return torch.stack(out, dim=1) if out else x.clone()
