"""The DVS pixel model (DAVIS240C-like) on log intensity.

Each pixel low-pass filters the log of its photocurrent (photoreceptor bandwidth proportional to the
intensity), compares the filtered level with the level at its last event, and fires ON when it rose
by its ON threshold, OFF when it fell by its OFF threshold (thresholds differ per pixel by a few
percent: mismatch). Several events can fire within one simulation step; each is timed to the µs where
the filtered level crossed its threshold (linear within the step). After an event the pixel is blind
for the refractory period; the reset absorbs what it missed. Background activity (leak and shot
noise, mostly ON) and hot pixels are drawn analytically as Poisson processes over the whole array.

Only pixels whose intensity changes are simulated step by step: the contact region of every trial
(all trials in lockstep, vectorised over trials and pixels). The LED blink changes every pixel by the
same factor, so its events are computed in closed form for the whole array.
"""

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from neurotac_cli.sim import contact
from neurotac_cli.sim.config import MATERIALS


@dataclass
class Camera:
    """Fixed pattern of one camera + membrane: brightness, thresholds, hot pixels."""

    brightness: np.ndarray  # (H, W) lit membrane, relative
    on_threshold: np.ndarray  # (H, W)
    off_threshold: np.ndarray
    hot_x: np.ndarray
    hot_y: np.ndarray

    @property
    def shape(self):
        return self.brightness.shape


