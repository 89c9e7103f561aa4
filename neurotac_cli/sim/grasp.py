"""Grasp plans: what happens in each trial (object, peak force, phase times, pose) and its true force.

Times here are µs from LED-off (the instant the force log starts, thesis 3.6.1).
"""

from dataclasses import dataclass, field

import numpy as np

from neurotac_cli.errors import UsageError
from neurotac_cli.sim.config import GRIPPER_FORCE_BANDS, MATERIALS, ObjectShape, SimConfig, parse_groups


@dataclass
class Grasp:
    trial: str
    material: str
    shape: ObjectShape
    labels: dict
    peak_force_n: float
    contact_us: int  # first touch
    loaded_us: int  # end of loading
    release_us: int  # the gripper starts opening
    released_us: int  # contact lost
    end_us: int  # end of the recording (from LED-off)
    center_px: tuple  # where the face centre lands on the sensor (x, y), float pixels
    orientation: float  # rotation of the face (rad)
    tilt: float  # misalignment of the face to the membrane (rad)
    tilt_dir: tuple  # unit vector of the tilt
    vibration_phase: float
    settle_dir: tuple
    drift_dir: tuple
    camera_start_us: int  # camera clock at the first recorded instant
    preroll_us: int  # first recorded instant to LED-on
    led_on_us: int  # LED on-time
    ripple_seed: int = 0  # seed of the grasp's band-limited force ripple
    extra: dict = field(default_factory=dict)

    @property
    def led_off_camera_us(self) -> int:
        """The true LED-off instant on the camera's clock (the manifest's true_t0_us)."""
        return self.camera_start_us + self.preroll_us + self.led_on_us


MAX_TRIALS = 20_000  # one run's trials: a --synced table holds all their events in memory


def plan_grasps(config: SimConfig, rng: np.random.Generator, trials: int | None = None) -> list[Grasp]:
    """Draw every trial's plan. `trials` keeps that many, spread over the groups in turn (a small data set)."""
    groups = parse_groups(config.groups)
    queue = []  # round-robin over groups so a small --trials still covers every group
    remaining = [g[2] for g in groups]
    total = sum(remaining)
    if total == 0:
        raise UsageError("every group of --objects counts 0 grasps: nothing to simulate (give a count of 1 or more)")
    if trials is not None and trials > total:  # writing fewer than asked for would pass unnoticed in a batch script
        raise UsageError(f"--trials {trials} is more than the {total} grasps of the preset's groups (or --objects); "
                         f"give --trials {total} or fewer, or more grasps per group with --objects")
    wanted = total if trials is None else trials  # the queue holds only what is written: a huge group with --trials 1 stays small
    if wanted > MAX_TRIALS:  # found now, not hours later when memory or the disk runs out
        raise UsageError(f"{wanted} trials is more than the {MAX_TRIALS} one run simulates (a --synced table holds every "
                         "trial's events in memory, about 0.2 MB each): simulate fewer (--trials or smaller --objects counts), "
                         "or several runs with their own --seed joined by `neurotac concat --rename`")
    while len(queue) < wanted:
        for index, group in enumerate(groups):
            if remaining[index] and len(queue) < wanted:
                queue.append(group)
                remaining[index] -= 1
    if not queue:
        raise UsageError("no trials to simulate (every group has a count of 0)")
    counters: dict = {}
    grasps = []
    for material, shape, _, labels in queue:
        key = (material, shape.name, tuple(sorted(labels.items())))
        counters[key] = counters.get(key, 0) + 1
        band = GRIPPER_FORCE_BANDS.get(labels.get("gripper_force"), (0.0, 1.0))
        low = config.force_min_n + band[0] * (config.force_max_n - config.force_min_n)
        high = config.force_min_n + band[1] * (config.force_max_n - config.force_min_n)
        grasps.append(_plan_one(config, rng, material, shape, labels, rng.uniform(low, high), counters[key]))
    order = sorted(range(len(grasps)), key=lambda i: grasps[i].trial)
    return [grasps[i] for i in order]


def _jitter(config, rng, value_us):
    return int(round(value_us * max(0.3, 1.0 + config.duration_jitter * rng.standard_normal())))


def loading_us(config: SimConfig, material: str, shape: ObjectShape, peak_force_n: float) -> float:
    """Servo settle time plus the gripper travel needed to build the peak force at the closing speed.

    The travel is the force over the series stiffness of membrane and object (softer objects need
    more travel, so they load more slowly: thesis 3.5, Fig. 3.5).
    """
    from neurotac_cli.sim.contact import foundation_stiffness

    mat = MATERIALS[material]
    area_m2 = 2 * np.sqrt(3.0) * (shape.size_mm / 2 * 1e-3) ** 2 if shape.face == "hex" else np.pi * (shape.size_mm / 4 * 1e-3) ** 2
    stiffness = foundation_stiffness(config, mat, shape.length_mm) * area_m2  # N/m
    travel_mm = peak_force_n / stiffness * 1e3
    return config.servo_settle_us + travel_mm / config.gripper_speed_mm_s * 1e6


