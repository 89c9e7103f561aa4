"""How well could any xcorr-style method align a simulated force log, given the true contact force?

    .venv/bin/python examples/sync_bound.py FOLDER --preset ch3 --seed 4 [--play 0,0.02]

FOLDER is what `neurotac simulate --preset P --seed S --out FOLDER` wrote (the same preset and seed
here: the grasp plans are drawn again and checked against manifest.csv). For every trial, the true
contact force (which the camera sees, up to its own response) is passed through a force-sensor model:
a first-order lag with one time constant for loading and one for unloading (a grid: 5-40 ms x 25-120
ms) after a play (backlash) operator of half-width W x the trial's peak force (each W of --play;
0 = none). The log's offset is then found by weighted least squares (free gain and level; the
sensor's extra noise while the gripper moves is weighted down), jointly with the sensor model, on a
0.25 ms grid within ±30 ms. Printed: each trial's error and chosen model, then max / mean error and
the trials within 2 ms, per material and overall.

This is an upper bound for a method that derives the force's shape from the camera: it is handed the
exact shape. With --camera, the other side: a loading template (rate ~ u^e on [c, l], u = (t - c) /
(l - c), e in 0, 0.25, 0.5, plus a constant) fitted by least squares to each trial's OFF-event rate
on the pixels that both darken and recover, and its contact (c) and end-of-loading (l) instants
compared with the simulator's: how late, and how variably, the camera shows the grasp. docs/journal.md
("What bounds xcorr on ch3") quotes both for ch3's FlexiForce.
"""

import argparse
import csv
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from neurotac_cli.sim.config import preset_config  # noqa: E402
from neurotac_cli.sim.grasp import plan_grasps, true_force  # noqa: E402

STEP_US = 250
RISE_US = np.array([5, 10, 15, 20, 25, 30, 40]) * 1000
FALL_US = np.array([25, 40, 60, 75, 90, 120]) * 1000
SHIFTS_US = np.arange(-30_000, 30_001, STEP_US)
PAD_US = 40_000


def play(force: np.ndarray, half_width: float) -> np.ndarray:
    """The play (backlash) operator: the output moves only when the input leaves the band around it."""
    out = np.empty_like(force)
    level = 0.0
    for i, value in enumerate(force):
        level = min(max(level, value - half_width), value + half_width)
        out[i] = level
    return out


def lags(force: np.ndarray) -> np.ndarray:
    """The force through every (rise, fall) first-order lag of the grid at once: (pairs, samples)."""
    up = np.repeat(1.0 - np.exp(-STEP_US / RISE_US), len(FALL_US))
    down = np.tile(1.0 - np.exp(-STEP_US / FALL_US), len(RISE_US))
    out = np.empty((len(up), len(force)))
    level = np.zeros(len(up))
    for i, value in enumerate(force):
        level += np.where(value > level, up, down) * (value - level)
        out[:, i] = level
    return out


def read_log(path) -> tuple:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))[1:]
    return np.array([float(r[0]) for r in rows]) * 1000, np.array([float(r[1]) for r in rows])