def make_camera(config, rng: np.random.Generator) -> Camera:
    w, h = config.sensor_width, config.sensor_height
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
    brightness = (1.0 - config.vignetting * r2) * (1.0 + config.texture * rng.standard_normal((h, w)))
    brightness = np.clip(brightness, 0.05, None).astype(np.float32)
    mismatch = config.threshold_mismatch
    on = config.on_threshold * np.clip(1 + mismatch * rng.standard_normal((h, w)), 0.5, 1.5)
    off = config.off_threshold * np.clip(1 + mismatch * rng.standard_normal((h, w)), 0.5, 1.5)
    hot = rng.choice(w * h, size=min(config.hot_pixels, w * h), replace=False)
    return Camera(brightness, on.astype(np.float32), off.astype(np.float32), hot % w, hot // w)


def _tau_us(config, intensity):
    """Photoreceptor time constant (µs): bandwidth scales with the photocurrent."""
    return 1e6 / (2 * np.pi * config.cutoff_hz * np.clip(intensity, 0.02, None))


# ---------------------------------------------------------------- the LED blink, in closed form


def led_events(config, camera: Camera, on_us: float, off_us: float, rng: np.random.Generator):
    """Events of the whole array for the LED switched on at `on_us` and off at `off_us` (µs, any clock).

    Returns (t, x, y, p) and the per-pixel residual (reference minus level) after the blink, which is
    the state the contact simulation starts from. The filtered log level approaches its new value
    exponentially, so the k-th threshold crossing is at t_k = -tau ln(1 - level_k / delta).
    """
    h, w = camera.shape
    base = camera.brightness + config.dark_level
    delta = np.log((camera.brightness * (1 + config.led_gain) + config.dark_level) / base)
    tau_on = _tau_us(config, camera.brightness * (1 + config.led_gain))
    tau_off = _tau_us(config, camera.brightness)
    on_t, off_t = camera.on_threshold, camera.off_threshold
    # Unknown history before the blink: the reference sits anywhere in its dead band.
    ref = -off_t + rng.random((h, w)).astype(np.float32) * (on_t + off_t) * 0.999
    pieces = []
    kmax = int(np.ceil(float(delta.max() / camera.on_threshold.min()))) + 1
    ref_after = ref.copy()
    for k in range(1, kmax + 1):  # at most a handful of thresholds per blink; vectorised over pixels
        level = ref + k * on_t
        fire = (level < delta) & (level > 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = on_us - tau_on * np.log1p(-np.where(fire, level / delta, 0.0))
        pieces.append((t, fire, 1, k))
        ref_after = np.where(fire, level, ref_after)
    ref = ref_after
    kmax = int(np.ceil(float((ref.max() + 1e-9) / camera.off_threshold.min()))) + 1
    for k in range(1, kmax + 1):
        level = ref - k * off_t
        fire = level > 0.02 * delta  # the level approaches 0 asymptotically: crossings very near it are lost in noise
        with np.errstate(invalid="ignore", divide="ignore"):
            t = off_us - tau_off * np.log(np.where(fire, level / delta, 1.0))
        pieces.append((t, fire, 0, k))
        ref_after = np.where(fire, level, ref_after)
    ys, xs = np.mgrid[0:h, 0:w]
    out_t, out_x, out_y, out_p = [], [], [], []
    for t, fire, polarity, k in pieces:
        out_t.append(t[fire] + rng.exponential(15.0, int(fire.sum())))  # latency jitter (µs)
        out_x.append(xs[fire])
        out_y.append(ys[fire])
        out_p.append(np.full(int(fire.sum()), polarity, np.uint8))
    t = np.concatenate(out_t)
    events = (np.round(t).astype(np.int64), np.concatenate(out_x), np.concatenate(out_y), np.concatenate(out_p))
    return _refractory(events, config.refractory_us, w), ref_after.astype(np.float32)


def _refractory(events, refractory_us, width):
    """Drop events of a pixel closer than the refractory period to its previous event (vectorised)."""
    t, x, y, p = events
    if not t.size or refractory_us <= 0:
        return events
    pixel = y.astype(np.int64) * width + x
    order = np.lexsort((t, pixel))
    t_s, pix_s = t[order], pixel[order]
    # Events of one pixel after a kept one: keep only those past the refractory time since the previous.
    gap = np.diff(t_s, prepend=t_s[0] - refractory_us - 1)
    same = np.concatenate([[False], pix_s[1:] == pix_s[:-1]])
    keep = ~same | (gap >= refractory_us)
    kept = order[keep]
    return t[kept], x[kept], y[kept], p[kept]


# ---------------------------------------------------------------- noise


def noise_events(config, camera: Camera, start_us: int, end_us: int, rng: np.random.Generator):
    """Background activity over the whole array and hot pixels, as Poisson processes (no per-pixel loop)."""
    h, w = camera.shape
    span = max(0, end_us - start_us)
    n = rng.poisson(config.background_rate_hz * w * h * span * 1e-6)
    t = rng.integers(start_us, max(start_us + 1, end_us), n)
    x = rng.integers(0, w, n)
    y = rng.integers(0, h, n)
    p = (rng.random(n) < config.background_on_share).astype(np.uint8)
    counts = rng.poisson(config.hot_rate_hz * span * 1e-6, camera.hot_x.size)
    hot_t = rng.integers(start_us, max(start_us + 1, end_us), int(counts.sum()))
    hot_x = np.repeat(camera.hot_x, counts)
    hot_y = np.repeat(camera.hot_y, counts)
    return (
        np.concatenate([t, hot_t]).astype(np.int64),
        np.concatenate([x, hot_x]),
        np.concatenate([y, hot_y]),
        np.concatenate([p, np.ones(hot_t.size, np.uint8)]),
    )


# ---------------------------------------------------------------- contacts, stepped in lockstep


def membrane_force(config, force: np.ndarray, step_us: int) -> np.ndarray:
    """Force the membrane deforms under: saturating (compaction) and creeping (a delayed share).

    g = Fs tanh(F / Fs); deformation = (1 - c) g + c LP_tau(g), a standard linear solid in creep.
    """
    sat = config.saturation_force_n * np.tanh(force / config.saturation_force_n)
    if config.creep <= 0:
        return sat
    alpha = 1.0 - np.exp(-step_us / max(1, config.creep_us))
    slow = lfilter([alpha], [1.0, alpha - 1.0], sat, axis=-1)
    return (1 - config.creep) * sat + config.creep * slow


def simulate_contacts(config, camera: Camera, grasps, forces, motions, residual, progress=None):
    """Step the contact regions of all grasps together. Returns per-grasp (t_rel_us, x, y, p).

    forces: (n, K) true force at t_k = k * step; motions: (n, K, 2) pixels; residual: (n, H, W) the
    reference-minus-level state each pixel of each grasp starts in (after its LED blink).
    """
    from neurotac_cli.sim.contact import flat_force_table, flat_pressure, foundation_stiffness, visibility

    n, steps = forces.shape
    step = config.step_us
    pitch = config.pixel_pitch_mm
    h, w = camera.shape
    fm = membrane_force(config, forces, step)
    # Geometry per grasp: flat hexagons (approach from force) or spheres (Hertz radius from force).
    flat = np.array([g.shape.face == "hex" for g in grasps])
    approach = np.zeros((n, steps))
    radius_mm = np.zeros((n, steps))
    peak_pressure = np.zeros((n, steps))
    stiffness = np.zeros(n)
    half_px = np.zeros(n)
    for i, g in enumerate(grasps):  # per grasp set-up (dozens), not per pixel
        mat = MATERIALS[g.material]
        if flat[i]:
            stiffness[i] = foundation_stiffness(config, mat, g.shape.length_mm)
            table_a, table_f = flat_force_table(g.shape.size_mm / 2, g.tilt, g.tilt_dir, stiffness[i],
                                                config.edge_factor_max, pitch)
            approach[i] = np.interp(fm[i], table_f + np.arange(table_f.size) * 1e-12, table_a)
            half_px[i] = g.shape.size_mm / 2 / contact.SQRT3_2 / pitch
        else:
            e_star = contact.effective_modulus(config.membrane_youngs_pa, config.membrane_poisson, mat.youngs_pa, mat.poisson)
            r_m = g.shape.size_mm / 2 * 1e-3
            radius_mm[i] = contact.hertz_radius_m(fm[i], r_m, e_star) * 1e3
            peak_pressure[i] = contact.hertz_peak_pressure(fm[i], r_m, e_star)
            half_px[i] = radius_mm[i].max() / pitch
    reach = float(np.abs(motions).max()) if motions.size else 0.0
    half = int(np.ceil(half_px.max() + reach + 3))
    size = 2 * half + 1
    if size > min(h, w):
        from neurotac_cli.errors import NeurotacError

        raise NeurotacError(f"the contact ({size} px across) does not fit the {w}x{h} sensor (use a smaller object or a larger pixel_pitch_mm)")
    cx = np.array([g.center_px[0] for g in grasps])
    cy = np.array([g.center_px[1] for g in grasps])
    ox = np.clip(np.round(cx).astype(int) - half, 0, w - size)
    oy = np.clip(np.round(cy).astype(int) - half, 0, h - size)
    cols = ox[:, None] + np.arange(size)[None, :]  # (n, S)
    rows = oy[:, None] + np.arange(size)[None, :]
    gather = rows[:, :, None] * w + cols[:, None, :]  # (n, S, S) flat sensor index
    bright = camera.brightness.ravel()[gather]
    on_thr = camera.on_threshold.ravel()[gather]
    off_thr = camera.off_threshold.ravel()[gather]
    # Positions relative to the face centre before motion (pixel centres at +0.5), in pixels.
    u0 = (cols + 0.5 - cx[:, None])[:, None, :].astype(np.float32)  # (n, 1, S)
    v0 = (rows + 0.5 - cy[:, None])[:, :, None].astype(np.float32)  # (n, S, 1)
    cos_o = np.cos([g.orientation for g in grasps]).astype(np.float32)[:, None, None]
    sin_o = np.sin([g.orientation for g in grasps]).astype(np.float32)[:, None, None]
    tilt = np.array([g.tilt for g in grasps], np.float32)[:, None, None]
    tdir = np.array([g.tilt_dir for g in grasps], np.float32)
    apothem = np.array([g.shape.size_mm / 2 for g in grasps], np.float32)[:, None, None]
    stiff = stiffness.astype(np.float32)[:, None, None]
    level = np.log(bright + config.dark_level).astype(np.float32)
    filtered = level.copy()
    reference = level + residual.reshape(n, -1)[np.arange(n)[:, None, None], gather]
    last = np.full(level.shape, -1e12)
    two_pi_fc = 2 * np.pi * config.cutoff_hz * step * 1e-6
    out = []
    for k in range(steps):  # a loop over time steps; every pixel of every grasp at once
        du = u0 - motions[:, k, 0][:, None, None]
        dv = v0 - motions[:, k, 1][:, None, None]
        uu = (du * cos_o + dv * sin_o) * pitch
        vv = (-du * sin_o + dv * cos_o) * pitch
        s = np.zeros(level.shape, np.float32)
        if flat.any():
            pressure, cover = flat_pressure(uu, vv, apothem, tilt, (tdir[:, 0, None, None], tdir[:, 1, None, None]),
                                            approach[:, k][:, None, None], stiff, config.edge_factor_max, pitch)
            s = np.where(flat[:, None, None], visibility(pressure, cover, config.pressure_scale_pa), s)
        if not flat.all():
            a = radius_mm[:, k][:, None, None]
            r2 = uu * uu + vv * vv
            with np.errstate(invalid="ignore", divide="ignore"):
                p = peak_pressure[:, k][:, None, None] * np.sqrt(np.clip(1.0 - r2 / np.maximum(a * a, 1e-12), 0.0, None))
            cover = np.clip(0.5 + (a - np.sqrt(r2)) / pitch, 0.0, 1.0)
            s = np.where(flat[:, None, None], s, visibility(p, cover, config.pressure_scale_pa))
        intensity = bright * (1.0 - config.object_contrast * s)
        target = np.log(intensity + config.dark_level)
        alpha = -np.expm1(-two_pi_fc * np.clip(intensity, 0.02, None))
        previous = filtered
        filtered = previous + alpha * (target - previous)
        t0 = k * step
        events = _fire(previous, filtered, reference, on_thr, off_thr, last, t0, step, config.refractory_us)
        if events is not None:
            out.append(events)
        if progress is not None and k % 200 == 0:
            progress(k, steps)
    if progress is not None:
        progress(steps, steps)
    return _split(out, n, size, ox, oy)


def _fire(previous, filtered, reference, on_thr, off_thr, last, t0, step, refractory):
    """Emit the threshold crossings of one step (in place: reference, last). None when there are none."""
    diff = filtered - reference
    n_on = np.floor(diff / on_thr)
    n_off = np.floor(-diff / off_thr)
    fire_on = n_on >= 1
    fire_off = n_off >= 1
    if not (fire_on.any() or fire_off.any()):
        return None
    parts = []
    for mask, count, threshold, sign, polarity in ((fire_on, n_on, on_thr, 1.0, 1), (fire_off, n_off, off_thr, -1.0, 0)):
        index = np.flatnonzero(mask)
        if not index.size:
            continue
        count = np.minimum(count.ravel()[index], 16).astype(np.int64)
        thr = threshold.ravel()[index]
        ref = reference.ravel()[index]
        reference.ravel()[index] = ref + sign * count * thr
        rep = np.repeat(np.arange(index.size), count)
        kth = np.arange(rep.size) - np.repeat(np.cumsum(count) - count, count) + 1
        crossing = ref[rep] + sign * kth * thr[rep]
        start = previous.ravel()[index][rep]
        end = filtered.ravel()[index][rep]
        with np.errstate(invalid="ignore", divide="ignore"):
            frac = np.clip((crossing - start) / (end - start), 0.0, 1.0)
        frac = np.nan_to_num(frac, nan=1.0)
        t = t0 + frac * step
        t = np.maximum(t, last.ravel()[index][rep] + kth * refractory)
        keep = t < t0 + step
        pixel = index[rep[keep]]
        t = t[keep]
        if pixel.size:
            # events of one pixel come in increasing k, so the last kept one is the latest
            flat_last = last.reshape(-1)
            flat_last[pixel] = t
        parts.append((pixel, t, np.full(pixel.size, polarity, np.uint8)))
    if not parts:
        return None
    pixel = np.concatenate([p[0] for p in parts])
    return pixel, np.concatenate([p[1] for p in parts]), np.concatenate([p[2] for p in parts])


def _split(out, n, size, ox, oy):
    if out:
        pixel = np.concatenate([o[0] for o in out])
        t = np.concatenate([o[1] for o in out])
        p = np.concatenate([o[2] for o in out])
    else:
        pixel, t, p = np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.uint8)
    trial = pixel // (size * size)
    local = pixel % (size * size)
    x = ox[trial] + local % size
    y = oy[trial] + local // size
    order = np.argsort(trial, kind="stable")
    bounds = np.searchsorted(trial[order], np.arange(n + 1))
    result = []
    for i in range(n):
        sel = order[bounds[i]:bounds[i + 1]]
        result.append((np.round(t[sel]).astype(np.int64), x[sel], y[sel], p[sel]))
    return result
