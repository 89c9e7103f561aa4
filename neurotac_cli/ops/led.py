"""The `led` sync method (thesis 3.6.1): the LED-off spike of OFF events.

The LED is switched off before each grasp and the force log starts at that instant. The
switch-off is a spike of OFF events over much of the field. OFF events are counted in 1 ms bins;
each bin is compared with the running median of the 50 ms around it (robust to background noise
and to the slower OFF bursts of contact), as a Poisson z-score; a spike must also cover a share of
the pixels (contact is local, the LED lights the whole membrane). The instant is the spike's onset
(the 0.5% quantile of its OFF event times) less the camera's response latency `latency_us` (the
photoreceptor needs time to cross its OFF threshold: ~170 µs for the simulated DAVIS240C behind the
membrane; measure it once on a real rig, or use `trigger`).
"""

import numpy as np

from neurotac_cli.errors import SyncError
from neurotac_cli.ops.instant import Instant

SMALL_LED_Z = 5  # a rejected burst this many times over the z bar is named as a small LED's, with its box
LED_LATENCY_US = 170  # spike onset minus LED switch-off, measured on the simulated DAVIS240C (docs/commands/sync.md)


def in_region(x, y, region):
    if region is None:
        return np.ones(len(x), dtype=bool)
    rx, ry, rw, rh = region
    return (x >= rx) & (x < rx + rw) & (y >= ry) & (y < ry + rh)


BACKGROUND_BINS = 51  # the running median that is a spike's background, in bins


STARTUP_US = 2_000  # a camera fires a burst as it starts (a Prophesee VGA recording here: 9 times its median OFF
# rate in its first millisecond, twice it to 2 ms): no burst of a recording's first 2 ms is taken for a blink