def best_offset(config, grasp, log_t, log_v, widths) -> tuple:
    """(offset error in µs, rise, fall, play width) of the best weighted least-squares fit."""
    fine = np.arange(-PAD_US, grasp.end_us + PAD_US, STEP_US, dtype=float)
    truth = true_force(config, grasp, fine)
    moving = ((log_t >= grasp.contact_us) & (log_t <= grasp.loaded_us)) | ((log_t >= grasp.release_us) & (log_t <= grasp.released_us))
    weight = 1.0 / (1.0 + 2.0 * moving) ** 2  # the simulated FlexiForce is 3x noisier while the gripper moves
    index = np.round((log_t[None, :] - SHIFTS_US[:, None] + PAD_US) / STEP_US).astype(int)  # (shifts, samples)
    sw, swy, swyy = weight.sum(), (weight * log_v).sum(), (weight * log_v**2).sum()
    best = (np.inf, 0, 0, 0, 0.0)
    for width in widths:
        for pair, model in enumerate(lags(play(truth, width * truth.max()))):
            m = model[index]  # the model at every shift: fit log ≈ a m + b, residual in closed form
            sm, smm, smy = (weight * m).sum(1), (weight * m * m).sum(1), (weight * m * log_v).sum(1)
            cov, var_m, var_y = smy - sm * swy / sw, smm - sm * sm / sw, swyy - swy * swy / sw
            residual = var_y - cov**2 / np.maximum(var_m, 1e-12)
            at = int(np.argmin(residual))
            if residual[at] < best[0]:
                best = (residual[at], int(SHIFTS_US[at]), int(RISE_US[pair // len(FALL_US)]), int(FALL_US[pair % len(FALL_US)]), width)
    return best[1:]


def camera_loading(folder, grasp, bin_us: int = 500) -> tuple:
    """(c, l) errors in µs of the loading template fitted to the trial's OFF rate (see the module doc)."""
    from neurotac_cli.io.manifest import read_camera

    table = read_camera(str(folder / f"{grasp.trial}.aedat"))
    t = table["t"].to_numpy().astype(np.int64) - grasp.led_off_camera_us
    keep = t > 3_000  # past the LED blink
    t, p = t[keep], table["p"].to_numpy()[keep]
    pixel = table["y"].to_numpy()[keep].astype(np.int64) * 65536 + table["x"].to_numpy()[keep]
    _, owner = np.unique(pixel, return_inverse=True)
    active = ((np.bincount(owner, weights=p == 0) >= 2) & (np.bincount(owner, weights=p == 1) >= 1))[owner]
    edges = np.arange(3_000, 400_000, bin_us)
    rate = np.histogram(t[active & (p == 0)], edges)[0].astype(float)
    centre = edges[:-1] + bin_us / 2
    n, sy, syy = len(rate), rate.sum(), (rate * rate).sum()
    best = (np.inf, 0, 0)
    for e in (0.0, 0.25, 0.5):
        for c in np.arange(3_000, 60_000, 1_000):
            ends = np.arange(c + 20_000, 350_000, bin_us)
            u = (centre[None, :] - c) / (ends[:, None] - c)
            m = np.where((u > 0) & (u <= 1), np.clip(u, 0, None) ** e, 0.0)
            sm, smm, smy = m.sum(1), (m * m).sum(1), m @ rate
            residual = syy - sy * sy / n - (smy - sm * sy / n) ** 2 / np.maximum(smm - sm * sm / n, 1e-12)
            at = int(np.argmin(residual))
            if residual[at] < best[0]:
                best = (residual[at], c, int(ends[at]))
    return best[1] - grasp.contact_us, best[2] - grasp.loaded_us


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="a folder written by neurotac simulate")
    parser.add_argument("--preset", default="ch3", help="the preset it was simulated with")
    parser.add_argument("--seed", type=int, required=True, help="the seed it was simulated with")
    parser.add_argument("--play", default="0", help="play half-widths to try, as shares of the peak force (comma-separated)")
    parser.add_argument("--camera", action="store_true", help="also fit the loading template to the camera's events")
    args = parser.parse_args()
    folder = pathlib.Path(args.folder)
    config = preset_config(args.preset)
    with open(folder / "manifest.csv", newline="") as handle:
        truth = {row["trial"]: int(row["true_t0_us"]) for row in csv.DictReader(handle)}
    grasps = plan_grasps(config, np.random.default_rng(np.random.SeedSequence(args.seed).spawn(4)[1]), trials=len(truth))
    if sorted(truth) != sorted(g.trial for g in grasps) or any(truth[g.trial] != g.led_off_camera_us for g in grasps):
        raise SystemExit(f"{folder} was not simulated with --preset {args.preset} --seed {args.seed}")
    widths = [float(value) for value in args.play.split(",")]
    errors: dict = {}
    for grasp in grasps:
        log_t, log_v = read_log(folder / f"{grasp.trial}_force.csv")
        error, rise, fall, width = best_offset(config, grasp, log_t, log_v, widths)
        errors.setdefault(grasp.material, []).append(error / 1000)
        print(f"{grasp.trial:18s} {error / 1000:+6.2f} ms   rise {rise // 1000} ms, fall {fall // 1000} ms, play {width:g}", flush=True)
    everything = np.abs(np.concatenate(list(errors.values())))
    for name, values in [*errors.items(), ("all", everything)]:
        values = np.abs(np.asarray(values))
        print(f"{name:9s} max {values.max():5.2f} ms  mean {values.mean():4.2f} ms  within 2 ms: {(values <= 2).sum()} of {len(values)}")
    if args.camera:
        seen: dict = {}
        for grasp in grasps:
            seen.setdefault(grasp.material, []).append(camera_loading(folder, grasp))
        print("camera, loading template against the truth (ms, min / median / max):")
        for name, values in seen.items():
            c, l = np.asarray(values, dtype=float).T / 1000
            print(f"{name:9s} contact {c.min():+6.2f} / {np.median(c):+6.2f} / {c.max():+6.2f}   "
                  f"end of loading {l.min():+6.2f} / {np.median(l):+6.2f} / {l.max():+6.2f}")


if __name__ == "__main__":
    main()
