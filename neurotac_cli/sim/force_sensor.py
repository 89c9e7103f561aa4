"""Force sensors as the rig logs them: 500 Hz samples on the micro-controller clock from LED-off.

- `nano17` (ATI Nano17 F/T cell): stiff strain-gauge cell, first-order response of ~1 ms, noise
  ~0.01 N, resolution 1/320 N (ATI's SI-12-0.12 calibration).
- `flexiforce` (Tekscan FlexiForce A201 under a silicone cover on the moving finger): the element
  itself answers in < 5 µs, but the cover and mount make it slow and hysteretic (thesis 3.7.1: the
  measured force falls slower than the contact is lost). Modelled as a first-order lag that is slower
  when unloading (3x), a play (backlash) operator of half-width 2% of the peak for the hysteresis
  (datasheet: < 4.5% of full scale), a residual offset that the cover holds after release, ±3%
  noise, and extra noise while the gripper moves.
"""

import numpy as np
from scipy.signal import lfilter

DEFAULT_LAG_US = {"nano17": 1_000, "flexiforce": 25_000}
DEFAULT_NOISE_N = {"nano17": 0.008, "flexiforce": 0.03}
RESOLUTION_N = {"nano17": 1.0 / 320.0, "flexiforce": 0.005}


def sensor_lag_us(config) -> int:
    return config.force_lag_us or DEFAULT_LAG_US[config.force_sensor]


def measure(config, force: np.ndarray, step_us: int, moving: np.ndarray, rng: np.random.Generator,
            zero: np.ndarray | float = 0.0) -> np.ndarray:
    """The sensor's reading of a true force sampled every `step_us` (same length). `moving`: gripper in
    motion; `zero`: the sensor's zero at each sample (a strain gauge warming drifts it), read as the
    force is, at the sensor's resolution."""
    lag = sensor_lag_us(config)
    noise = config.force_noise_n if config.force_noise_n >= 0 else DEFAULT_NOISE_N[config.force_sensor]
    if config.force_sensor == "nano17":
        alpha = 1.0 - np.exp(-step_us / lag)
        reading = lfilter([alpha], [1.0, alpha - 1.0], force)
        reading = reading + noise * rng.standard_normal(force.shape)
    else:
        reading = _flexiforce(force, step_us, lag)
        reading = reading + noise * rng.standard_normal(force.shape) * (1.0 + 2.0 * moving)
    resolution = RESOLUTION_N[config.force_sensor]
    reading = reading + zero if np.any(zero) else reading  # no zero added: the same bytes as a sensor that keeps it
    return np.round(reading / resolution) * resolution


def _flexiforce(force, step_us, lag_us):
    """Asymmetric first-order lag + play hysteresis + residual offset held by the cover; a loop over
    time samples only (one trace of ~500 samples per grasp at the 2 ms log rate, not per event)."""
    peak = float(force.max()) if force.size else 0.0
    width = 0.02 * peak
    up = 1.0 - np.exp(-step_us / lag_us)
    down = 1.0 - np.exp(-step_us / (3.0 * lag_us))
    out = np.empty_like(force, dtype=float)
    level = 0.0
    play = 0.0
    for i, value in enumerate(force):
        play = min(max(play, value - width), value + width)
        level += (up if play > level else down) * (play - level)
        out[i] = level
    residual = 0.04 * peak * (np.maximum.accumulate(force) > 0.5 * peak) * (force < 0.1 * peak)
    return np.maximum(out, residual)
