"""The `xcorr` sync method: no LED, the camera's event rate cross-correlated with the force log.

No LED: the camera's event rate is cross-correlated with the force log's |dF/dt|, both
in 250 µs bins smoothed over 1 ms (bins ten times above their surroundings, such as a blink, are
set to the surroundings' level so a blink cannot dominate). Two pieces of physics sit between the
two signals and are modelled rather than ignored:
* the force sensor answers late: a first-order lag y' = (F - y) / tau, with its own tau when
  loading (tau_rise) and when unloading (tau_fall), as strain-gauge cells (~1 ms) and
  polymer-covered force-sensing resistors (tens of ms, slower to recover) do. Then dy/dt is dF/dt
  through that lag, and sign(dy/dt) says which tau acts at each instant. The event rate, which
  follows |dF/dt| with no such lag, is passed through the same lag (tau_rise where the log rises,
  tau_fall where it falls) before it is compared: the clean camera signal is filtered, the noisy
  force log is never differentiated twice. The two taus are given (`sensor_lag_us`) or estimated
  jointly with the offset: every pair of a small geometric grid is tried, and of those within
  `XCORR_TIE` of the best correlation the fastest sensor is kept (a longer lag only smooths, and
  smoothing alone raises a correlation a little).
* the membrane saturates: a newton more changes the image less at high force (contact area and
  contrast approach their limits), so |dF/dt| is weighted by 1 / (1 + F / (s F_peak)) with F the
  force the sensor was following (y + tau dy/dt, smoothed) and s = `saturation` (0 = linear).
* polarity: the membrane darkens (OFF events) while it is loaded and brightens (ON) while it is
  unloaded, so the signed rate OFF - k ON (k balances the polarities over the recording; only
  pixels with >= 2 OFF and >= 1 ON, bursts left out) follows signed dF/dt. It is fitted too
  (finer tau grid, no tie rule, no saturation weighting) and kept when its sensor is slow to
  unload (tau_fall >= 15 ms): with a FlexiForce under a cover (simulated ch3) it cuts the error
  from max 20.3 / mean 7.9 ms to max 12.8 / mean 2.4 ms; with a fast cell the unsigned rate is
  better (the signed fit sees tau_fall <= 5 ms there and is not used). A bright object brightens the
  membrane as it presses: the signed rate is fitted with both signs and the better kept (its signal
  then "signed, pressed as ON"). Details: `signal`.
Among the offsets that keep the force log inside the recording (20 ms of slack at either end),
the one of the highest Pearson correlation, refined by a parabola, less the camera's response
delay `response_us` (the event rate follows the force ~1.6 ms late on the simulated rig:
photoreceptor and membrane), is the instant. Confidence = the correlation at the peak and its
margin over the best offset 20 ms or more away, for the chosen sensor model.
"""

import numpy as np

from neurotac_cli.errors import SyncError
from neurotac_cli.ops.instant import Instant
from neurotac_cli.ops.led import in_region
from neurotac_cli.ops.phases import rest_block, rest_levels, step_noise

XCORR_RESPONSE_US = 1_600  # event rate behind |dF/dt| (membrane creep, photoreceptor), simulated rig
XCORR_BIN_US = 250
XCORR_SMOOTH_US = 1_000
XCORR_SLACK_US = 20_000  # how far the force log may reach past the recording's ends
XCORR_SENSOR_LAGS_US = (0, 1_000, 2_000, 5_000, 10_000, 20_000, 40_000, 80_000)  # tau grid, rise x fall
XCORR_TIE = 0.01  # correlations this close are a tie: the faster sensor model wins
XCORR_SATURATION = 0.5  # membrane saturation force, as a share of the trace's peak force (0 = linear)
XCORR_SIGNED_LAGS_US = (0, 1_000, 2_000, 5_000, 10_000, 15_000, 20_000, 25_000, 30_000, 40_000, 60_000, 80_000, 120_000)
XCORR_SLOW_FALL_US = 15_000  # a sensor this slow to unload is aligned on the signed rate (OFF - ON) instead
XCORR_NEAR = 0.02  # offsets whose correlation is this close to the best span the reported uncertainty
XCORR_UNCERTAIN_US = 5_000  # sync warns about trials whose uncertainty is larger
XCORR_COARSE_US = 20_000  # a log's sample period whose square over this is its least uncertainty (see xcorr_instant)
# below this best correlation sync warns that camera and force log may not belong together; a warning,
# not a refusal, because matched and mismatched simulated pairs overlap (docs/journal.md)
XCORR_MIN_CORRELATION = 0.5


