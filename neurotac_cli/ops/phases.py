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
            "e.g. 0-21,22-121,122-143, or `auto`, `session` or `none`)"
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


def phases_from_ranges(n_frames: int, ranges: list[tuple[int, int]], start: int = 0) -> np.ndarray:
    """The phase of frames `start`..`n_frames - 1` given inclusive (first, last) frame ranges per phase."""
    labels = np.full(n_frames - start, NONE, dtype=object)
    for name, (first, last) in zip(PHASES, ranges):
        low, high = max(first, start), min(last + 1, n_frames)
        if low < high:
            labels[low - start:high - start] = name
    return labels


# ---------------------------------------------------------------- sessions: many grasps in one trial

# Shares of a grasp's own peak (above the rest level), per frame or in total.
MOVE_SHARE = 0.15  # a move of the gripper changes the force by at least this much
SLOPE_SHARE = 0.02  # per frame: a slower change is a held force settling (relaxation, regulation), not a move
TAIL_SHARE = 0.006  # per frame: a move goes on while the force keeps changing its way at least this fast
MERGE_FRAMES = 2  # contact dips of at most this many frames do not split a grasp


def label_session(force: np.ndarray, contact_share: float = CONTACT_SHARE, move_share: float = MOVE_SHARE,
                  slope_share: float = SLOPE_SHARE, block: int | None = None,
                  spikes: list | None = None, slow: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(phase per frame, grasp index per frame as int32, -1 for none) of a trial holding many grasps.

    A grasp is a run of frames in contact: force above the rest level (`rest_levels`: the 5th
    percentile of the log's stretches of `block` frames, which a drifting sensor moves) by more than
    `contact_share` of the force scale (95th percentile above rest) and by 5 noise s.d. (the noise is
    read from frame-to-frame differences; a log whose noise sets that bar is read through a centred
    median, `_calm`); dips of at most MERGE_FRAMES frames stay in the grasp; a
    run whose peak is within 10 noise s.d. of rest is noise, not a grasp. The frame that first reads
    below contact after a grasp is its last (releasing), as in `detect_phases`.

    Inside a grasp, a *move* is a run of frames in which the force changes the same way by more than
    `slope_share` of the grasp's peak per frame, by `move_share` of it in total, extended while it
    keeps changing that way by TAIL_SHARE of the peak (and 3 noise s.d.) per frame. Rising moves are grasping, falling moves
    releasing, everything else holding. So: the first rise is grasping from first contact; a
    re-grasp (loosen, tighten) is releasing then grasping; a partial release (a fall to a lower
    level that is then held) is releasing then holding; a force change while held slower than
    `slope_share` per frame, and a viscoelastic object relaxing, stay holding; after the last fall
    every frame to the end of contact is releasing.

    A run of contact with fewer frames in contact than MIN_GRASP_US holds (at the frames' period, which
    `block` gives), away from the log's ends, is a force sensor's glitch (or a burst of them), not a
    grasp: no gripper presses and lets go within it. Each is left at rest and, with `spikes`,
    appended there as (first frame, frames, peak above rest). A noise slower than the log's samples
    is read over lags (`slow_noise`) and, with `slow`, appended there as (its σ, the steps' σ).

    Limits: a grasp weaker than `contact_share` of the session's force scale is not found (a 0.5 N
    touch among 20 N grasps: lower `contact_share`); the noise is read from the trace itself, so it
    needs some tens of frames at rest to be read well.
    """
    force = np.asarray(force, dtype=np.float64)
    known = ~np.isnan(force)
    if not known.any():
        return np.full(len(force), NONE, dtype=object), np.full(len(force), -1, dtype=np.int32)
    logged, (force, noise, rest) = force, _calm(force, contact_share, block or REST_BLOCK)
    rest = rest_levels(force, contact_share, block) if rest is None else rest
    filled = np.where(known, force, rest)
    shortest = int(np.ceil(MIN_GRASP_US * (block or REST_BLOCK) / REST_STRETCH_US))
    short = []
    phase, grasp, threshold = _grasps(filled, rest, noise, shortest, contact_share, move_share, slope_share, short)
    sigma = slow_noise(force, filled - rest, grasp < 0, noise, block or REST_BLOCK, contact_share)
    if sigma is not None:  # its wander moved the levels of a few blocks by more than a step noise's bar
        short, rest = [], rest_levels(force, contact_share, block, sigma)
        filled = np.where(known, force, rest)
        phase, grasp, threshold = _grasps(filled, rest, sigma, shortest, contact_share, move_share, slope_share, short)
        if slow is not None:
            slow.append((sigma, noise))
    if spikes is not None:
        spikes += short
        if force is not logged:  # the median took the glitches out before they were runs
            spikes += _glitches(np.where(known, logged, rest), rest, threshold - rest, grasp, shortest)
    return phase, grasp


def _grasps(filled: np.ndarray, rest: np.ndarray, noise: float, shortest: int, contact_share: float, move_share: float,
            slope_share: float, spikes: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`label_session`'s (phase, grasp, contact threshold per sample) of a log with its missing
    samples at rest, at this noise σ; runs too short for a grasp appended to `spikes`."""
    n = len(filled)
    phase = np.full(n, NONE, dtype=object)
    grasp = np.full(n, -1, dtype=np.int32)
    threshold = rest + _contact_bar(filled - rest, contact_share, noise)
    index = 0
    for first, last in _contact_runs(filled > threshold):
        peak = float((filled[first:last + 1] - rest[first:last + 1]).max())
        if peak < max(10 * noise, 1e-6):
            continue
        if int((filled[first:last + 1] > threshold[first:last + 1]).sum()) < shortest and first > 0 and last < n - 1:
            spikes.append((first, last - first + 1, peak))
            continue
        end = min(last + 2, n)  # the first frame below contact is the grasp's last
        grasp[first:end] = index
        before = filled[first - 1] if first > 0 else rest[0]
        phase[first:end] = _grasp_phases(filled[first:end], before, float(rest[first]), noise, move_share, slope_share,
                                         ends_in_contact=end == last + 1)
        index += 1
    return phase, grasp, threshold


SLOW_NOISE_US = 640_000  # the longest lag `slow_noise` reads a log's noise over
SLOW_NOISE_RATIO = 2.5  # ... and how far above the sample-to-sample noise it must read to be used
SLOW_NOISE_MARGIN_US = 100_000  # ... between samples this far from a grasp found (its edges' frames under the bar)
SLOW_FIRST_RATIO = 1.5  # a first reading this far above the step noise is read again under a bar of its own


def slow_noise(force: np.ndarray, above: np.ndarray, resting: np.ndarray, noise: float, block: int,
               contact_share: float = CONTACT_SHARE) -> float | None:
    """The σ of a noise slower than the log's samples, where it reads more than SLOW_NOISE_RATIO times
    `noise` (the sample-to-sample one), else None. A load cell low-passed well below its sample rate
    (a sensor's anti-alias filter, a logger oversampling it) has steps a fraction of its noise (a
    third of it where each sample keeps 0.9 of the last), so a bar of 5 step σ sat inside the noise:
    with 0.2 N of it, 14-39% of the rest frames were grasps, and up to 2.2 times as many grasps as
    there were. It is read over lags (`_lagged_noise`) between samples `resting` and under the contact
    bar `above` their rest level; that bar, of the step noise, cuts such a noise's peaks off, so
    where the first reading passes SLOW_FIRST_RATIO times `noise` it is read again under a bar of
    its own. A white noise reads about the same at every lag, so its labels do not change."""
    sigma = _lagged_noise(force, resting & (above <= _contact_bar(above, contact_share, noise)), block)
    if sigma > SLOW_FIRST_RATIO * noise:
        sigma = _lagged_noise(force, resting & (above <= _contact_bar(above, contact_share, sigma)), block)
    return sigma if sigma > SLOW_NOISE_RATIO * noise else None


def _lagged_noise(force: np.ndarray, quiet: np.ndarray, block: int) -> float:
    """The largest spread of the differences of samples 1, 2, 4 ... samples apart, up to
    SLOW_NOISE_US, between known samples that lie SLOW_NOISE_MARGIN_US or more from any sample not
    `quiet`: a sample on a grasp, or on a weak one's edge, would read its force as noise (between
    grasps 0.2-0.6 s apart, a white noise read 2.5-5 times its σ where only the grasps were left
    out, and its grasps were lost); lags with under 200 such pairs are not read (0 where none is)."""
    n = len(force)
    loud = np.concatenate([[0], np.cumsum(~quiet | np.isnan(force))])
    index = np.arange(n)
    margin = max(1, int(SLOW_NOISE_MARGIN_US * block / REST_STRETCH_US))
    near = (loud[np.minimum(index + margin + 1, n)] - loud[np.maximum(index - margin, 0)]) > 0
    sigma, lag, longest = 0.0, 1, max(1, int(SLOW_NOISE_US * block / REST_STRETCH_US))
    while lag <= longest and 2 * lag < n:
        steps = (force[lag:] - force[:-lag])[~near[lag:] & ~near[:-lag]]
        if len(steps) < 200:
            break
        sigma = max(sigma, _spread(steps[::max(1, len(steps) // 100_000)]))  # 100,000 pairs read a σ to 0.3%
        lag *= 2
    return sigma


def _glitches(logged: np.ndarray, rest: np.ndarray, bar: np.ndarray, grasp: np.ndarray, shortest: int) -> list:
    """(first frame, frames, peak above rest) of each run of a log read through a median
    (`_calm`), as logged above its rest by the contact `bar` and by 5 of its own noise σ, peaking 10 σ
    above it (as a grasp must), shorter than `shortest` frames and away from the grasps found: the
    glitches the median left at rest."""
    noise = step_noise(np.diff(logged))
    near = np.convolve(grasp >= 0, np.ones(2 * MERGE_FRAMES + 1), "same") > 0
    above = logged - rest
    runs = _contact_runs((above > np.maximum(bar, 5 * noise)) & ~near)
    return [(first, last - first + 1, float(above[first:last + 1].max())) for first, last in runs
            if last - first + 1 < shortest and above[first:last + 1].max() >= 10 * noise]


CALM_US = (30_000, 50_000, 90_000)  # the centred medians `_calm` tries, shortest first: well inside our shortest grasp


def _calm(force: np.ndarray, contact_share: float, block: int) -> tuple[np.ndarray, float, np.ndarray | None]:
    """The log `label_session` reads, its noise σ and its rest levels where they were read here (else
    None): as logged where `contact_share` of its scale
    (the 95th percentile above its rest levels) stands above 5 noise σ, else the centred median of
    the fewest samples (CALM_US at the period `block` gives) whose noise does not (the longest
    where none), missing samples kept missing. A noisy load cell (0.2 N on grasps of 0.5-6 N) put
    the bar at 1 N: a quarter of the contact frames and a sixth of the grasps were lost. A median
    keeps a press's edge where it is and a glitch shorter than half its span out.

    The median's noise is the larger of the spread of the differences of medians `k` samples apart
    (two disjoint spans: a noise that is not white, a lagging sensor's, is not taken for smaller than
    it is) and a median's of white noise (1.2533 σ / √k: a quantised log's medians repeat a value).
    A median that leaves more than 0.8 of the noise is not used: a slow noise is not lowered by a
    few samples' median, which only takes off the peaks that carried weak grasps over the bar. Nor
    is a log of under three blocks read so: its one or two rest levels cannot follow a drift, which
    the noise of the log as logged keeps under the bar."""
    known, filled = _bridged(force)
    steps = np.diff(force)
    noise = step_noise(steps[~np.isnan(steps)]) if len(force) > 2 else 0.0  # the steps the log has: none across a gap
    if len(force) < 3 * block or noise == 0:
        return force, noise, None
    rest = rest_levels(force, contact_share, block)
    scale = contact_share * float(np.percentile(filled - rest, 95))
    calm = force, noise, rest
    if 5 * noise <= scale:
        return calm
    period_us = REST_STRETCH_US / block
    spans = dict.fromkeys(2 * int(round(us / period_us / 2)) + 1 for us in CALM_US)
    for k in [k for k in spans if k >= 3 and 4 * k <= len(force)]:
        median = np.median(np.lib.stride_tricks.sliding_window_view(np.pad(filled, k // 2, mode="edge"), k), axis=1)
        # no less than a median of k samples of white noise reads (a quantised log's medians repeat a value)
        sigma = max(_spread(median[k:] - median[:-k]), 1.2533 * noise / np.sqrt(k))
        if sigma > 0.8 * noise:
            continue
        calm = np.where(known, median, np.nan), sigma, None
        if 5 * sigma <= scale:
            break
    return calm


MIN_GRASP_US = 40_000  # a run of contact shorter than this is a force sensor's glitch (our grasps: 0.43 s and more)
REST_STRETCH_US = 10_000_000  # a stretch of the log whose 5th percentile is its rest level there
REST_BLOCK = 1000  # ... in samples, where their period is not known: 10 s of 10 ms frames


def rest_block(period_us: float | None) -> int:
    """The samples in REST_STRETCH_US at this sample period (REST_BLOCK where it is not known)."""
    return REST_BLOCK if not period_us or period_us <= 0 else max(2, int(round(REST_STRETCH_US / period_us)))


def rest_levels(force: np.ndarray, contact_share: float = CONTACT_SHARE, block: int | None = None,
                noise: float | None = None) -> np.ndarray:
    """The rest level of a log at each sample. Each `block` samples' 5th percentile (REST_BLOCK
    unless given: `rest_block`) is their rest, unless a grasp holds through the block: a block whose
    level stands above the line through its neighbours' (at an end, through the two nearest) by
    half the contact bar (`_contact_bar`: `contact_share` of the log's scale, or 5 noise σ), and above
    the lowest block on each side of it, is left out, again until none stands out, so a hold of any
    length reads no rest of its own; the rest is interpolated between the blocks kept. A force
    sensor's zero drifts (a strain gauge warming: 0.2 N a minute put a session's later rests above a
    level read once for the whole log, and they were labelled grasps), and a drift is a line through
    the blocks (each block's percentile read about that line, which is followed half a block past
    the log's ends, so that the drift inside a block does not sink its level). It can also step (the
    sensor re-tared, a cable knocked): the blocks after a step up have no lower block after them,
    so they are kept, and between two kept blocks apart by more than the contact bar the rest steps
    where the samples cross from one level to the other (`_rest_step`), not along a line. Missing
    samples (NaN) are left out of the levels, which are interpolated across them. A log of under
    two blocks has one level, its 5th percentile. `noise`: the log's noise σ where the caller read
    it (`slow_noise`; else its sample-to-sample steps')."""
    force = np.asarray(force, dtype=np.float64)
    if np.isnan(force).all():
        return np.zeros(len(force))
    x, y, _ = _rest_points(force, contact_share, block, noise)
    return _followed(np.arange(len(force), dtype=np.float64), x, y, block or REST_BLOCK)


def _bridged(force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(which samples are known, the log with its missing samples bridged by lines between the known)."""
    known = ~np.isnan(force)
    return known, force if known.all() else np.interp(np.arange(len(force)), np.flatnonzero(known), force[known])


def _rest_points(force: np.ndarray, contact_share: float, block: int | None,
                 noise: float | None = None) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """`rest_levels`' points (places, levels: a step is two points a sample apart) and the samples at
    which its steps begin, of a log with at least one known sample. The blocks are read once for
    the steps, then again on each side of them, so that no block mixes two zeros. Missing samples
    are left out of the levels and the steps (bridged from a grasp into a rest, they would read as
    either)."""
    known, filled = _bridged(force)
    block = block or REST_BLOCK
    noise = step_noise(np.diff(filled)) if noise is None else noise
    bar = _contact_bar(filled - float(np.percentile(filled, 5)), contact_share, noise)
    x, y = _block_rest(force, filled, 0, len(force), block, bar)
    # a step, not a drift: one block-to-block change apart by half the contact bar from what its
    # neighbours' rates make of its span (a long hold between two kept blocks spans several blocks)
    change, rate = np.diff(y), np.diff(y) / np.diff(x)
    around = np.array([np.median(np.delete(rate[max(k - 3, 0):k + 4], min(k, 3))) if len(rate) > 1 else 0.0
                       for k in range(len(rate))]) * np.diff(x)
    steps = {_rest_step(force, int(np.ceil(x[k - 1])) if k else 0, int(x[k + 2]) if k + 2 < len(x) else len(force) - 1,
                        y[k], y[k + 1]) for k in np.flatnonzero(np.abs(change - around) > 0.5 * bar)}
    steps = sorted((steps | _end_tares(filled, bar, block)) - {0, len(force)})
    if not steps:
        return x, y, []
    xs, ys = [], []
    for first, end in zip([0, *steps], [*steps, len(force)]):
        px, py = _block_rest(force, filled, first, end, block, bar)
        # flat to a step's side: the next part's level begins a sample on (the log's ends: followed)
        xs += [[first] if first else [], px, [end - 1] if end < len(force) else []]
        ys += [py[:1] if first else [], py, py[-1:] if end < len(force) else []]
    return np.concatenate(xs), np.concatenate(ys), steps


def _end_tares(filled: np.ndarray, bar: float, block: int) -> set[int]:
    """The steps of the rest in a log's first and last two `block`s, which its blocks do not show:
    one sample that drops the log, and its level, by more than the contact `bar` from a rest
    (REST_RUN samples flat within the bar, no sample of the log before them lower: three in a row,
    by half the bar) to a rest (the same, at the lowest level of the block after): a sensor tared
    after its log began, which read as a grasp from the first frame and swallowed the grasps before
    the tare; and the mirror at the end (one sample up from a rest to a rest held to the last:
    re-tared before the log stopped). A press moves the force over several samples, a tare in one; a hold from the log's
    first sample let go within one sample (or pressed within one and held to its last) reads as a
    tare: the limit, where a fast gripper or long frames make one-sample presses."""
    steps = set()
    for log, mirrored in ((filled, False), (filled[::-1], True)):
        drops = np.flatnonzero(log[:-1] - log[1:] > bar) + 1  # the first sample at the new level
        for at in drops[(drops >= REST_RUN) & (drops <= 2 * block)][::-1]:
            before, after = log[at - REST_RUN:at], log[at:at + REST_RUN]
            # the lowest level before it, of three samples in a row (a few samples at rest before a
            # hold tell it from a zero's offset; noise alone reaches no lower than the bar's half)
            lowest = float(np.median(np.lib.stride_tricks.sliding_window_view(log[:at], 3), axis=1).min())
            if len(after) == REST_RUN and max(np.ptp(before), np.ptp(after)) <= bar < np.median(before) - np.median(after) \
                    and abs(np.median(before) - lowest) <= bar / 2 \
                    and abs(np.median(after) - np.percentile(log[at:at + block], 5)) <= bar / 2:
                steps.add(len(log) - int(at) if mirrored else int(at))
                break
    return steps


def _block_rest(force: np.ndarray, filled: np.ndarray, first: int, end: int, block: int, bar: float) -> tuple[np.ndarray, np.ndarray]:
    """The places and levels of the rest blocks (`_rest_blocks`) of samples `first` to `end`, each the
    5th percentile of its known samples about the line through the blocks' 5th percentiles, at its
    known samples' mean place (a block with none is left out; `filled`, the log with its gaps
    bridged, where the samples hold none); under two blocks, their 5th percentile at their middle."""
    part = force[first:end] if not np.isnan(force[first:end]).all() else filled[first:end]
    known = ~np.isnan(part)
    blocks = (end - first) // block
    if blocks < 2:
        return np.array([first + (end - first - 1) / 2]), np.array([float(np.percentile(part[known], 5))])
    edges = np.linspace(0, end - first, blocks + 1).astype(int)
    spans = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if known[a:b].any()]
    centres = np.array([first + a + np.flatnonzero(known[a:b]).mean() for a, b in spans])  # where its samples are
    levels = np.array([np.percentile(part[a:b][known[a:b]], 5) for a, b in spans])
    kept = _rest_blocks(centres, levels, 0.5 * bar)
    centres, spans = centres[kept], [span for span, keep in zip(spans, kept) if keep]
    if len(centres) < 2:
        return centres, levels[kept]
    # each level read again about the line through them: a zero drifting 0.5 N a minute moves 0.08 N
    # in a block, and the block's 5th percentile, read flat, sits under most of its rest by half that
    # (a log at rest labelled one grasp from end to end); along the line, its rest's noise alone
    line = _followed(np.arange(first, end, dtype=np.float64), centres, levels[kept], block)
    levels = np.array([np.interp(c, centres, levels[kept]) + np.percentile((part[a:b] - line[a:b])[known[a:b]], 5)
                       for c, (a, b) in zip(centres, spans)])
    return centres, levels


def _rest_blocks(centres: np.ndarray, levels: np.ndarray, margin: float) -> np.ndarray:
    """Which blocks read a rest (`rest_levels`): the block that stands out most above the line through
    its kept neighbours, and above the lowest kept block on each side, left out first (a hold's
    edges go before its middle), until none does."""
    kept = np.ones(len(levels), dtype=bool)
    while kept.sum() > 1:
        index = np.flatnonzero(kept)
        # each kept block against the line through its kept neighbours; at an end, through the two
        # nearest (a drift goes on past them), or the one other where only two are kept
        if len(index) > 2:
            before, after = np.r_[index[1], index[:-2], index[-3]], np.r_[index[2], index[2:], index[-2]]
        else:
            before, after = index[::-1], index[::-1]
        width = centres[after] - centres[before]
        share = np.divide(centres[index] - centres[before], width, out=np.zeros(len(index)), where=width != 0)
        above = levels[index] - (levels[before] + share * (levels[after] - levels[before]))
        # a hold has rest on both sides; a block with none lower on one side is a zero that stepped
        # (at an end, where one side is empty, a hold to the end and a step cannot be told apart: a hold)
        kept_levels = levels[index]
        lowest_before = np.minimum.accumulate(np.r_[np.inf, kept_levels[:-1]])
        lowest_after = np.minimum.accumulate(np.r_[kept_levels[1:], np.inf][::-1])[::-1]
        floor = np.maximum(lowest_before, lowest_after)
        floor[~np.isfinite(floor)] = -np.inf
        above = np.where(kept_levels - floor > margin, above, -np.inf)
        worst = int(np.argmax(above))
        if above[worst] <= margin:
            break
        kept[index[worst]] = False
    return kept


REST_RUN = 10  # samples in a row within half a step of a level: the log resting there, not a press passing through it


def _rest_step(force: np.ndarray, first: int, last: int, before: float, after: float) -> int:
    """Where a rest level steps from `before` to `after` between samples `first` and `last`: after the
    last sample near the lower level where it steps up (after the step none reads so low), at the
    first where it steps down (before it none did); the crossing is half the step. Where the log is
    missing between that sample and the nearest rest at the other level (REST_RUN samples near it),
    the step is at the gap's start: a zero that moved while nothing was logged."""
    span = force[first:last + 1]
    half = abs(after - before) / 2
    near = np.flatnonzero(span < min(before, after) + half)
    if not len(near):
        return first if after < before else last + 1
    at = int(near[-1]) + 1 if after > before else int(near[0])
    resting = np.convolve(np.abs(span - (after if after > before else before)) < half, np.ones(REST_RUN), "valid") >= REST_RUN
    if after > before:  # the first rest at the new level after the crossing
        later = np.flatnonzero(resting[at:])
        bracket = (at, at + int(later[0]) if len(later) else len(span))
    else:  # the last rest at the old level before it
        earlier = np.flatnonzero(resting[:max(at - REST_RUN + 1, 0)])
        bracket = (int(earlier[-1]) + REST_RUN if len(earlier) else 0, at)
    missing = np.flatnonzero(np.isnan(span[bracket[0]:bracket[1]]))
    return first + (bracket[0] + int(missing[0]) if len(missing) else at)


def _contact_bar(above_rest: np.ndarray, contact_share: float, noise: float) -> float:
    """How far above its rest a log is in contact: `contact_share` of its force scale (the 95th
    percentile above rest), or 5 `noise` σ, whichever is larger (no NaN)."""
    return max(contact_share * float(np.percentile(above_rest, 95)), 5 * noise, 1e-6)


def rest_line(force: np.ndarray, block: int | None = None, grasp: np.ndarray | None = None,
              slow: float | None = None) -> np.ndarray | None:
    """A log's zero at each sample: the median of the samples between grasps (`label_session`) in each
    `block` samples (REST_BLOCK unless given), placed at their mean place, joined by lines and followed
    for half a block past the first and last (a drift goes on to the log's ends; a log that ends in a
    long grasp has no rest to say where it went). Where the rest levels step (`rest_levels`: a
    re-tared sensor), each side of the step has its own line. The rest levels that find the grasps
    are 5th percentiles, which sit about 1.6 noise σ under the rest's mean and, in a drifting block,
    at its early part. Under a noise slower than the samples (`slow_noise`), whose bar the grasps
    are found at, a weak grasp lies between them, and a sample between grasps above the contact bar
    of the log's sample-to-sample noise is left out (the zero up to 0.18 N r.m.s. off at 0.2 N of such
    noise, 0.08-0.13 N without those samples); that slower noise's bar also places the steps, whose
    wander moved a few blocks' levels by more than the other's. Where no sample lies between grasps
    (a trial held from start to end), the median of every sample per block; None where no sample is
    known. `grasp`: the log's grasp labels (`label_session`'s), where the caller has them, and
    `slow` the slower noise's σ it read for them (its `slow`), if any."""
    force = np.asarray(force, dtype=np.float64)
    known = ~np.isnan(force)
    if not known.any():
        return None
    block = block or REST_BLOCK
    if grasp is None:
        said = []
        grasp = label_session(force, block=block, slow=said)[1]
        slow = said[0][0] if said else None
    between = (grasp < 0) & known
    x, y, tares = _rest_points(force, CONTACT_SHARE, block, slow)
    if slow is not None:  # nor above the steps' noise's bar: a grasp too weak for the slower bar lies between grasps
        rest = _followed(np.arange(len(force), dtype=np.float64), x, y, block)
        steps = np.diff(force)
        bar = _contact_bar(np.where(known, force, rest) - rest, CONTACT_SHARE, step_noise(steps[~np.isnan(steps)]))
        between &= np.nan_to_num(force - rest) <= bar
    if not between.any():
        between = known
    bounds = [0, *tares, len(force)]
    line = np.empty(len(force))
    for first, end in zip(bounds[:-1], bounds[1:]):
        places = first + np.flatnonzero(between[first:end])
        if not len(places):  # a side of a step with no rest of its own: the samples it has, or the log's
            places = first + np.flatnonzero(known[first:end]) if known[first:end].any() else np.flatnonzero(known)
        line[first:end] = _joined(np.arange(first, end, dtype=np.float64), places, force[places], block)
    return line


def _joined(at: np.ndarray, places: np.ndarray, values: np.ndarray, block: int) -> np.ndarray:
    """At `at`, the line through the medians of `values` (at `places`) per `block` samples, each placed
    at its samples' mean place, followed half a block past the ends (`rest_line`)."""
    stretch = places // block
    points = [(places[stretch == k].mean(), np.median(values[stretch == k])) for k in np.unique(stretch)]
    x, y = (np.array(v) for v in zip(*points))
    return _followed(at, x, y, block)


def _followed(at: np.ndarray, x: np.ndarray, y: np.ndarray, block: int) -> np.ndarray:
    """At `at`, the line through the points (x, y), followed half a `block` past its first and last
    point along its first and last piece, flat beyond."""
    line = np.interp(at, x, y)
    if len(x) > 1:
        for ends, (a, b) in ((at < x[0], (0, 1)), (at > x[-1], (-2, -1))):
            near = np.clip(at[ends], x[0] - block / 2, x[-1] + block / 2)
            line[ends] = y[a] + (near - x[a]) * (y[b] - y[a]) / max(x[b] - x[a], 1e-9)
    return line


def rest_drift(force: np.ndarray, line: np.ndarray | None = None, contact_share: float = CONTACT_SHARE,
               block: int | None = None, noise: float | None = None) -> float | None:
    """How far a session log's zero (`rest_line`, or `line` where the caller has it) moves from its
    start to its end, where that passes half the contact bar (of the log's step noise, or `noise`
    where the caller read a slower one: `slow_noise`, whose wander moves the zero of a few blocks);
    else None (and for a log of under two blocks)."""
    force = np.asarray(force, dtype=np.float64)
    known = ~np.isnan(force)
    if known.sum() < 2 * (block or REST_BLOCK):
        return None
    line = rest_line(force, block) if line is None else line
    moved = float(line[-1] - line[0])
    bar = _contact_bar(force[known] - line[known], contact_share, noise or step_noise(np.diff(force[known])))
    return moved if abs(moved) > 0.5 * bar else None


QUANTUM_SHARE = 0.05  # steps of one quantum this common are a quantised log's noise (`step_noise`)


def step_noise(steps: np.ndarray) -> float:
    """A trace's sample-to-sample noise (σ) from its steps: the median absolute deviation of the steps,
    scaled to σ (x 1.4826) and from a difference of two samples to one (/ √2); a grasp's few large
    steps do not move it. At least the log's quantum where its noise flips it (QUANTUM_SHARE of the
    steps or more are one quantum): a log quantised more coarsely than its noise mostly repeats a
    value, and a deviation of 0 would make any step of noise a grasp; a clean trace's few steps are
    no noise."""
    steps = np.asarray(steps, dtype=np.float64)
    if not len(steps):
        return 0.0
    mad = _spread(steps)
    moved = np.abs(steps[steps != 0])
    if not len(moved):
        return mad
    quantum = float(moved.min())
    flips = np.count_nonzero(np.isclose(moved, quantum, rtol=0.01)) >= QUANTUM_SHARE * len(steps)
    return max(mad, quantum) if flips else mad


def _spread(steps: np.ndarray) -> float:
    """The σ of each of two samples whose differences are `steps`: their median absolute deviation,
    scaled to σ (x 1.4826) and from a difference to one sample (/ √2)."""
    return 1.4826 * float(np.median(np.abs(steps - np.median(steps)))) / np.sqrt(2)


def _contact_runs(touching: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) frames of each run of contact, runs apart by at most MERGE_FRAMES frames merged."""
    frames = np.flatnonzero(touching)
    if not frames.size:
        return []
    breaks = np.flatnonzero(np.diff(frames) > MERGE_FRAMES + 1)
    starts = np.concatenate([[frames[0]], frames[breaks + 1]])
    ends = np.concatenate([frames[breaks], [frames[-1]]])
    return list(zip(starts.tolist(), ends.tolist()))


def _grasp_phases(f: np.ndarray, before: float, rest: float, noise: float, move_share, slope_share,
                  ends_in_contact: bool) -> np.ndarray:
    """Phases of one grasp's frames (f: its force, `before`: the frame before it)."""
    peak = max(float(f.max()) - rest, 1e-9)
    change = np.diff(np.concatenate([[before], f]))
    labels = np.full(len(f), "holding", dtype=object)
    moves = _moves(change, peak, move_share, slope_share, tail=max(TAIL_SHARE * peak, 3 * noise))
    rises = [m for m in moves if m[2] > 0]
    # from first contact to the end of the first rise: grasping, however slowly the rise began
    labels[:moves[0][1] + 1 if moves and moves[0][2] > 0 else 1] = "grasping"
    for start, stop, sign in moves:
        labels[start:stop + 1] = "grasping" if sign > 0 else "releasing"
    falls = [m for m in moves if m[2] < 0]
    if falls and (not rises or falls[-1][0] > rises[-1][0]):
        labels[falls[-1][0]:] = "releasing"
    if not ends_in_contact:
        labels[-1] = "releasing"
    return labels


def _moves(change: np.ndarray, peak: float, move_share: float, slope_share: float, tail: float) -> list[tuple[int, int, int]]:
    """(first, last frame, +1 rising / -1 falling) of each move: fast same-way runs, extended while slower, big enough."""
    sign = np.where(change > slope_share * peak, 1, np.where(change < -slope_share * peak, -1, 0))
    moves = []
    k = 0
    while k < len(sign):
        if sign[k] == 0:
            k += 1
            continue
        way, start, stop = int(sign[k]), k, k
        while stop + 1 < len(sign) and way * change[stop + 1] > tail:
            stop += 1
        while start - 1 >= 0 and way * change[start - 1] > tail and (not moves or start - 1 > moves[-1][1]):
            start -= 1
        if way * change[start:stop + 1].sum() >= move_share * peak:
            moves.append((start, stop, way))
        k = stop + 1
    return moves


def session_columns(force: np.ndarray, n_real: int, n_total: int, window_us: int | None = None,
                    spikes: list | None = None, slow: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """`frame --phases session`: phase and grasp index of the first n_real frames (of `window_us`),
    padding frames none / -1; `spikes` and `slow` as `label_session`'s."""
    phase = np.full(n_total, NONE, dtype=object)
    grasp = np.full(n_total, -1, dtype=np.int32)
    if n_real and not np.isnan(force[:n_real]).all():
        phase[:n_real], grasp[:n_real] = label_session(force[:n_real], block=rest_block(window_us), spikes=spikes, slow=slow)
    return phase, grasp
