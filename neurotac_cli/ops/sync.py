"""Find the shared instant of camera and force logger; cut and label trials (thesis 3.6.1).

Methods (each returns the sync instants t0 on the camera clock, one per force-log trial):

- `led`: the LED is switched off before each grasp and the force log starts at that instant. The
  switch-off is a spike of OFF events over much of the field. OFF events are counted in 1 ms bins;
  each bin is compared with the running median of the 50 ms around it (robust to background noise
  and to the slower OFF bursts of contact), as a Poisson z-score; a spike must also cover a share of
  the pixels (contact is local, the LED lights the whole membrane). The instant is the spike's onset
  (the 0.5% quantile of its OFF event times) less the camera's response latency `latency_us` (the
  photoreceptor needs time to cross its OFF threshold: ~170 µs for the simulated DAVIS240C behind the
  membrane; measure it once on a real rig, or use `trigger`).
- `trigger`: external trigger events of an AEDAT 4.0 file (schema metadata `neurotac:triggers`).
- `offset`: a known clock offset: the force log's zero is camera time `offset_us`.
- `xcorr`: no LED: the camera's event rate is cross-correlated with the force log's |dF/dt|, both
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
    better (the signed fit sees tau_fall <= 5 ms there and is not used). Details: `signal`.
  Among the offsets that keep the force log inside the recording (20 ms of slack at either end),
  the one of the highest Pearson correlation, refined by a parabola, less the camera's response
  delay `response_us` (the event rate follows the force ~1.6 ms late on the simulated rig:
  photoreceptor and membrane), is the instant. Confidence = the correlation at the peak and its
  margin over the best offset 20 ms or more away, for the chosen sensor model.

A long session (several force-log trials in one camera file) is cut into trials: trial i holds the
events up to the end of its force log (or the next instant, if sooner); the events after that are
the next trial's lead-in, as in a file of one grasp (the first trial holds all that came before).
Force is conditioned as in the thesis: a median filter (window `median_us`), in newtons.
"""

from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from neurotac_cli import provenance, schema as sch
from neurotac_cli.errors import NeurotacError, SyncError
from neurotac_cli.io.force import ForceLog

METHODS = ("led", "trigger", "offset", "xcorr")
LED_LATENCY_US = 170  # spike onset minus LED switch-off, measured on the simulated DAVIS240C (docs/commands/sync.md)
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
# below this best correlation sync warns that camera and force log may not belong together; a warning, not a
# refusal: simulated grasps matched 0.43-0.88, mismatched 0.45-0.89 (examples/sync_mismatch.py, docs/journal.md)
XCORR_MIN_CORRELATION = 0.5


@dataclass(frozen=True)
class SyncMethod:
    """How to find the sync instant. Validated when built."""

    method: str = "led"
    offset_us: int | None = None
    region: tuple | None = None  # (x, y, w, h) where the LED is seen
    latency_us: int = LED_LATENCY_US
    response_us: int = XCORR_RESPONSE_US
    sensor_lag_us: tuple | None = None  # xcorr: the force sensor's (rise, fall) time constants; None = estimate
    saturation: float = XCORR_SATURATION
    min_z: float = 10.0
    min_coverage: float = 0.05
    trigger_type: str | None = None
    median_us: int = 10_000
    bin_us: int = 1_000
    keep_led: bool = False  # keep the blink's own events in the trial (they are a marker, not touch)

    def __post_init__(self):
        if self.method not in METHODS:
            raise NeurotacError(f"unknown sync method {self.method!r} (use one of {', '.join(METHODS)})")
        if self.method == "offset" and self.offset_us is None:
            raise NeurotacError("--method offset needs --offset DURATION (the camera time of the force log's zero)")
        if self.region is not None and (len(self.region) != 4 or self.region[2] <= 0 or self.region[3] <= 0):
            raise NeurotacError(f"region must be X,Y,W,H with positive W and H, got {self.region!r}")
        if self.median_us < 0:
            raise NeurotacError("the median filter window cannot be negative")
        if self.sensor_lag_us is not None and (len(self.sensor_lag_us) != 2 or min(self.sensor_lag_us) < 0):
            raise NeurotacError(f"the sensor lag is RISE[,FALL], two durations >= 0, got {self.sensor_lag_us!r}")
        if self.saturation < 0:
            raise NeurotacError("the membrane saturation share cannot be negative (0 = a linear membrane)")

    def args(self) -> dict:
        out = {"method": self.method, "median_us": self.median_us}
        if self.method == "offset":
            out["offset_us"] = self.offset_us
        if self.method == "led":
            out.update(latency_us=self.latency_us, min_z=self.min_z, min_coverage=self.min_coverage, keep_led=self.keep_led)
        if self.method == "xcorr":
            out["response_us"] = self.response_us
            out["sensor_lag_us"] = None if self.sensor_lag_us is None else list(self.sensor_lag_us)
            out["saturation"] = self.saturation
        if self.method == "trigger":
            out["trigger_type"] = self.trigger_type
        if self.region is not None:
            out["region"] = list(self.region)
        return out