def xcorr_instant(t, x, y, force_t, force_v, method, p=None) -> Instant:
    """Align the camera's event rate with |dF/dt| through a force-sensor model (see the module doc);
    with polarities `p`, a slow sensor is aligned on the signed rate against signed dF/dt instead."""
    from scipy.ndimage import gaussian_filter1d

    bin_us = XCORR_BIN_US
    smooth = XCORR_SMOOTH_US / bin_us
    keep = in_region(x, y, method.region)
    times = t[keep]
    if len(times) < 100 or len(force_t) < 10:
        raise SyncError("too few events or force samples to cross-correlate (need activity during the grasp)")
    origin = int(times.min())
    bins = (times - origin) // bin_us
    rate, burst = _steady_rate(bins, bin_us)
    rate = gaussian_filter1d(rate, smooth)
    grid = np.arange(int(force_t[0]), int(force_t[-1]) + 1, bin_us)
    force = gaussian_filter1d(np.interp(grid, force_t, force_v), smooth)
    slope = np.gradient(force)  # N per bin
    if not np.any(slope) or rate.std() == 0:
        raise SyncError("the force log or the event rate is flat: nothing to cross-correlate")
    signed_rate = None if p is None else _signed_rate(bins, x[keep], y[keep], p[keep], burst)
    fit, signal = _chosen_fit(rate, None if signed_rate is None else gaussian_filter1d(signed_rate, smooth), force, slope, grid, method)
    peak, rise, fall, best, corr, lags, valid = fit
    shift, low, high, second = _around_the_peak(peak, best, corr, lags, valid, bin_us)
    # rate bin j covers [origin + j·bin, +bin): its centre matches force grid point j - lag
    t0 = origin + (lags[best] + shift + 0.5) * bin_us - int(force_t[0]) - method.response_us
    # between two samples the log is a straight line, whose error grows with the square of their spacing:
    # the plateau of the correlation alone does not cover a coarse log's error (12 ch4 trials: 50 Hz up
    # to 16.6 ms off beside plateaus of ±2.3-5.5 ms; 100 Hz up to 2.7 ms). At least half a period, and
    # a period's square over 20 ms (a whole period at 50 Hz, half of one at 100 Hz; docs/journal.md)
    period = float(np.median(np.diff(force_t)))
    uncertainty = max(int((high - low) * bin_us // 2), int(max(period / 2, period * period / XCORR_COARSE_US)))
    # near-best offsets that run to the end of those that keep the log inside the recording are no
    # peak: the correlation may go on rising past it (a membrane that lags the force by tens of ms, a
    # log that ends where the recording does): the uncertainty reaches at least the slack
    at_edge = not (0 < low and high < len(valid) - 1 and valid[low - 1] and valid[high + 1])
    if at_edge:
        uncertainty = max(uncertainty, XCORR_SLACK_US)
    return Instant(
        t0=int(round(t0)),
        score=round(peak, 3),
        details={
            "correlation": round(peak, 3),
            "margin": round(peak - second, 3),
            "uncertainty_us": uncertainty,
            "response_us": method.response_us,
            "sensor_rise_us": int(rise),
            "sensor_fall_us": int(fall),
            "sensor": "given" if method.sensor_lag_us is not None else "estimated",
            "saturation": method.saturation if signal == "rate" else 0.0,
            "signal": signal,
            **({"at_edge": True} if at_edge else {}),
        },
    )


def _chosen_fit(rate, signed_rate, force, slope, grid, method) -> tuple:
    """(the fit of `_xcorr_fit`, its signal's name): the event rate against |dF/dt|, or the signed rate
    (OFF - k ON on the pixels that darken and recover, None where there is none) against signed dF/dt,
    where loading and unloading cannot be mistaken for each other; the signed rate is kept when it sees
    a sensor slow to unload (measured better there, worse with a fast cell). A press darkens the
    membrane where the object is darker than it and brightens it where the object is brighter
    (`simulate --set object_contrast=-1.5`): the signed rate is fitted with both signs, the better kept."""
    fit = _xcorr_fit(rate, force, slope, grid, method, XCORR_SENSOR_LAGS_US, XCORR_TIE, method.saturation, signed=False)
    if signed_rate is not None:
        signed_fit = _xcorr_fit(signed_rate, force, slope, grid, method, XCORR_SIGNED_LAGS_US, 0.0, 0.0, signed=True,
                                signs=(1.0, -1.0))
        if signed_fit[2] >= XCORR_SLOW_FALL_US:
            return signed_fit[:7], "signed" if signed_fit[7] > 0 else "signed, pressed as ON"
    return fit[:7], "rate"


def _steady_rate(bins: np.ndarray, bin_us: int, length: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Events per bin, with blinks and flicker (bins far above their surroundings) set to the
    surroundings' level; and where they were."""
    from scipy.ndimage import median_filter

    rate = np.bincount(bins, minlength=length or 0).astype(np.float64)
    local = median_filter(rate, size=(50_000 // bin_us) | 1, mode="nearest")
    burst = rate > 10 * (local + 3)
    return np.where(burst, local, rate), burst


AGREE_BIN_US = 1_000
AGREE_SMOOTH_US = 10_000  # grasps last hundreds of ms: whether they line up needs no finer match
AGREE_LAG_US = 50_000  # the force sensor's and the membrane's lags, either way
AGREE_MIN = 0.2  # simulated sessions of `--vary all` physics: their own log r 0.82-0.93; another session's at most 0.17


def agreement(t, force_t, force_v, t0: int, sorted_time: bool = False, raw=None) -> float | None:
    """How well the event rate follows |dF/dt| with the force log placed at camera time `t0` (as a
    blink or a trigger placed it): Pearson r at the best lag within AGREE_LAG_US, of the rate as
    counted or without its slow changes, whichever is higher (`_rates_read`), over the whole
    sensor's event times `t` (an LED's --region holds no contact). None where the log holds no
    grasp (`_holds_a_grasp` of `raw`, the log as read, where `force_v` is filtered: a median
    flattens the noise the test measures), or it and the events share too little time to tell.
    `sorted_time`: `t` is in order, so the log's span is found by bisection rather than by a pass
    over every event."""
    from scipy.ndimage import gaussian_filter1d

    if len(force_t) < 10 or not _holds_a_grasp(np.asarray(force_v if raw is None else raw, dtype=np.float64), force_t):
        return None
    lo, hi = t0 + int(force_t[0]), t0 + int(force_t[-1])
    if sorted_time:
        times = t[np.searchsorted(t, lo):np.searchsorted(t, hi)]
    else:
        times = t[(t >= lo) & (t < hi)]
    lags = AGREE_LAG_US // AGREE_BIN_US
    if len(times) < 100:
        return None
    start, end = max(int(times.min()), lo), min(int(times.max()), hi)
    length = (end - start) // AGREE_BIN_US
    if length < 10 * lags:
        return None
    inside = times[(times >= start) & (times < start + length * AGREE_BIN_US)]
    rate = _steady_rate((inside - start) // AGREE_BIN_US, AGREE_BIN_US, length)[0][:length].astype(np.float64)
    grid = start + (np.arange(length) + 0.5) * AGREE_BIN_US
    force = gaussian_filter1d(np.interp(grid, t0 + np.asarray(force_t), np.asarray(force_v, dtype=np.float64)), AGREE_SMOOTH_US / AGREE_BIN_US)
    slope = np.abs(np.gradient(force))
    if not slope.any() or rate.std() == 0:
        return None
    # each lag's window of the slope, from -lags to +lags, against the rate as counted and without its slow changes
    scores = np.concatenate([_window_pearson(read[lags:length - lags], slope) for read in _rates_read(rate)])
    return round(float(np.nanmax(scores)), 3) if np.isfinite(scores).any() else None


AGREE_SLOW_US = 100_000  # the rate's changes slower than this (the lighting drifting) are taken out in one of its readings


def _rates_read(rate: np.ndarray) -> list:
    """The event rate (1 ms bins) as counted, and as its excess over its running median of
    AGREE_SLOW_US in Poisson σ, each smoothed by AGREE_SMOOTH_US. Lighting that drifts over a second
    swings the rate more than the grasps do (a simulated session lit 40% brighter and darker each
    second: r 0.01 with its own log as counted, 0.38 without the slow swings); a viscoelastic
    membrane's slow response is a grasp's own (an independent generator: 0.59-0.74 as counted,
    0.17-0.23 without). The log fits the events in whichever reading it fits better: another
    session's log fits neither (at most 0.17 over 102 pairs of four generators' sessions)."""
    from scipy.ndimage import gaussian_filter1d, median_filter

    smooth = AGREE_SMOOTH_US / AGREE_BIN_US
    # the median runs on the rate smoothed over 5 bins: a median of 1 ms Poisson counts steps by whole events
    trend = median_filter(gaussian_filter1d(rate, 5.0), size=AGREE_SLOW_US // AGREE_BIN_US + 1, mode="nearest")
    return [gaussian_filter1d(rate, smooth), gaussian_filter1d((rate - trend) / np.sqrt(trend + 1.0), smooth)]


def _holds_a_grasp(values: np.ndarray, t_us: np.ndarray) -> bool:
    """Whether a force log (its samples at times `t_us`) rises above its rest level (`rest_levels`,
    which a drifting zero moves) by 10 times its sample-to-sample noise, as `frame --phases session`
    finds a grasp: a log of a session without a grasp is noise, and the events' r with it says
    nothing about whose log it is."""
    finite = np.isfinite(values)
    values, t_us = values[finite], np.asarray(t_us)[finite]
    if len(values) < 3:
        return False
    rest = rest_levels(values, block=rest_block(float(np.median(np.diff(t_us)))))
    return float(np.max(values - rest)) > 10 * step_noise(np.diff(values))


def _window_pearson(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pearson r of `a` with every window of `b` as long as `a` (b[k:k + len(a)], k = 0 .. len(b) -
    len(a)), NaN where either is flat: the products by FFT (`_xc`), the windows' sums from running sums."""
    m = len(a)
    s_ab = _xc(b, a)[m - 1:len(b)]
    running = np.concatenate([[0.0], np.cumsum(b)]), np.concatenate([[0.0], np.cumsum(b * b)])
    s_b, s_bb = (total[m:] - total[:-m] for total in running)
    cov = s_ab - a.sum() * s_b / m
    var = (np.dot(a, a) - a.sum() ** 2 / m) * (s_bb - s_b * s_b / m)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(var > 1e-12 * np.maximum(np.dot(a, a) * s_bb, 1e-300), cov / np.sqrt(np.maximum(var, 1e-300)), np.nan)


def disagreement_warnings(trials: dict, how: str) -> list[str]:
    """One warning for the trials whose force log, placed by `how` (a blink, a trigger), hardly moves
    with the events: a log of another recording paired with this one."""
    low = {name: info["agreement"] for name, info in trials.items() if info.get("agreement") is not None and info["agreement"] < AGREE_MIN}
    if not low:
        return []
    worst = min(low, key=low.get)
    return [f"on {len(low)} of {len(trials)} trial(s) the force log, placed by {how}, hardly moves with the events (r below "
            f"{AGREE_MIN} with |dF/dt|; lowest {low[worst]:.3f}, {worst}): is each log paired with its own recording?"]


def _around_the_peak(peak, best, corr, lags, valid, bin_us):
    """(shift of the peak by a parabola through its neighbours, in bins; first and last index of the
    run of near-best offsets around it; the best correlation 20 ms or more away)."""
    shift = 0.0
    if 0 < best < len(corr) - 1 and np.isfinite(corr[best - 1]) and np.isfinite(corr[best + 1]):
        left, right = corr[best - 1], corr[best + 1]
        denominator = left - 2 * peak + right
        if denominator < 0:
            shift = 0.5 * (left - right) / denominator
    far = np.abs(lags - lags[best]) >= 20_000 // bin_us
    below = np.flatnonzero(corr < peak - XCORR_NEAR)
    low = below[below < best][-1] + 1 if (below < best).any() else 0
    high = below[below > best][0] - 1 if (below > best).any() else len(corr) - 1
    second = float(np.max(corr[far & valid])) if (far & valid).any() else 0.0
    return shift, low, high, second


def _signed_rate(index, x, y, p, burst):
    """OFF - k ON events per bin on the pixels that both darken and recover (>= 2 OFF, >= 1 ON): the
    membrane's darkening rate. `index`: each event's bin; `burst`: the bins of a blink or flicker
    (xcorr's rate), left out with their neighbours; k balances the two polarities over the recording
    (the thresholds differ). None when there is no such pixel."""
    bins = len(burst)
    burst = burst.copy()
    burst[1:] |= burst[:-1].copy()
    burst[:-1] |= burst[1:].copy()
    calm = ~burst[index]
    pixel = y.astype(np.int64) * 65536 + x
    _, owner = np.unique(pixel[calm], return_inverse=True)
    is_off = p[calm] == 0
    offs = np.bincount(owner, weights=is_off)
    ons = np.bincount(owner, weights=~is_off)
    active = ((offs >= 2) & (ons >= 1))[owner]
    off = np.bincount(index[calm][active & is_off], minlength=bins).astype(np.float64)[:bins]
    on = np.bincount(index[calm][active & ~is_off], minlength=bins).astype(np.float64)[:bins]
    if off.sum() == 0 or on.sum() == 0:
        return None
    return off - off.sum() / on.sum() * on


ACTIVE_SHARE = 0.05  # a force log's grasps: where it reads above this share of its peak


def _xcorr_fit(rate, force, slope, grid, method, lag_grid, tie: float, saturation: float, signed: bool, signs=(1.0,)):
    """Every sensor model (given, or each pair of `lag_grid`) against every offset: (correlation, rise,
    fall, best lag index, correlation by lag, lags, valid lags, sign) of the chosen model. The target is
    |dF/dt| (weighted by the membrane saturation) or, when `signed`, dF/dt itself; each of `signs`
    reads the correlations as they are (1) or turned over (-1: the rate negated, which the sensor's
    lag, linear, passes on), from one grid."""
    from scipy.ndimage import gaussian_filter1d

    bin_us = XCORR_BIN_US
    smooth = XCORR_SMOOTH_US / bin_us
    rising = (slope > 0).astype(np.float64)
    falling = 1.0 - rising
    peak_force = max(float(np.percentile(force, 99)), 1e-12)
    candidates = [tuple(method.sensor_lag_us)] if method.sensor_lag_us is not None else [
        (rise, fall) for rise in lag_grid for fall in lag_grid
    ]
    # the rate through each time constant, and its sums for each side: once per tau, not per (rise, fall) pair
    lagged = {tau: _first_order_lag(rate, tau, bin_us) for tau in {tau for pair in candidates for tau in pair}}
    on_rise = {rise: _SensorSide(lagged[rise], rising) for rise in {pair[0] for pair in candidates}}
    on_fall = {fall: _SensorSide(lagged[fall], falling) for fall in {pair[1] for pair in candidates}}
    lags = np.arange(-len(grid) + 1, len(rate))
    overlap = np.minimum(len(rate), lags + len(grid)) - np.maximum(0, lags)
    # the force trace lies inside the recording. One longer than the recording (a logger started before
    # the camera, or stopped after it) cannot: its grasps (where it leaves rest) must, and the rest logged
    # before or after them may reach past its ends. (Letting a trace that fits reach past them too moved
    # simulated `ch5` offsets by 60 ms: its own ends hold the offset in place.)
    slack = XCORR_SLACK_US // bin_us
    pressed = np.flatnonzero(np.abs(force) > ACTIVE_SHARE * peak_force)
    first, last = (pressed[0], pressed[-1]) if len(grid) > len(rate) and len(pressed) else (0, len(grid) - 1)
    valid = (lags + first >= -slack) & (lags + last < len(rate) + slack)
    # the force the sensor was following, y + tau dy/dt smoothed, is linear in the taus: its parts are smoothed once
    smoothed = [gaussian_filter1d(part, 8 * smooth) for part in (force, slope * rising / bin_us, slope * falling / bin_us)]
    fits = []
    for rise, fall in candidates:
        target = slope if signed else np.abs(slope)
        if saturation > 0:
            followed = smoothed[0] + rise * smoothed[1] + fall * smoothed[2]
            target = target / (1.0 + np.clip(followed, 0, None) / (saturation * peak_force))
        raw = _pearson_by_lag(overlap, on_rise[rise], on_fall[fall], target)
        for sign in signs:
            corr = np.where(valid & np.isfinite(raw), sign * raw, -np.inf)
            best = int(np.argmax(corr))
            fits.append((float(corr[best]), rise, fall, best, corr, sign))
    top = max(fit[0] for fit in fits)
    if not np.isfinite(top):
        raise SyncError("the force log's grasps span longer than the recording: no offset puts them inside it")
    # a slower sensor model also smooths, which alone lifts a correlation a little: near-ties go to the faster
    peak, rise, fall, best, corr, sign = min((fit for fit in fits if fit[0] >= top - tie), key=lambda fit: (fit[1] + fit[2], -fit[0]))
    return peak, rise, fall, best, corr, lags, valid, sign


def _first_order_lag(signal: np.ndarray, tau_us: float, bin_us: int) -> np.ndarray:
    """The signal through a first-order lag of time constant tau (starting settled at its first value)."""
    if tau_us <= 0:
        return signal
    from scipy.signal import lfilter

    alpha = 1.0 - np.exp(-bin_us / tau_us)
    filtered, _ = lfilter([alpha], [1.0, alpha - 1.0], signal, zi=[(1.0 - alpha) * signal[0]])
    return filtered


def _xc(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """sum over j of u[L + j] v[j], for every lag L from -len(v) + 1 to len(u) - 1 (FFT)."""
    from scipy.signal import correlate

    return correlate(u, v, mode="full", method="fft")


class _SensorSide:
    """The event rate through one time constant, read where the sensor is in that state (mask, 0/1
    on the force's clock), with its sums for every lag, which do not depend on the force side."""

    def __init__(self, rate: np.ndarray, mask: np.ndarray):
        self.rate, self.mask = rate, mask
        self.s_a, self.s_aa = _xc(rate, mask), _xc(rate * rate, mask)


def _pearson_by_lag(n: np.ndarray, rise: _SensorSide, fall: _SensorSide, b: np.ndarray) -> np.ndarray:
    """Pearson correlation, for every lag L, of a[L + j] with b[j] over their overlap (n values), where
    a[L + j] = rise.rate[L + j] if rise.mask[j] else fall.rate[L + j] (the sensor's state is read on b's
    clock). Every sum is a cross-correlation (FFT): the masks are 0/1 and complementary, so a, a² and
    a·b split by side."""
    ones = np.ones(len(rise.rate))
    s_a, s_aa = rise.s_a + fall.s_a, rise.s_aa + fall.s_aa
    s_ab = _xc(rise.rate, rise.mask * b) + _xc(fall.rate, fall.mask * b)
    s_b, s_bb = _xc(ones, b), _xc(ones, b * b)
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = s_ab - s_a * s_b / n
        var = (s_aa - s_a * s_a / n) * (s_bb - s_b * s_b / n)
        return np.where((n > 1) & (var > 1e-12 * np.maximum(s_aa * s_bb, 1e-300)), cov / np.sqrt(np.maximum(var, 1e-300)), np.nan)


def uncertainty_warnings(trials: dict) -> list[str]:
    """One warning for the trials (sync metadata per trial) whose offset is uncertain by more than
    XCORR_UNCERTAIN_US; none when every trial is sure enough."""
    wide = {name: info["uncertainty_us"] for name, info in trials.items()
            if info.get("uncertainty_us", 0) > XCORR_UNCERTAIN_US and not info.get("at_edge")}  # `edge_warnings` says why
    if not wide:
        return []
    worst = max(wide, key=wide.get)
    return [f"xcorr's offset is uncertain by more than ±{XCORR_UNCERTAIN_US / 1000:g} ms on {len(wide)} of {len(trials)} "
            f"trial(s) (largest ±{wide[worst] / 1000:.1f} ms, {worst}; a slow force sensor, or a log sampled more "
            f"than {XCORR_UNCERTAIN_US / 1000:g} ms apart?); an LED blink (--method led) "
            "or a trigger aligns within 0.1 ms"]


def edge_warnings(trials: dict) -> list[str]:
    """One warning for the trials whose best offset lies at the end of the offsets xcorr may take."""
    edge = [name for name, info in trials.items() if info.get("at_edge")]
    if not edge:
        return []
    return [f"on {len(edge)} of {len(trials)} trial(s) ({edge[0]}{', ...' if len(edge) > 1 else ''}) xcorr's best offset is the "
            f"last it may take (the force log may reach at most {XCORR_SLACK_US / 1000:g} ms past either end of the recording), "
            "not a peak: the true one may lie beyond; record some rest before and after each grasp, or use --method led or trigger"]


XCORR_NOISY_SHARE = 0.02  # a log's sample noise (σ) above this share of its range lowers r by itself (0.15 N on 3.4 N: r 0.22 at the right offset)


def force_noise_share(values: np.ndarray) -> float:
    """A force log's sample-to-sample noise (σ, `step_noise`) as a share of its range (0.5th to 99.5th
    percentile); 0 where it has no range."""
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if len(values) < 3:
        return 0.0
    span = float(np.percentile(values, 99.5) - np.percentile(values, 0.5))
    return step_noise(np.diff(values)) / span if span > 0 else 0.0


def unrelated_warnings(trials: dict) -> list[str]:
    """One warning for the trials whose event rate and force log hardly correlate at any offset,
    naming a noisy log as a cause that does not need a wrong pairing (`force_noise_share`)."""
    low = {name: info["correlation"] for name, info in trials.items() if info.get("correlation", 1.0) < XCORR_MIN_CORRELATION}
    if not low:
        return []
    worst = min(low, key=low.get)
    noisy = trials[worst].get("force_noise_share", 0.0)
    why = (f"; its force log's noise is {100 * noisy:.1f}% of its range, which alone lowers r: where the log is noisy "
           "a low r is expected of a right pairing too") if noisy >= XCORR_NOISY_SHARE else ""
    return [f"on {len(low)} of {len(trials)} trial(s) the event rate and the force log correlate below "
            f"{XCORR_MIN_CORRELATION} at their best offset (lowest r {low[worst]:.3f}, {worst}): are they of the same "
            f"grasp? Check the pairing; an LED blink (--method led) or a trigger does not depend on it{why}"]
