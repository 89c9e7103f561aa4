"""Event-level TES (shift event timestamps by J windows, then frame) measured against frame-level TES.

The event-level version lives here, as the reference for the measurement, not in the package: framed
with the same window it gives the same frames in distribution as `augment --tes` (see
docs/design.md, "augment"; the figures in docs/journal.md), so the command works on frames only.
"""

import numpy as np
import pytest

from neurotac_cli.ops import augment as aug

WINDOW = 10_000
FRAMES, HEIGHT, WIDTH = 12, 6, 5


def recording(seed):
    """Events (t, x, y, p) of one trial with t in [0, FRAMES * WINDOW)."""
    rng = np.random.default_rng(seed)
    rates = rng.gamma(1.0, 1.5, size=(FRAMES, 2, HEIGHT, WIDTH))
    counts = rng.poisson(rates)
    frame, p, y, x = np.nonzero(counts)
    repeat = counts[frame, p, y, x]
    frame, p, y, x = (np.repeat(a, repeat) for a in (frame, p, y, x))
    t = frame * WINDOW + rng.integers(0, WINDOW, len(frame))
    order = np.argsort(t, kind="stable")
    return t[order], x[order], y[order], p[order]


def frame_events(t, x, y, p):
    inside = (t >= 0) & (t < FRAMES * WINDOW)
    counts = np.zeros((FRAMES, 2, HEIGHT, WIDTH), np.int64)
    np.add.at(counts, (t[inside] // WINDOW, p[inside], y[inside], x[inside]), 1)
    return counts


def event_level_tes(t, x, y, p, shift, zeta, rng):
    """Move exactly round(zeta * n) random events of each window and polarity J windows, keeping their
    place inside the window."""
    group = (t // WINDOW) * 2 + p
    sizes = np.bincount(group, minlength=2 * FRAMES)
    take = np.rint(zeta * sizes).astype(np.int64)
    shuffled = rng.permutation(len(t))
    in_groups = shuffled[np.argsort(group[shuffled], kind="stable")]
    rank = np.arange(len(t)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    moved = in_groups[rank < np.repeat(take, sizes)]
    t = t.copy()
    t[moved] += shift * WINDOW
    return t


@pytest.mark.parametrize("shift, zeta", [(-2, 0.5), (1, 0.25), (3, 0.75)])
def test_event_level_and_frame_level_tes_agree_in_distribution(shift, zeta):
    t, x, y, p = recording(11)
    original = frame_events(t, x, y, p)
    draws = 300
    rng = np.random.default_rng(5)
    by_events = np.stack([frame_events(event_level_tes(t, x, y, p, shift, zeta, rng), x, y, p) for _ in range(draws)])
    by_frames = np.stack([aug.temporal_event_shift(original.astype(np.uint16), shift, zeta, rng)[0] for _ in range(draws)])
    # Exact, draw by draw: the same number of events leaves and reaches every frame and channel.
    np.testing.assert_array_equal(by_events.sum(axis=(3, 4)), by_frames.astype(np.int64).sum(axis=(3, 4)))
    # In expectation, per pixel: X - qX + shift(qX) with q = round(zeta n) / n per frame and channel.
    totals = original.sum(axis=(2, 3), keepdims=True)
    share = np.divide(np.rint(zeta * totals), totals, out=np.zeros(totals.shape), where=totals > 0)
    expected = original - share * original + aug.frame_shift(share * original, shift)
    for sample in (by_events, by_frames):
        error = sample.mean(axis=0) - expected
        spread = sample.std(axis=0) / np.sqrt(draws)
        z = np.abs(error[spread > 0]) / spread[spread > 0]
        assert np.all(error[spread == 0] == 0)
        assert z.max() < 5.0 and abs(z.mean() - 0.8) < 0.15  # |N(0,1)| has mean 0.80
