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
    gain = np.full((h, w), config.led_gain, np.float32)
    if config.led_box:
        x0, y0, bw, bh = config.led_box
        lit = np.zeros((h, w), bool)
        lit[y0:y0 + bh, x0:x0 + bw] = True
        gain = np.where(lit, gain, 0.0).astype(np.float32)
    delta = np.log((camera.brightness * (1 + gain) + config.dark_level) / base)
    tau_on = _tau_us(config, camera.brightness * (1 + gain))
    tau_off = _tau_us(config, camera.brightness)
    on_t, off_t = camera.on_threshold, camera.off_threshold
    # Unknown history before the blink: the reference sits anywhere in its dead band.
    ref = -off_t + rng.random((h, w)).astype(np.float32) * (on_t + off_t) * 0.999
    ys, xs = np.mgrid[0:h, 0:w]
    out = []
    last = np.full((h, w), -np.inf)
    refractory = float(config.refractory_us)

    def emit(t, fire, polarity):
        # latency jitter (µs), then the refractory period: a pixel still past its threshold fires as
        # soon as it may (the level keeps moving the same way during a blink)
        t = t + rng.exponential(15.0, (h, w))
        t = np.where(fire, np.maximum(t, last + refractory), last)
        last[...] = t
        out.append((t[fire], xs[fire], ys[fire], np.full(int(fire.sum()), polarity, np.uint8)))

    kmax = int(np.ceil(float(delta.max() / camera.on_threshold.min()))) + 1
    ref_after = ref.copy()
    for k in range(1, kmax + 1):  # at most a handful of thresholds per blink; vectorised over pixels
        level = ref + k * on_t
        fire = (level < delta) & (level > 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            emit(on_us - tau_on * np.log1p(-np.where(fire, level / delta, 0.0)), fire, 1)
        ref_after = np.where(fire, level, ref_after)
    ref = ref_after
    kmax = int(np.ceil(float((ref.max() + 1e-9) / camera.off_threshold.min()))) + 1
    for k in range(1, kmax + 1):
        level = ref - k * off_t
        # the level falls from delta towards 0 asymptotically: crossings very near 0 are lost in noise
        fire = (level > 0.02 * delta) & (level < delta)
        with np.errstate(invalid="ignore", divide="ignore"):
            emit(off_us - tau_off * np.log(np.where(fire, level / delta, 1.0)), fire, 0)
        ref_after = np.where(fire, level, ref_after)
    t = np.concatenate([o[0] for o in out])
    events = (np.round(t).astype(np.int64), *(np.concatenate([o[j] for o in out]) for j in (1, 2, 3)))
    return events, ref_after.astype(np.float32)


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

    g = F / (1 + (F / Fs)^n)^(1/n): linear at low force, flat beyond Fs (the membrane is fully
    compacted); deformation = (1 - c) g + c LP_tau(g), a standard linear solid in creep.
    """
    n = config.saturation_sharpness
    force = np.clip(force, 0.0, None)
    sat = force / (1.0 + (force / config.saturation_force_n) ** n) ** (1.0 / n)
    if config.creep <= 0:
        return sat
    alpha = 1.0 - np.exp(-step_us / max(1, config.creep_us))
    slow = lfilter([alpha], [1.0, alpha - 1.0], sat, axis=-1)
    return (1 - config.creep) * sat + config.creep * slow


def simulate_contacts(config, camera: Camera, grasps, forces, motions, residual, progress=None, exact=False, state=None):
    """Step the contact regions of all grasps together. Returns per-grasp (t_rel_us, x, y, p).

    forces: (n, K) true force at t_k = k * step; motions: (n, K, 2) pixels; residual: (n, H, W) the
    reference-minus-level state each pixel of each grasp starts in (after its LED blink).

    The pixels near each contact (the face grown by the largest motion and a margin) of all grasps
    form one flat vector, stepped together. The geometry of each face is computed once at rest; the
    small rigid motion d moves it to first order (rho(x - d) = rho(x) - d . grad rho), and the tilt
    term of the flat punch, linear in position, folds into each grasp's approach. `exact` recomputes
    the geometry at the moved position every step instead (a slip moves the face by many pixels).
    `state`, a dict, receives the pixels stepped (x, y) and their reference-minus-level at the end.
    """
    n, steps = forces.shape
    step = config.step_us
    fm = membrane_force(config, forces, step)
    reach = float(np.abs(motions).max()) if motions.size else 0.0
    blocks = [_contact_block(config, camera, g, i, fm[i], motions[i] * (not exact), reach, residual[i])  # per grasp, not pixel
              for i, g in enumerate(grasps)]
    flat, trial, xs, ys, field, drive, peak, spread = _stack_blocks(blocks)
    is_flat = flat.all()
    is_sphere = (~flat).all()
    bright = field["bright"]
    level = np.log(bright + np.float32(config.dark_level))
    filtered = level.copy()
    reference = level + field["residual"]
    last = np.full(level.shape, -1e9, np.float32)
    two_pi_fc = np.float32(2 * np.pi * config.cutoff_hz * step * 1e-6)
    contrast = np.float32(config.object_contrast)
    dark = np.float32(config.dark_level)
    touching = (drive > 0).any(axis=0) | (peak > 0).any(axis=0)  # stepped while touching, and 20 ms after (the level settles)
    active = np.convolve(touching.astype(float), np.ones(int(20_000 / step) + 1), mode="full")[:steps] > 0
    out = []
    geometry = _exact_geometry(config, grasps, blocks, trial) if exact else None
    for k in range(steps):  # a loop over time steps; every pixel of every grasp at once
        if not active[k]:
            continue
        dx = motions[trial, k, 0].astype(np.float32)
        dy = motions[trial, k, 1].astype(np.float32)
        # exact: the geometry at the moved position; else moved to first order
        rho, field["gap"] = geometry(dx, dy) if exact else (field["rho"] - dx * field["grad_x"] - dy * field["grad_y"], field["gap"])
        rho = rho / spread[trial, k]
        s = _shading(config, rho, flat, is_flat, is_sphere, field, drive[trial, k], peak[trial, k])
        intensity = bright * (np.float32(1.0) - contrast * s)
        target = np.log(intensity + dark)
        alpha = -np.expm1(-two_pi_fc * np.maximum(intensity, np.float32(0.02)))
        previous = filtered
        filtered = previous + alpha * (target - previous)
        events = _fire(previous, filtered, reference, field["on"], field["off"], last, float(k * step), step,
                       config.refractory_us)
        if events is not None:
            out.append(events)
        if progress is not None and k % 200 == 0:
            progress(k, steps)
    if progress is not None:
        progress(steps, steps)
    if state is not None:
        state.update(x=xs, y=ys, residual=reference - filtered)
    return _split(out, n, trial, xs, ys)


def _stack_blocks(blocks):
    """The grasps' contact blocks as one flat vector of pixels: (flat, trial, x, y, per-pixel fields,
    and per grasp and step the drive, peak and spread)."""
    flat = np.concatenate([b["flat"] for b in blocks])
    trial = np.concatenate([b["trial"] for b in blocks])
    xs = np.concatenate([b["x"] for b in blocks])
    ys = np.concatenate([b["y"] for b in blocks])
    field = {name: np.concatenate([b[name] for b in blocks]).astype(np.float32)
             for name in ("rho", "grad_x", "grad_y", "gap", "stiffness", "apothem", "bright", "on", "off", "residual")}
    # per grasp and step: the flat punch's approach (tilt motion folded in) or the sphere's radius and peak pressure
    drive = np.stack([b["drive"] for b in blocks]).astype(np.float32)  # (n, K)
    peak = np.stack([b["peak"] for b in blocks]).astype(np.float32)
    spread = np.stack([b["spread"] for b in blocks]).astype(np.float32)  # 1 + lateral bulge of the face
    return flat, trial, xs, ys, field, drive, peak, spread


def _shading(config, rho, flat, is_flat, is_sphere, field, drive, peak):
    """The share of each pixel's light the contact takes at one step: flat punches (hex norm, rim
    coverage, Boussinesq rim factor, foundation pressure) and spheres (Hertz); `drive` and `peak`
    are each pixel's grasp's approach or contact radius and peak pressure at that step."""
    cap = np.float32(config.edge_factor_max)
    scale = np.float32(1.0 / config.pressure_scale_pa)
    inv_pitch = np.float32(1.0 / config.pixel_pitch_mm)
    s = np.empty_like(rho)
    if not is_sphere:
        f = flat if not is_flat else slice(None)
        r = rho[f]
        cover = np.clip(np.float32(0.5) + (np.float32(1.0) - r) * field["apothem"][f] * inv_pitch, 0, 1)
        edge = np.minimum(np.float32(0.5) / np.sqrt(np.clip(np.float32(1.0) - r * r, np.float32(1e-6), None)), cap)
        pressure = field["stiffness"][f] * np.clip(drive[f] - field["gap"][f], 0, None) * edge
        s[f] = -np.expm1(-pressure * scale) * cover
    if not is_flat:
        # rho = distance from the centre (mm), drive = contact radius (mm), peak = p0 (Pa)
        f = ~flat if not is_sphere else slice(None)
        r = rho[f]
        a = drive[f]
        inside = np.clip(np.float32(1.0) - (r * r) / np.maximum(a * a, np.float32(1e-12)), 0, None)
        cover = np.clip(np.float32(0.5) + (a - r) * inv_pitch, 0, 1)
        s[f] = -np.expm1(-peak[f] * np.sqrt(inside) * scale) * cover
    return s

def _exact_geometry(config, grasps, blocks, trial):
    """(dx, dy) -> (rho, gap) of every stepped pixel with each face moved by (dx, dy) pixels."""
    from neurotac_cli.sim.contact import hex_norm

    pitch = np.float32(config.pixel_pitch_mm)
    per = {name: np.array([value(g) for g in grasps], np.float32)[trial] for name, value in (
        ("cx", lambda g: g.center_px[0]), ("cy", lambda g: g.center_px[1]),
        ("cos", lambda g: np.cos(g.orientation)), ("sin", lambda g: np.sin(g.orientation)),
        ("tilt", lambda g: g.tilt), ("tx", lambda g: g.tilt_dir[0]), ("ty", lambda g: g.tilt_dir[1]),
        ("apothem", lambda g: g.shape.size_mm / 2), ("flat", lambda g: g.shape.face == "hex"))}
    px = np.concatenate([b["x"] for b in blocks]).astype(np.float32) + np.float32(0.5)
    py = np.concatenate([b["y"] for b in blocks]).astype(np.float32) + np.float32(0.5)
    flat = per["flat"] > 0
    corner = per["apothem"] / np.float32(contact.SQRT3_2)

    def at(dx, dy):
        u = px - per["cx"] - dx
        v = py - per["cy"] - dy
        uu = (u * per["cos"] + v * per["sin"]) * pitch
        vv = (-u * per["sin"] + v * per["cos"]) * pitch
        rho = np.where(flat, hex_norm(uu, vv, per["apothem"]), np.hypot(uu, vv))
        gap = np.where(flat, per["tilt"] * ((uu * per["tx"] + vv * per["ty"]) + corner) * np.float32(1e-3), 0)
        return rho.astype(np.float32), gap.astype(np.float32)

    return at


def _contact_block(config, camera, grasp, index, membrane_force_n, motion, reach, residual):
    """The pixels near one grasp's contact, with their geometry at rest, and the grasp's drive per step."""
    from neurotac_cli.sim.contact import flat_force_table, foundation_stiffness, hex_norm

    pitch = config.pixel_pitch_mm
    h, w = camera.shape
    mat = MATERIALS[grasp.material]
    cx, cy = grasp.center_px
    flat = grasp.shape.face == "hex"
    if flat:
        apothem = grasp.shape.size_mm / 2
        stiffness = foundation_stiffness(config, mat, grasp.shape.length_mm)
        table_a, table_f = flat_force_table(apothem, grasp.tilt, grasp.tilt_dir, stiffness, config.edge_factor_max, pitch)
        approach = np.interp(membrane_force_n, table_f + np.arange(table_f.size) * 1e-12, table_a)
        # moving the face by d lowers the gap under it by tilt * (d . tilt_dir): add that to the approach
        shift_mm = (motion[:, 0] * grasp.tilt_dir[0] + motion[:, 1] * grasp.tilt_dir[1]) * pitch
        drive = np.where(approach > 0, approach + grasp.tilt * shift_mm * 1e-3, 0.0)
        peak = np.zeros_like(drive)
        # A soft object squeezed along its length bulges sideways (Poisson): its face grows by
        # nu * strain, strain = mean pressure / E (foam at 3 N: ~7%; steel: nothing).
        area_mm2 = 2 * np.sqrt(3.0) * apothem**2
        spread = 1.0 + mat.poisson * np.clip(membrane_force_n, 0, None) / (area_mm2 * 1e-6) / mat.youngs_pa
        extent_px = apothem * float(spread.max()) / contact.SQRT3_2 / pitch
    else:
        e_star = contact.effective_modulus(config.membrane_youngs_pa, config.membrane_poisson, mat.youngs_pa, mat.poisson)
        radius_m = grasp.shape.size_mm / 2 * 1e-3
        drive = contact.hertz_radius_m(membrane_force_n, radius_m, e_star) * 1e3
        peak = contact.hertz_peak_pressure(membrane_force_n, radius_m, e_star)
        stiffness, apothem = 0.0, 0.0
        spread = np.ones_like(drive)
        extent_px = float(drive.max()) / pitch
    half = int(np.ceil(extent_px + reach + 3))
    cols = np.arange(int(np.floor(cx)) - half, int(np.floor(cx)) + half + 1)
    rows = np.arange(int(np.floor(cy)) - half, int(np.floor(cy)) + half + 1)
    u_px = (cols + 0.5 - cx)[None, :] + np.zeros((rows.size, 1))
    v_px = (rows + 0.5 - cy)[:, None] + np.zeros((1, cols.size))
    cos_o, sin_o = np.cos(grasp.orientation), np.sin(grasp.orientation)
    uu = (u_px * cos_o + v_px * sin_o) * pitch
    vv = (-u_px * sin_o + v_px * cos_o) * pitch
    if flat:
        rho = hex_norm(uu, vv, apothem)
        corner = apothem / contact.SQRT3_2
        gap = grasp.tilt * ((uu * grasp.tilt_dir[0] + vv * grasp.tilt_dir[1]) + corner) * 1e-3
        near = rho <= float(spread.max()) + (reach + 3) * pitch / apothem
    else:
        rho = np.hypot(uu, vv)
        gap = np.zeros_like(rho)
        near = rho <= (extent_px + reach + 3) * pitch
    grad_y, grad_x = np.gradient(rho)  # per pixel of motion
    yy, xx = np.meshgrid(rows, cols, indexing="ij")
    keep = near & (xx >= 0) & (xx < w) & (yy >= 0) & (yy < h)
    x, y = xx[keep], yy[keep]
    count = int(keep.sum())
    return {
        "flat": np.full(count, flat), "trial": np.full(count, index), "x": x, "y": y,
        "rho": rho[keep], "grad_x": grad_x[keep], "grad_y": grad_y[keep], "gap": gap[keep],
        "stiffness": np.full(count, stiffness), "apothem": np.full(count, apothem),
        "bright": camera.brightness[y, x], "on": camera.on_threshold[y, x], "off": camera.off_threshold[y, x],
        "residual": residual[y, x], "drive": drive, "peak": peak, "spread": spread,
    }


def _fire(previous, filtered, reference, on_thr, off_thr, last, t0, step, refractory):
    """Emit the threshold crossings of one step (in place: reference, last). None when there are none."""
    diff = filtered - reference
    on_index = np.flatnonzero(diff >= on_thr)
    off_index = np.flatnonzero(diff <= -off_thr)
    if not (on_index.size or off_index.size):
        return None
    parts = []
    for index, threshold, sign, polarity in ((on_index, on_thr, 1.0, 1), (off_index, off_thr, -1.0, 0)):
        if not index.size:
            continue
        thr = threshold[index]
        ref = reference[index]
        count = np.minimum(np.floor(sign * diff[index] / thr), 16).astype(np.int64)
        reference[index] = ref + sign * count * thr  # the reset absorbs what the refractory period misses
        rep = np.repeat(np.arange(index.size), count)
        kth = np.arange(rep.size) - np.repeat(np.cumsum(count) - count, count) + 1
        crossing = ref[rep] + sign * kth * thr[rep]
        start = previous[index][rep]
        end = filtered[index][rep]
        with np.errstate(invalid="ignore", divide="ignore"):
            frac = np.nan_to_num(np.clip((crossing - start) / (end - start), 0.0, 1.0), nan=1.0)
        t = t0 + frac * step
        t = np.maximum(t, last[index][rep] + kth * refractory)
        keep = t < t0 + step
        pixel = index[rep[keep]]
        t = t[keep]
        last[pixel] = t  # events of a pixel come in increasing k: the last write is its latest event
        parts.append((pixel, t, np.full(pixel.size, polarity, np.uint8)))
    if not parts:
        return None
    return tuple(np.concatenate([part[j] for part in parts]) for j in range(3))


def _split(out, n, trial, xs, ys):
    if out:
        pixel = np.concatenate([o[0] for o in out])
        t = np.concatenate([o[1] for o in out])
        p = np.concatenate([o[2] for o in out])
    else:
        pixel, t, p = np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.uint8)
    owner = trial[pixel]
    order = np.argsort(owner, kind="stable")
    bounds = np.searchsorted(owner[order], np.arange(n + 1))
    result = []
    for i in range(n):
        sel = order[bounds[i]:bounds[i + 1]]
        result.append((np.round(t[sel]).astype(np.int64), xs[pixel[sel]], ys[pixel[sel]], p[sel]))
    return result
