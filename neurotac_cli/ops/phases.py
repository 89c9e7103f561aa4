"""Grasp phases per frame: grasping (force rises), holding (plateau), releasing (force falls), none.

Detected from the framed force trace, or given as frame ranges (thesis ch. 3: frames 1-22 / 23-122 /
123-144, i.e. `0-21,22-121,122-143` in the 0-based `frame` column).
"""

import re

import numpy as np

from neurotac_cli.errors import UsageError

PHASES = ("grasping", "holding", "releasing")
NONE = "none"

# Detection thresholds, as shares of the trial's force range above its baseline.
CONTACT_SHARE = 0.05  # force above baseline + 5% of the range = in contact
PLATEAU_SHARE = 0.90  # force above baseline + 90% of the range = holding


def detect_phases(force: np.ndarray, contact_share: float = CONTACT_SHARE, plateau_share: float = PLATEAU_SHARE) -> np.ndarray:
    """Label each frame from its force (read at the frame's end): `none` before contact and after
    release, `grasping` while the force rises to its plateau, `holding` from the first to the last
    frame on the plateau, `releasing` while it falls, up to and including the frame in which it
    drops below the contact threshold. A grasp whose force relaxes out of the plateau band while
    it is held (a viscoelastic object: ch3's foam loses 15% in 300 ms) keeps holding until its final
    fall, found as the knee of a hinge fitted to the force from the plateau's start to the fall's
    midpoint.

    The baseline is the force's 5th percentile and the plateau level its 95th (robust to spikes);
    frames with a missing force count as below contact. A trace with no rise above the noise
    (range < 1e-6 N) is all `none`.
    """
    force = np.asarray(force, dtype=np.float64)
    labels = np.full(len(force), NONE, dtype=object)
    known = ~np.isnan(force)
    if not known.any():
        return labels
    baseline = float(np.percentile(force[known], 5))
    level = float(np.percentile(force[known], 95))
    span = level - baseline
    if span < 1e-6:
        return labels
    filled = np.where(known, force, baseline)
    contact = np.flatnonzero(filled > baseline + contact_share * span)
    plateau = np.flatnonzero(filled >= baseline + plateau_share * span)
    first_contact, last_contact = int(contact[0]), int(contact[-1])
    first_hold, last_hold = int(plateau[0]), int(plateau[-1])
    release = last_hold + 1
    # the final fall starts at the knee of a hinge (a line, then a line with a bend) fitted by least
    # squares from the plateau's start to the first frame below half the range after the last above it
    above = np.flatnonzero(filled[first_hold:] >= baseline + 0.5 * span)
    end = first_hold + int(above[-1]) + 1
    if end < len(filled) and end - last_hold > 3:  # a fall of 1-3 frames after the plateau: the plateau rule holds
        release = max(release, _knee(filled[first_hold:end + 1]) + first_hold + 1)
    labels[first_contact:first_hold] = "grasping"
    labels[first_hold:release] = "holding"
    # the frame whose end first reads below contact is the one the release finished in: releasing too
    labels[release:last_contact + 2] = "releasing"
    return labels


def _knee(y: np.ndarray) -> int:
    """The index b of the best hinge fit y ~ a + c i + d max(0, i - b), over b = 1 .. len - 2."""
    i = np.arange(len(y), dtype=np.float64)
    best, knee = np.inf, len(y) - 2
    for b in range(1, len(y) - 1):
        basis = np.column_stack([np.ones_like(i), i, np.maximum(0.0, i - b)])
        coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
        sse = float(np.sum((basis @ coef - y) ** 2))
        if sse < best:
            best, knee = sse, b
    return knee


def parse_ranges(text: str) -> list[tuple[int, int]]:
    """`0-21,22-121,122-143` -> [(0, 21), (22, 121), (122, 143)]: inclusive frame numbers for
    grasping, holding and releasing, in the 0-based numbering of the `frame` column."""
    parts = [part.strip() for part in str(text).split(",")]
    if len(parts) != 3:
        raise UsageError(
            f"cannot read phases {text!r} (give three inclusive frame ranges for grasping, holding and releasing, "
            "e.g. 0-21,22-121,122-143, or `auto`)"
        )
    ranges = []
    for part in parts:
        match = re.match(r"^(\d+)\s*-\s*(\d+)$", part)
        if not match or int(match.group(1)) > int(match.group(2)):
            raise UsageError(f"cannot read phase range {part!r} in {text!r} (write FIRST-LAST frame numbers, e.g. 22-121)")
        ranges.append((int(match.group(1)), int(match.group(2))))
    for (_, end), (start, _) in zip(ranges, ranges[1:]):
        if start <= end:
            raise UsageError(f"phase ranges {text!r} overlap or are out of order (grasping, then holding, then releasing)")
    return ranges


def phases_from_ranges(n_frames: int, ranges: list[tuple[int, int]]) -> np.ndarray:
    labels = np.full(n_frames, NONE, dtype=object)
    for name, (first, last) in zip(PHASES, ranges):
        labels[first:last + 1] = name
    return labels
