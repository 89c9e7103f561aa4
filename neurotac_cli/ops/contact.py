"""Contact from the events alone: touching or not, and the phase, per frame, causally, in O(1) state.

Why a state machine and not a threshold on the event rate: a held object makes almost no events
(the membrane is still), so a quiet frame is either rest or a steady hold. What tells them apart
is the history: pressing darkens the membrane (a burst of OFF events), releasing brightens it back
(a burst of ON events). So:

- rest -> touching (phase grasping) when a frame's OFF count rises above the background by
  `onset_sigma` Poisson σ and by `min_events`;
- grasping -> holding once the OFF count falls under `settled_share` of its peak since the onset
  (a later OFF burst, a re-grasp, goes back to grasping);
- touching -> releasing on an ON-dominated burst (`dominance` times more ON than OFF events);
- releasing -> rest when the ON events of that run of bursts reach `release_share` of the OFF
  events since the onset: the membrane is back, and the force reached zero within a frame of it on
  simulated ch4 (a hold's ripple makes runs of a few dozen ON events, a full release thousands).

The background (mean OFF and ON counts per frame) is a running mean over rest frames with a time
constant of `background_frames`, so slow illumination changes and hot pixels move it. The OFF sum
since the onset leaks with `memory_frames`, so a contact that never ends keeps them bounded.
"""

from dataclasses import asdict, dataclass

import numpy as np

NONE, GRASPING, HOLDING, RELEASING = "none", "grasping", "holding", "releasing"


@dataclass(frozen=True)
class ContactConfig:
    onset_sigma: float = 6.0  # OFF count above the background mean by this many Poisson σ ...
    min_events: float = 20.0  # ... and by at least this many events (pooled crop of the frame)
    settled_share: float = 0.25  # grasping ends when OFF falls under this share of its peak
    release_share: float = 0.04  # ON of a release run / OFF since the onset that ends a contact
    dominance: float = 2.0  # a release burst has this many times more ON than OFF events
    background_frames: float = 100.0  # time constant of the background's running mean (frames)
    memory_frames: float = 3000.0  # time constant of the sums since the onset (frames): bounded state
    background_off: float = 5.0  # starting background, events per frame (until rest frames refine it)
    background_on: float = 10.0

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class ContactState:
    """Everything the detector keeps between frames: a handful of numbers."""

    mean_off: float
    mean_on: float
    phase: str = NONE
    off_since: float = 0.0  # OFF events since the onset (leaky)
    peak_off: float = 0.0
    on_run: float = 0.0  # ON events of the current ON-dominated run (a release in progress)
    onsets: int = 0  # contacts begun so far (a new one resets the force model's state)

    @classmethod
    def start(cls, config: ContactConfig) -> "ContactState":
        return cls(mean_off=config.background_off, mean_on=config.background_on)


def step(config: ContactConfig, state: ContactState, off: float, on: float) -> str:
    """Advance one frame of `off` and `on` event counts; returns the frame's phase (none = not touching)."""
    keep = np.exp(-1.0 / config.memory_frames)
    state.off_since = state.off_since * keep + off
    if state.phase == NONE:
        if off > state.mean_off + max(config.onset_sigma * np.sqrt(state.mean_off + 1.0), config.min_events):
            state.phase, state.onsets = GRASPING, state.onsets + 1
            state.off_since, state.peak_off, state.on_run = off, off, 0.0
        else:
            _update_background(config, state, off, on)
        return state.phase
    pressing = off > state.mean_off + max(config.onset_sigma * np.sqrt(state.mean_off + 1.0), config.min_events)
    burst = on > state.mean_on + max(config.onset_sigma * np.sqrt(state.mean_on + 1.0), config.min_events)
    if burst and on > config.dominance * off:
        state.on_run += on
        state.phase = RELEASING
        if state.on_run >= config.release_share * state.off_since:
            state.phase, state.on_run = NONE, 0.0
    elif pressing and off > config.settled_share * state.peak_off:
        state.phase, state.on_run = GRASPING, 0.0
        state.peak_off = max(state.peak_off, off)
    else:
        state.on_run = 0.0
        if state.phase == RELEASING or off < config.settled_share * state.peak_off:
            state.phase = HOLDING
    return state.phase


def _update_background(config, state, off, on):
    """Running mean of rest frames; a frame far above it (a creep tail, a flicker) moves it by at most 3σ."""
    rate = 1.0 / config.background_frames
    cap_off = state.mean_off + 3.0 * np.sqrt(state.mean_off + 1.0)
    cap_on = state.mean_on + 3.0 * np.sqrt(state.mean_on + 1.0)
    state.mean_off += rate * (min(off, cap_off) - state.mean_off)
    state.mean_on += rate * (min(on, cap_on) - state.mean_on)


def detect(config: ContactConfig, off: np.ndarray, on: np.ndarray, state: ContactState | None = None):
    """Phases of a run of frames (OFF and ON counts per frame), continuing from `state`.

    Returns (phase array of str, onset flags (a contact begins at this frame), the state after)."""
    state = state or ContactState.start(config)
    phases = np.empty(len(off), dtype=object)
    onsets = np.zeros(len(off), dtype=bool)
    for k, (a, b) in enumerate(zip(np.asarray(off, dtype=np.float64).tolist(), np.asarray(on, dtype=np.float64).tolist())):
        before = state.onsets
        phases[k] = step(config, state, a, b)
        onsets[k] = state.onsets != before
    return phases, onsets, state


def frame_sums(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OFF and ON events per frame of (T, 2, H, W) counts."""
    sums = np.asarray(counts).reshape(len(counts), 2, -1).sum(axis=2, dtype=np.float64)
    return sums[:, 0], sums[:, 1]