@dataclass
class Instant:
    t0: int
    score: float | None = None
    details: dict = field(default_factory=dict)


# ---------------------------------------------------------------- force conditioning


def condition_force(log: ForceLog, median_us: int) -> np.ndarray:
    """Median-filter the force (window `median_us`, as an odd number of samples; 0 = none)."""
    values = np.asarray(log.value, dtype=np.float64)
    if median_us <= 0 or len(values) < 3 or log.period_us <= 0:
        return values
    size = int(round(median_us / log.period_us))
    size = max(1, size if size % 2 else size + 1)
    if size <= 1:
        return values
    from scipy.ndimage import median_filter

    return median_filter(values, size=size, mode="nearest")


# ---------------------------------------------------------------- led


def _in_region(x, y, region):
    if region is None:
        return np.ones(len(x), dtype=bool)
    rx, ry, rw, rh = region
    return (x >= rx) & (x < rx + rw) & (y >= ry) & (y < ry + rh)


def find_led_spikes(t, x, y, p, method: SyncMethod, count: int, sensor=None) -> list[Instant]:
    """The `count` strongest LED-off spikes, in time order; SyncError when fewer stand out."""
    off = (p == 0) & _in_region(x, y, method.region)
    times, off_x, off_y = t[off], x[off], y[off]
    if len(times) > 1 and np.any(np.diff(times) < 0):
        order = np.argsort(times, kind="stable")
        times, off_x, off_y = times[order], off_x[order], off_y[order]
    if len(times) == 0:
        raise SyncError("no OFF events (in the region) to find an LED-off spike in (check --region, or use --method xcorr)")
    bin_us = method.bin_us
    origin = int(times.min())
    index = (times - origin) // bin_us
    counts = np.bincount(index).astype(np.float64)
    from scipy.ndimage import median_filter

    background = median_filter(counts, size=51, mode="nearest")
    pair = counts + np.concatenate([counts[1:], [0.0]])  # a spike spreads over up to ~1.5 ms
    excess = pair - 2 * background
    z = excess / np.sqrt(2 * background + 1)
    if sensor is not None:
        width, height = sensor
        pixels = width * height if method.region is None else method.region[2] * method.region[3]
    else:
        pixels = int((x.max() + 1) * (y.max() + 1)) if len(x) else 1
    # candidates: local maxima of z, strongest first, at least 50 ms apart
    order = np.argsort(-z, kind="stable")
    chosen, rejected = [], []
    taken = np.zeros(len(z), dtype=bool)
    gap = max(1, 50_000 // bin_us)
    for i in order[: 200 + 4 * count]:  # a handful of candidates per wanted spike, not per event
        if taken[i] or z[i] <= 0:
            continue
        lo, hi = origin + i * bin_us, origin + (i + 2) * bin_us
        a, b = np.searchsorted(times, [lo, hi])
        pix = np.unique(off_y[a:b].astype(np.int64) * 65536 + off_x[a:b])
        coverage = len(pix) / max(pixels, 1)
        taken[max(0, i - gap): i + gap + 1] = True
        if z[i] >= method.min_z and coverage >= method.min_coverage:
            # the spike may start in the bin before the best pair: take its neighbours too
            c, d = np.searchsorted(times, [lo - bin_us, hi + bin_us])
            spike = times[c:d]
            onset = int(spike[min(len(spike) - 1, int(0.005 * len(spike)))])
            chosen.append(
                Instant(
                    t0=onset - method.latency_us,
                    score=float(round(z[i], 1)),
                    details={
                        "onset_us": onset,
                        "coverage": round(coverage, 3),
                        "spike_events": int(len(spike)),
                        # the pair starting at bin i holds the spike: its end is counted from the fuller bin
                        "led_end_us": origin + _burst_end(counts, background, i + int(np.argmax(counts[i : i + 2]))) * bin_us,
                    },
                )
            )
            if len(chosen) == count:
                break
        else:
            rejected.append((float(z[i]), coverage, lo))
    if len(chosen) < count:
        best = max(rejected, default=None)
        found = f"found {len(chosen)} of {count}; " if count > 1 else ""
        detail = (
            f"best OFF burst at {best[2]} µs: z={best[0]:.1f}, covering {100 * best[1]:.1f}% of the pixels"
            if best
            else "no OFF burst at all"
        )
        raise SyncError(
            f"no LED-off spike stands out ({found}{detail}; a spike needs z >= {method.min_z:g} over "
            f">= {100 * method.min_coverage:g}% of the pixels); check the LED is in view, give --region, "
            "or use --method xcorr, trigger or offset"
        )
    return sorted(chosen, key=lambda instant: instant.t0)


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


# ---------------------------------------------------------------- trigger, offset


def find_triggers(schema: pa.Schema, method: SyncMethod, count: int) -> list[Instant]:
    triggers = sch.get_meta(schema, "neurotac:triggers", None)
    if not triggers:
        raise SyncError(
            "the recording has no external trigger events (only AEDAT 4.0 files carry them, kept by `neurotac import`); "
            "use --method led, xcorr or offset"
        )
    kinds = sorted({str(item.get("type")) for item in triggers})
    chosen = [item for item in triggers if method.trigger_type in (None, item.get("type"))]
    if not chosen:
        raise SyncError(f"no trigger of type {method.trigger_type!r} (the file has {', '.join(kinds)}); choose one with --trigger-type")
    if count > 1 and len(chosen) != count:
        raise SyncError(
            f"{len(chosen)} triggers but {count} trials in the force log; pick a trigger type with --trigger-type "
            f"(the file has {', '.join(kinds)})"
        )
    return [Instant(t0=int(item["t"]), details={"type": item.get("type"), "triggers": len(chosen)}) for item in chosen[:count]]


# ---------------------------------------------------------------- xcorr


def xcorr_instant(t, x, y, force_t, force_v, method: SyncMethod, p=None) -> Instant:
    """Align the camera's event rate with |dF/dt| through a force-sensor model (see the module doc);
    with polarities `p`, a slow sensor is aligned on the signed rate against signed dF/dt instead."""
    from scipy.ndimage import gaussian_filter1d, median_filter

    bin_us = XCORR_BIN_US
    smooth = XCORR_SMOOTH_US / bin_us
    keep = _in_region(x, y, method.region)
    times = t[keep]
    if len(times) < 100 or len(force_t) < 10:
        raise SyncError("too few events or force samples to cross-correlate (need activity during the grasp)")
    origin = int(times.min())
    bins = (times - origin) // bin_us
    rate = np.bincount(bins).astype(np.float64)
    # blinks and flicker: bins far above their surroundings are set to the surroundings' level
    local = median_filter(rate, size=(50_000 // bin_us) | 1, mode="nearest")
    burst = rate > 10 * (local + 3)
    rate = gaussian_filter1d(np.where(burst, local, rate), smooth)
    grid = np.arange(int(force_t[0]), int(force_t[-1]) + 1, bin_us)
    force = gaussian_filter1d(np.interp(grid, force_t, force_v), smooth)
    slope = np.gradient(force)  # N per bin
    if not np.any(slope) or rate.std() == 0:
        raise SyncError("the force log or the event rate is flat: nothing to cross-correlate")
    fit = _xcorr_fit(rate, force, slope, grid, method, XCORR_SENSOR_LAGS_US, XCORR_TIE, method.saturation, signed=False)
    signal = "rate"
    signed_rate = None if p is None else _signed_rate(bins, x[keep], y[keep], p[keep], burst)
    if signed_rate is not None:
        # the signed rate, OFF - k ON on the pixels that darken and recover, follows signed dF/dt, where
        # loading (darkening) and unloading (brightening) cannot be mistaken for each other; it is kept
        # when it sees a sensor slow to unload (measured better there, worse with a fast cell)
        signed_fit = _xcorr_fit(gaussian_filter1d(signed_rate, smooth), force, slope, grid, method, XCORR_SIGNED_LAGS_US, 0.0, 0.0, signed=True)
        if signed_fit[2] >= XCORR_SLOW_FALL_US:
            fit, signal = signed_fit, "signed"
    peak, rise, fall, best, corr, lags, valid = fit
    shift = 0.0
    if 0 < best < len(corr) - 1 and np.isfinite(corr[best - 1]) and np.isfinite(corr[best + 1]):
        left, right = corr[best - 1], corr[best + 1]
        denominator = left - 2 * peak + right
        if denominator < 0:
            shift = 0.5 * (left - right) / denominator
    far = np.abs(lags - lags[best]) >= 20_000 // bin_us
    below = np.flatnonzero(corr < peak - XCORR_NEAR)  # the run of near-best offsets around the best
    low = below[below < best][-1] + 1 if (below < best).any() else 0
    high = below[below > best][0] - 1 if (below > best).any() else len(corr) - 1
    second = float(np.max(corr[far & valid])) if (far & valid).any() else 0.0
    # rate bin j covers [origin + j·bin, +bin): its centre matches force grid point j - lag
    t0 = origin + (lags[best] + shift + 0.5) * bin_us - int(force_t[0]) - method.response_us
    return Instant(
        t0=int(round(t0)),
        score=round(peak, 3),
        details={
            "correlation": round(peak, 3),
            "margin": round(peak - second, 3),
            "uncertainty_us": int((high - low) * bin_us // 2),
            "response_us": method.response_us,
            "sensor_rise_us": int(rise),
            "sensor_fall_us": int(fall),
            "sensor": "given" if method.sensor_lag_us is not None else "estimated",
            "saturation": method.saturation if signal == "rate" else 0.0,
            "signal": signal,
        },
    )


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


def _xcorr_fit(rate, force, slope, grid, method: SyncMethod, lag_grid, tie: float, saturation: float, signed: bool):
    """Every sensor model (given, or each pair of `lag_grid`) against every offset: (correlation, rise,
    fall, best lag index, correlation by lag, lags, valid lags) of the chosen model. The target is
    |dF/dt| (weighted by the membrane saturation) or, when `signed`, dF/dt itself."""
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
    valid = overlap >= len(grid) - XCORR_SLACK_US // bin_us  # the force trace lies inside the recording
    # the force the sensor was following, y + tau dy/dt smoothed, is linear in the taus: its parts are smoothed once
    smoothed = [gaussian_filter1d(part, 8 * smooth) for part in (force, slope * rising / bin_us, slope * falling / bin_us)]
    fits = []
    for rise, fall in candidates:
        target = slope if signed else np.abs(slope)
        if saturation > 0:
            followed = smoothed[0] + rise * smoothed[1] + fall * smoothed[2]
            target = target / (1.0 + np.clip(followed, 0, None) / (saturation * peak_force))
        corr = _pearson_by_lag(overlap, on_rise[rise], on_fall[fall], target)
        corr = np.where(valid & np.isfinite(corr), corr, -np.inf)
        best = int(np.argmax(corr))
        fits.append((float(corr[best]), rise, fall, best, corr))
    top = max(fit[0] for fit in fits)
    if not np.isfinite(top):
        raise SyncError("the recording is shorter than the force log: nothing to cross-correlate")
    # a slower sensor model also smooths, which alone lifts a correlation a little: near-ties go to the faster
    peak, rise, fall, best, corr = min((fit for fit in fits if fit[0] >= top - tie), key=lambda fit: (fit[1] + fit[2], -fit[0]))
    return peak, rise, fall, best, corr, lags, valid


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


# ---------------------------------------------------------------- trials


@dataclass
class Source:
    """One camera recording with its force log and labels (one manifest row, or the command line)."""

    trial: str
    events: pa.Table
    force: list  # list[ForceLog]
    labels: dict = field(default_factory=dict)


def sync_source(source: Source, method: SyncMethod) -> tuple[list[dict], dict]:
    """Sync one recording: (trials for schema.recordings_table, sync info per trial)."""
    table = source.events
    t = _column(table, "t", np.int64)
    x = _column(table, "x", np.uint16)
    y = _column(table, "y", np.uint16)
    p = _column(table, "p", np.uint8)
    logs = source.force
    count = len(logs)
    forces = [condition_force(log, method.median_us) for log in logs]
    if method.method == "led":
        instants = find_led_spikes(t, x, y, p, method, count, sch.sensor_of(table.schema))
    elif method.method == "trigger":
        instants = find_triggers(table.schema, method, count)
    elif method.method == "offset":
        if count > 1:
            raise SyncError(f"--method offset gives one instant, but the force log holds {count} trials; use --method led or trigger")
        instants = [Instant(t0=int(method.offset_us), details={"offset_us": int(method.offset_us)})]
    else:
        if count > 1:
            raise SyncError(f"--method xcorr aligns one force trace, but the force log holds {count} trials; split the log")
        instants = [xcorr_instant(t, x, y, logs[0].t, forces[0], method, p)]
    order = np.argsort(t, kind="stable") if len(t) > 1 and np.any(np.diff(t) < 0) else None
    if order is not None:
        t, x, y, p = t[order], x[order], y[order], p[order]
    # trial i ends where its force log ends (or at the next instant, if sooner); what follows, up
    # to the next instant, is the next trial's lead-in (its LED blink), as in one-grasp files
    bounds = []
    for instant, following, log in zip(instants, instants[1:], logs):
        end = instant.t0 + int(log.t[-1]) + max(int(log.period_us), 1)
        bounds.append(min(end, following.t0))
    cuts = [0] + [int(np.searchsorted(t, bound)) for bound in bounds] + [len(t)]
    trials, info = [], {}
    for i, (instant, log, values) in enumerate(zip(instants, logs, forces)):
        name = source.trial if count == 1 else (log.trial or f"{source.trial}-{i + 1:02d}")
        a, b = cuts[i], cuts[i + 1]
        led_end = instant.details.get("led_end_us")
        if led_end is not None and not method.keep_led:
            # the blink's switch-off burst marks the instant; it is not touch: leave it out of the trial
            a_led = max(a, int(np.searchsorted(t, led_end)))
            instant.details["led_events_removed"] = a_led - a
            a = a_led
        trials.append(
            {
                "trial": name,
                "t0": instant.t0,
                "events": (t[a:b] - instant.t0, x[a:b], y[a:b], p[a:b]),
                "force": (log.t, values.astype(np.float32)),
                "labels": dict(source.labels),
            }
        )
        entry = {"t0": instant.t0, "score": instant.score}
        entry.update(instant.details)
        if log.notes:
            entry["notes"] = log.notes
        info[name] = entry
    return trials, info


def _column(table: pa.Table, name: str, dtype) -> np.ndarray:
    return table.column(name).to_numpy().astype(dtype, copy=False)


def sync_sources(sources, method: SyncMethod) -> pa.Table:
    """Sync every source (an iterable, read one at a time) into one recordings table."""
    trials, info, sensor, inputs = [], {}, None, []
    for source in sources:
        inputs.append(source.events.schema)
        found = sch.sensor_of(source.events.schema)
        if sensor is None:
            sensor = found
        elif found is not None and found != sensor:
            raise NeurotacError(
                f"recording of trial {source.trial} is {found[0]}x{found[1]}, the others {sensor[0]}x{sensor[1]}; "
                "sync recordings of one sensor together"
            )
        made, details = sync_source(source, method)
        for trial in made:
            if trial["trial"] in info:
                raise NeurotacError(f"trial {trial['trial']!r} appears twice; give each trial its own name")
        trials += made
        info.update(details)
    sync = dict(method.args())
    sync["trials"] = info
    width, height = sensor if sensor else (None, None)
    return provenance.carry(sch.recordings_table(trials, width, height, sync=sync), inputs)


# ---------------------------------------------------------------- inputs


@dataclass(frozen=True)
class ForceOptions:
    time_column: str | None = None
    force_column: str | None = None
    time_unit: str | None = None
    force_unit: str | None = None

    def read(self, path: str) -> list:
        from neurotac_cli.io.force import read_force_log

        return read_force_log(path, self.time_column, self.force_column, self.time_unit, self.force_unit)


def read_camera(path: str, sensor=None) -> pa.Table:
    """A camera file in any format `import` reads, or an events table, as one events table."""
    from neurotac_cli import tables
    from neurotac_cli.io import is_table, read_events_table

    if is_table(path):
        table = tables.read([path], kind="events")
        if sensor is not None:
            table = table.replace_schema_metadata(sch.set_meta(table.schema, sensor=sch.sensor_meta(*sensor)).metadata)
        return table
    return read_events_table(path, sensor=sensor)


MANIFEST_REQUIRED = ("trial", "events", "force")


def manifest_sources(path: str, force_options: ForceOptions, sensor=None, labels: dict | None = None):
    """Sources from a manifest CSV: one row per recording with columns trial, events, force (paths
    relative to the manifest's folder) and label columns. Columns named `true_*` (ground truth of
    simulated data) are neither used nor copied. Files are read one row at a time."""
    import csv
    import os

    if not os.path.isfile(path):
        raise NeurotacError(f"{path}: no such manifest")
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        raise NeurotacError(f"{path}: the manifest has no rows")
    missing = [name for name in MANIFEST_REQUIRED if name not in rows[0]]
    if missing:
        raise NeurotacError(
            f"{path}: the manifest has no {', '.join(missing)} column (columns: {', '.join(rows[0])}; "
            "expected trial,events,force,<labels>...)"
        )
    folder = os.path.dirname(os.path.abspath(path))
    label_names = [name for name in rows[0] if name not in MANIFEST_REQUIRED and not name.startswith("true_") and name]
    for number, row in enumerate(rows, start=2):
        if not row["events"] or not row["force"] or not row["trial"]:
            raise NeurotacError(f"{path}: line {number} lacks a trial, events or force entry")
        row_labels = dict(labels or {})
        row_labels.update({name: row[name] for name in label_names if row.get(name) not in (None, "")})
        yield Source(
            trial=row["trial"],
            events=read_camera(os.path.join(folder, row["events"]), sensor),
            force=force_options.read(os.path.join(folder, row["force"])),
            labels=row_labels,
        )