def _plan_one(config, rng, material, shape, labels, peak, index) -> Grasp:
    contact = int(rng.uniform(*config.contact_delay_us))
    grasp_end = max(contact + 5_000, _jitter(config, rng, config.grasp_us))
    load = min(loading_us(config, material, shape, peak) * rng.uniform(0.9, 1.1), grasp_end - contact)
    loaded = contact + int(load)
    hold = _jitter(config, rng, config.hold_us)
    phase_release = _jitter(config, rng, config.release_us)
    if config.max_duration_us:
        hold = max(10_000, min(hold, config.max_duration_us - grasp_end - phase_release - config.tail_us))
    release = grasp_end + hold
    unload = min(phase_release, int(0.5 * loading_us(config, material, shape, peak) * rng.uniform(0.8, 1.2)))
    released = release + max(2_000, unload)
    end = release + phase_release + config.tail_us
    w, h = config.sensor_width, config.sensor_height
    center = (w / 2 + config.position_jitter_px * rng.standard_normal(), h / 2 + config.position_jitter_px * rng.standard_normal())
    angle = rng.uniform(0, 2 * np.pi)
    settle = rng.uniform(0, 2 * np.pi)
    drift = rng.uniform(0, 2 * np.pi)
    return Grasp(
        trial="-".join([material, shape.name, *labels.values(), f"{index:02d}"]),
        material=material,
        shape=shape,
        labels={"material": material, "object": shape.name, "size_mm": shape.size_label, **labels},
        peak_force_n=float(peak),
        contact_us=contact,
        loaded_us=loaded,
        release_us=release,
        released_us=released,
        end_us=end,
        center_px=center,
        orientation=float(rng.uniform(0, np.pi / 3)),
        tilt=abs(float(rng.standard_normal())) * np.deg2rad(config.tilt_deg),
        tilt_dir=(float(np.cos(angle)), float(np.sin(angle))),
        vibration_phase=float(rng.uniform(0, 2 * np.pi)),
        settle_dir=(float(np.cos(settle)), float(np.sin(settle))),
        drift_dir=(float(np.cos(drift)), float(np.sin(drift))),
        camera_start_us=int(rng.uniform(*config.camera_offset_us)),
        preroll_us=int(rng.uniform(*config.preroll_us)),
        led_on_us=int(rng.uniform(*config.led_on_us)),
        ripple_seed=int(rng.integers(0, 2**63 - 1)),
    )


def true_force(config: SimConfig, grasp: Grasp, t_us: np.ndarray) -> np.ndarray:
    """The contact force (N) at times t (µs from LED-off): loading, held with relaxation and ripple, unloading.

    Loading follows the gripper closing at constant speed into a stiffening contact (F ~ u^1.5, the
    Hertz/foundation force-approach law of a face that comes into contact progressively); the hold
    relaxes by the material's share with its time constant (a position-controlled gripper squeezing a
    viscoelastic object) and carries a small ripple; unloading mirrors loading.
    """
    t = np.asarray(t_us, dtype=float)
    mat = MATERIALS[grasp.material]
    relaxation = mat.relaxation if config.gripper == "position" else 0.0  # a force-controlled grip holds its force
    peak = grasp.peak_force_n
    load = np.clip((t - grasp.contact_us) / max(1, grasp.loaded_us - grasp.contact_us), 0, 1)
    force = peak * load**1.5
    held = np.clip(t - grasp.loaded_us, 0, None)
    relax = 1.0 - relaxation * -np.expm1(-held / mat.relaxation_us)
    ripple = config.force_vibration * _ripple(config, grasp, t)
    settle = 0.06 * np.exp(-held / max(1, config.settle_us)) * np.sin(2 * np.pi * config.settle_hz * held * 1e-6)
    force = force * (relax + (ripple + settle) * (t > grasp.loaded_us))
    level_at_release = peak * (1.0 - relaxation * -np.expm1(-(grasp.release_us - grasp.loaded_us) / mat.relaxation_us))
    unload = np.clip((t - grasp.release_us) / max(1, grasp.released_us - grasp.release_us), 0, 1)
    after = t >= grasp.release_us
    force = np.where(after, level_at_release * (1.0 - unload) ** 1.5, force)
    return np.clip(force, 0.0, max(config.force_max_n, peak))  # the design's stated maximum holds, ripple included


def _ripple(config, grasp, t):
    """Unit-s.d. force ripple of the hold: half a tone at `vibration_hz`, half band-limited noise
    (white noise on a 1 ms grid, smoothed over ~1 / vibration_hz), a fixed function of time per grasp."""
    from scipy.ndimage import gaussian_filter1d

    grid_ms = np.arange(0, grasp.end_us / 1000 + 2)
    noise = np.random.default_rng(grasp.ripple_seed).standard_normal(grid_ms.size)
    noise = gaussian_filter1d(noise, sigma=max(1.0, 1000.0 / config.vibration_hz / 4))
    noise /= max(noise.std(), 1e-12)
    tone = np.sqrt(2) * np.sin(2 * np.pi * config.vibration_hz * t * 1e-6 + grasp.vibration_phase)
    return np.sqrt(0.5) * (tone + np.interp(t / 1000, grid_ms, noise))


def rigid_motion_px(config: SimConfig, grasp: Grasp, t_us: np.ndarray) -> np.ndarray:
    """Object displacement on the membrane (pixels, shape (n, 2)): settling after loading, drift and vibration."""
    t = np.asarray(t_us, dtype=float)
    held = np.clip(t - grasp.loaded_us, 0, None)
    in_contact = (t >= grasp.contact_us) & (t <= grasp.released_us)
    settle = config.settle_px * np.exp(-held / max(1, config.settle_us)) * np.sin(2 * np.pi * config.settle_hz * held * 1e-6)
    settle = settle * (t > grasp.loaded_us)
    hold_span = max(1, grasp.release_us - grasp.loaded_us)
    drift = config.drift_px * np.clip(held / hold_span, 0, 1)
    vib = config.vibration_px * np.sin(2 * np.pi * config.vibration_hz * 1.7 * held * 1e-6 + grasp.vibration_phase)
    dx = settle * grasp.settle_dir[0] + drift * grasp.drift_dir[0] + vib * grasp.drift_dir[1]
    dy = settle * grasp.settle_dir[1] + drift * grasp.drift_dir[1] - vib * grasp.drift_dir[0]
    return np.stack([dx * in_contact, dy * in_contact], axis=-1)