def led_spikes(t, x, y, p, method, count: int, sensor=None, spare: int = 1) -> list[Instant]:
    """The strongest LED-off spikes, `count` and up to `spare` more of OFF events alone (with those of
    both polarities stronger than them: `on_share`), in time order; SyncError when fewer than `count`
    stand out."""
    times, off_x, off_y = _off_events(t, x, y, p, method.region)
    bin_us = method.bin_us
    # a median's width of empty bins either side: a quiet --region holds OFF events only in its blink,
    # and bins from its first to its last OFF event alone would make the blink its own background
    origin = int(times.min()) - BACKGROUND_BINS * bin_us
    counts = np.bincount((times - origin) // bin_us, minlength=int((times.max() - origin) // bin_us) + 1 + BACKGROUND_BINS)
    counts = counts.astype(np.float64)
    from scipy.ndimage import median_filter

    background = median_filter(counts, size=BACKGROUND_BINS, mode="nearest")
    pair = counts + np.concatenate([counts[1:], [0.0]])  # a spike spreads over up to ~1.5 ms
    z = (pair - 2 * background) / np.sqrt(2 * background + 1)
    pixels = _pixels_seen(x, y, sensor, method.region)
    starting = int(np.min(t)) + STARTUP_US  # pairs of bins starting before it hold no blink (the recording's, not the region's, start)
    # candidates: local maxima of z, strongest first, at least 50 ms apart
    chosen, rejected, startup, on_times = [], [], None, _OnTimes(t, x, y, p, method.region)
    taken = np.zeros(len(z), dtype=bool)
    gap = max(1, 50_000 // bin_us)
    for i in np.argsort(-z, kind="stable")[: 200 + 4 * count]:  # a handful of candidates per wanted spike, not per event
        if taken[i] or z[i] <= 0:
            continue
        lo, hi = origin + i * bin_us, origin + (i + 2) * bin_us
        a, b = np.searchsorted(times, [lo, hi])
        coverage = len(np.unique(off_y[a:b].astype(np.int64) * 65536 + off_x[a:b])) / max(pixels, 1)
        if lo < starting:  # the camera's start-up, or a blink the recording began inside: said where it matters
            if startup is None and z[i] >= method.min_z and coverage >= method.min_coverage:
                startup = max(lo, int(times[a]) if b > a else lo)  # its first OFF event, not its bin's start
            continue
        taken[max(0, i - gap): i + gap + 1] = True
        if not (z[i] >= method.min_z and coverage >= method.min_coverage):
            rejected.append((float(z[i]), coverage, lo, a, b))
            continue
        # the spike may start in the bin before the best pair: take its neighbours too
        c, d = np.searchsorted(times, [lo - bin_us, hi + bin_us])
        # the pair starting at bin i holds the spike: its end is counted from the fuller bin
        end_bin = _burst_end(counts, background, i + int(np.argmax(counts[i : i + 2])))
        chosen.append(_spike_instant(times[c:d], z[i], coverage, origin + end_bin * bin_us, method.latency_us))
        _echo(chosen[-1], (i, end_bin, gap), z, times, off_x, off_y, (origin, bin_us, pixels, starting), method)
        chosen[-1].details["window_us"] = (lo - bin_us, hi + bin_us)
        # spikes of both polarities (a shaking membrane) do not use up the spare: more of them than it
        # stronger than the blink hid the blink from the choice (weighed only once there are more spikes than wanted)
        if len(chosen) >= count + spare and sum(on_times.share(spike) < MIXED_ON_PER_OFF for spike in chosen) >= count + spare:
            break
    if len(chosen) < count:
        best = max(rejected, default=None)  # its box only: the only one the error shows
        best = best and (*best[:3], _box(off_x[best[3]:best[4]], off_y[best[3]:best[4]], sensor))
        raise _no_spike(len(chosen), count, best, method, startup)
    if startup is not None:
        _after_startup(chosen, startup)
    for spike in chosen:  # the polarity of each, where more spikes stand out than are wanted
        if len(chosen) > count:
            on_times.share(spike)
        del spike.details["window_us"]
    return sorted(chosen, key=lambda instant: instant.t0)


ECHO_SHARE = 0.5  # a burst near a blink over this share of its pixels is the LED's own (a press darkens the object's patch)
ECHOES_WEIGHED = 8  # the bursts of highest z near a blink whose pixels are counted


def _echo(instant: Instant, spike: tuple, z: np.ndarray, times, off_x, off_y, binning: tuple, method):
    """Other blink-like bursts within the 50 ms about a spike (`spike`: its best pair's bin, its
    burst's end bin, the gap in bins), which no candidate can be: a switch that bounces, or an LED
    that flickers as it goes dark, blinks more than once, and the spike taken is the one of highest
    z, whichever the force log starts at. Said in one warning on the spike, with each other burst's
    instant as the spike's own is read (its onset less the latency). Bins of the camera's start-up
    (before `starting`) are not looked at: a burst there is said as that. A bounce within the
    burst's own few milliseconds is part of it."""
    i, end_bin, gap = spike
    origin, bin_us, pixels, starting = binning
    first = max(0, i - gap, -(-(starting - origin) // bin_us))
    near = np.arange(first, min(len(z), i + gap + 1))
    # pairs of bins that hold none of the spike's own burst, from the bin before its best pair to its end
    near = near[((near < i - 2) | (near > end_bin)) & (z[near] >= method.min_z)]
    others, looked = [], []
    for k in near[np.argsort(-z[near], kind="stable")]:
        if len(looked) >= ECHOES_WEIGHED:
            break
        if any(abs(k - seen) <= 2 for seen in looked):  # a neighbouring pair of a burst already looked at: the same burst
            continue
        looked.append(int(k))
        a, b = np.searchsorted(times, [origin + k * bin_us, origin + (k + 2) * bin_us])
        coverage = len(np.unique(off_y[a:b].astype(np.int64) * 65536 + off_x[a:b])) / max(pixels, 1)
        if coverage >= max(method.min_coverage, ECHO_SHARE * instant.details["coverage"]):
            c, d = np.searchsorted(times, [origin + (k - 1) * bin_us, origin + (k + 3) * bin_us])
            others.append((int(k), _spike_instant(times[c:d], z[k], coverage, 0, method.latency_us)))
    if others:
        onset = instant.details["onset_us"]
        listed = "; ".join(f"{other.details['onset_us']} µs, {abs(other.details['onset_us'] - onset) / 1000:.3g} ms "
                           f"{'after' if other.details['onset_us'] > onset else 'before'} (z {other.score:.0f}, covering "
                           f"{other.details['coverage']:.0%} of the pixels; its instant {other.t0} µs)" for _, other in sorted(others))
        instant.details.setdefault("warnings", []).append(
            f"blink-like bursts also at {listed}, beside the spike taken at {onset} µs (z {instant.score:.0f}): an LED switch that "
            "bounces, or a light that flickers, blinks more than once; the one of highest z was taken: check which one the force "
            "log starts at (a log of one trial is placed at another instant by --method offset --offset)")


MIXED_ON_PER_OFF = 0.5  # a spike with this many ON events per OFF event in its bins is weighed after those of OFF alone (sync)


class _OnTimes:
    """Each spike's ON events per OFF event in its bins (`on_share`): an LED switching off darkens every
    pixel it lights (a blink: 20 ON events against 80,838 OFF), where a gripper's motor shaking the
    membrane, or the scene moving past a camera on an arm, makes both polarities alike (about 1:1).
    The ON events' times (in the region) are taken out and put in order once, at the first spike
    weighed, so any number of spikes costs a bisection each."""

    def __init__(self, t, x, y, p, region):
        self.events, self.region, self.times = (t, x, y, p), region, None

    def share(self, spike: Instant) -> float:
        """The spike's ON share, counted in its bins (`window_us` of its details) the first time it is asked."""
        if "on_share" not in spike.details:
            if self.times is None:
                t, x, y, p = self.events
                on = t[(p == 1) & in_region(x, y, self.region)]
                self.times = on if bool(np.all(on[1:] >= on[:-1])) else np.sort(on)
            lo, hi = np.searchsorted(self.times, spike.details["window_us"])
            spike.details["on_share"] = round((hi - lo) / max(spike.details["spike_events"], 1), 3)
        return spike.details["on_share"]


def _startup_text(startup_us: int) -> str:
    return (f"a burst as bright as a blink in the recording's first {STARTUP_US / 1000:g} ms (at {startup_us} µs) is taken for the "
            "camera starting, not a blink: if the recording began inside the blink, start it earlier, or use --method "
            "xcorr or offset")


TAIL_US = 2 * STARTUP_US  # a burst this soon after a blink-like start-up burst may be that blink's tail


def _after_startup(chosen: list, startup_us: int):
    """A spike taken within TAIL_US after a start-up burst that would have passed as a blink may be
    that blink's tail (the recording began inside it), read late: a warning on it."""
    for instant in chosen:
        if instant.details["onset_us"] - startup_us < TAIL_US:
            instant.details.setdefault("warnings", []).append(
                f"the spike at {instant.details['onset_us']} µs may be the tail of a blink: {_startup_text(startup_us)}")


def _box(x: np.ndarray, y: np.ndarray, sensor=None):
    """(x0, y0, x1, y1) about most of a burst's events (the 5-95% of each coordinate, widened by a tenth
    each way: the background's events fall all over the view), inside the sensor where its size is
    known; None without events."""
    if len(x) == 0:
        return None
    (x0, x1), (y0, y1) = np.percentile(x, [5, 95]), np.percentile(y, [5, 95])
    wide, tall = 0.1 * (x1 - x0) + 1, 0.1 * (y1 - y0) + 1
    right, bottom = (sensor[0] - 1, sensor[1] - 1) if sensor else (np.inf, np.inf)
    return int(max(x0 - wide, 0)), int(max(y0 - tall, 0)), int(min(x1 + wide, right)), int(min(y1 + tall, bottom))


def _off_events(t, x, y, p, region):
    """Times (in order), x and y of the OFF events in `region`; SyncError when there are none."""
    off = (p == 0) & in_region(x, y, region)
    times, off_x, off_y = t[off], x[off], y[off]
    if len(times) > 1 and np.any(np.diff(times) < 0):
        order = np.argsort(times, kind="stable")
        times, off_x, off_y = times[order], off_x[order], off_y[order]
    if len(times) == 0:
        raise SyncError("no OFF events (in the region) to find an LED-off spike in (check --region, or use --method xcorr)")
    return times, off_x, off_y


def _pixels_seen(x, y, sensor, region) -> int:
    """How many pixels the LED could light: the region's, the sensor's, or the events' extent."""
    if sensor is not None:
        width, height = sensor
        return width * height if region is None else region[2] * region[3]
    return int((x.max() + 1) * (y.max() + 1)) if len(x) else 1


def _spike_instant(spike: np.ndarray, z: float, coverage: float, end_us: int, latency_us: int) -> Instant:
    """The instant of a spike's OFF event times: its onset (0.5% quantile) less the camera's latency."""
    onset = int(spike[min(len(spike) - 1, int(0.005 * len(spike)))])
    return Instant(
        t0=onset - latency_us,
        score=float(round(z, 1)),
        details={"onset_us": onset, "coverage": round(coverage, 3), "spike_events": int(len(spike)), "led_end_us": end_us},
    )


def _no_spike(found: int, count: int, best, method, startup: int | None = None) -> SyncError:
    """The error when fewer than `count` spikes stand out; `best` = (z, coverage, time, OFF events' box
    (x0, y0, x1, y1)) of the best rejected burst. A burst far above the bar in z over too few pixels
    may be a small LED's (one in a corner of the view): the error gives its box as a --region, unless
    a blink-like burst opened the recording (`startup`, its time): the recording may have begun inside
    its blink, and the best burst be that blink's tail (read late) or a bright object's release (the
    log placed 0.3 s late), so no bar or box of it is offered."""
    found_text = f"found {found} of {count}; " if count > 1 else ""
    detail = (f"best OFF burst at {best[2]} µs: z={best[0]:.1f}, covering {100 * best[1]:.1f}% of the pixels"
              if best else "no OFF burst at all")
    advice = "check the LED is in view, give --region, or use --method xcorr, trigger or offset"
    if startup is not None:  # no bar or box of the best burst: it may be the blink's tail, or a press the log cannot start at
        advice = _startup_text(startup) + "; a small LED elsewhere in the view: give its box with --region"
    elif best and best[0] >= SMALL_LED_Z * method.min_z and best[3] is not None:
        x0, y0, x1, y1 = best[3]
        advice = (f"if that burst is a small LED's (one in a corner of the view), give its box, --region {x0},{y0},"
                  f"{x1 - x0 + 1},{y1 - y0 + 1}, or --min-coverage {best[1] / 2:.2g} (half its share: other trials' blinks vary)")
    return SyncError(
        f"no LED-off spike stands out ({found_text}{detail}; a spike needs z >= {method.min_z:g} over "
        f">= {100 * method.min_coverage:g}% of the pixels); {advice}"
    )


def extra_spike(chosen: list[Instant], count: int, why: str = "") -> SyncError:
    """The error when more spikes stand out than the force log has trials: taking the strongest
    would put the trial's zero at whichever blink happened to be brighter. `why`: what else was tried."""
    onsets = ", ".join(f"{instant.details['onset_us']} µs" for instant in sorted(chosen, key=lambda instant: instant.t0))
    return SyncError(
        f"more LED-off spikes stand out than the force log has trials ({count}): at least {len(chosen)}, at {onsets}{why}; "
        "which one starts a trial is not ours to guess: give --region, cut the recording to one blink per trial "
        "(neurotac select --where \"t BETWEEN a AND b\"), or give the force log of every blink"
    )


def _burst_end(counts: np.ndarray, background: np.ndarray, peak: int, longest_bins: int = 20) -> int:
    """The first bin after `peak` whose OFF count is back within 5 sigma of the background."""
    stop = min(len(counts), peak + longest_bins)
    quiet = counts[peak:stop] <= background[peak:stop] + 5 * np.sqrt(background[peak:stop] + 1)
    return peak + (int(np.argmax(quiet)) if quiet.any() else stop - peak)


def led_burst_end_us(t_rel: np.ndarray, p: np.ndarray, bin_us: int = 1_000, around_us: int = 50_000) -> int:
    """Where the switch-off burst of an LED that went dark at time 0 ends (times relative to it):
    the first bin after its peak, within 2 bins of 0, whose OFF count is back to the background."""
    off = t_rel[(p == 0) & (t_rel >= -around_us) & (t_rel < around_us)]
    counts = np.bincount((off + around_us) // bin_us, minlength=2 * around_us // bin_us).astype(np.float64)
    from scipy.ndimage import median_filter

    background = median_filter(counts, size=51, mode="nearest")
    start = around_us // bin_us
    peak = start + int(np.argmax(counts[start : start + 3]))
    return _burst_end(counts, background, peak) * bin_us - around_us
