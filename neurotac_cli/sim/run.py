"""Simulate a data set of grasps: what a rig writes (camera files, force logs, manifest) or a recordings table.

    simulate(config, seed, trials=None, progress=None) -> Simulation
    write_dataset(simulation, folder)          AEDAT 2.0 files, force CSVs, manifest.csv, still.aedat
    recordings(simulation) -> pa.Table         the synced `recordings` table (true sync instant)
"""

import collections
import csv
import dataclasses
import hashlib
import io
import json
import os
from dataclasses import dataclass

import numpy as np

from neurotac_cli.errors import UsageError
from neurotac_cli.sim import dvs, force_sensor
from neurotac_cli.sim.config import SimConfig
from neurotac_cli.sim.grasp import Grasp, plan_grasps, rigid_motion_px, true_force

SENSOR_STEP_US = 250  # the force sensors' dynamics are integrated on this grid, then logged every force_period_us


@dataclass
class Trial:
    grasp: Grasp
    t: np.ndarray  # camera clock, µs
    x: np.ndarray
    y: np.ndarray
    p: np.ndarray
    force_t_us: np.ndarray  # micro-controller clock, µs from LED-off
    force_n: np.ndarray  # the sensor's reading
    true_force_n: np.ndarray  # the true contact force at force_t_us


@dataclass
class Simulation:
    config: SimConfig
    seed: int
    trials: list
    still: tuple  # (t, x, y, p) of the still-scene recording


def simulate(config: SimConfig, seed: int = 0, trials: int | None = None, progress=None, variation=None,
             rigs: int = 0) -> Simulation:
    """Every grasp of the design (or the first `trials`, spread over its groups), same seed same result.

    With a `variation` (sim.physics), each trial gets its own physics and camera, drawn from the
    varied families' ranges, and is simulated on its own; its drawn values go to `grasp.extra["physics"]`.
    With `rigs` as well, each group's grasps are dealt in turn to that many rigs instead, each one draw of the
    physics and one camera shared by its grasps (a lab's sensors), its grasps labelled `rig` = rigN-XXXXXX,
    the suffix a digest of the rig's drawn physics: one name, one sensor, whatever the run that made it.
    """
    streams = np.random.SeedSequence(seed).spawn(4)
    camera = dvs.make_camera(config, np.random.default_rng(streams[0]))
    grasps = plan_grasps(config, np.random.default_rng(streams[1]), trials)
    noise_rngs = [np.random.default_rng(s) for s in streams[2].spawn(len(grasps) + 1)]  # one per trial + the still scene
    if variation is None:
        result = _simulate_trials(config, camera, grasps, noise_rngs, progress)
    elif rigs:
        rig_of = _dealt(grasps, rigs)
        result = [None] * len(grasps)
        for k, seq in enumerate(streams[3].spawn(rigs)):
            rng = np.random.default_rng(seq)
            varied, physics = variation.draw(config, rng)
            members = [i for i, rig in enumerate(rig_of) if rig == k]
            name = f"rig{k + 1}-{hashlib.sha1(json.dumps(physics, sort_keys=True, default=str).encode()).hexdigest()[:6]}"
            planned = []
            for i in members:
                grasp = replan(varied, rng, dataclasses.replace(grasps[i], labels={**grasps[i].labels, "rig": name}))
                grasp.extra["physics"] = physics
                planned.append(grasp)
            made = _simulate_trials(varied, dvs.make_camera(varied, rng), planned, [noise_rngs[i] for i in members], None)
            for i, trial in zip(members, made):
                result[i] = trial
    else:
        result = []
        for grasp, noise_rng, seq in zip(grasps, noise_rngs, streams[3].spawn(len(grasps))):
            rng = np.random.default_rng(seq)
            varied, physics = variation.draw(config, rng)
            grasp = replan(varied, rng, grasp)
            grasp.extra["physics"] = physics
            result += _simulate_trials(varied, dvs.make_camera(varied, rng), [grasp], [noise_rng], None)
    still_rng = noise_rngs[-1]
    start = int(still_rng.uniform(*config.camera_offset_us))
    still = dvs.noise_events(config, camera, start, start + config.still_us, still_rng)
    order = np.argsort(still[0], kind="stable")
    still = tuple(a[order] for a in still)
    return Simulation(config, seed, result, (still[0], still[1].astype(np.uint16), still[2].astype(np.uint16), still[3].astype(np.uint8)))


def _dealt(grasps: list, rigs: int) -> list[int]:
    """Each grasp's rig: the grasps of every group (material, object and labels) dealt in turn, so
    that every rig holds every group (standardising per rig needs each material on each sensor)."""
    groups = [tuple(sorted(g.labels.items())) for g in grasps]  # material, object, size and the group's own labels
    sizes = collections.Counter(groups)
    smallest = min(sizes, key=sizes.get)
    if sizes[smallest] < rigs:
        group = dict(smallest)
        raise UsageError(f"--rigs {rigs}: the group {group['material']}:{group['object']} has {sizes[smallest]} grasp(s), and every rig "
                         f"needs one of every group; give at most {sizes[smallest]} rigs, or more grasps (--trials, --objects)")
    seen = collections.Counter()
    rig_of = []
    for group in groups:
        rig_of.append(seen[group] % rigs)
        seen[group] += 1
    return rig_of


def replan(config: SimConfig, rng: np.random.Generator, grasp: Grasp) -> Grasp:
    """The same grasp (trial id, object, labels, peak force) with timing and pose drawn under other physics."""
    from neurotac_cli.sim.grasp import _plan_one

    custom = {k: v for k, v in grasp.labels.items() if k not in ("material", "object", "size_mm")}
    index = int(grasp.trial.rsplit("-", 1)[1])
    return _plan_one(config, rng, grasp.material, grasp.shape, custom, grasp.peak_force_n, index)


def _simulate_trials(config, camera, grasps, noise_rngs, progress) -> list:
    """The trials of `grasps` on one camera, stepped in lockstep; noise_rngs[i] draws trial i's blink, noise and force log."""
    step = config.step_us
    end = max(g.end_us for g in grasps) if grasps else 0
    steps = int(np.ceil(end / step)) + 1
    times = np.arange(steps) * float(step)
    forces = np.stack([true_force(config, g, times) for g in grasps]) if grasps else np.zeros((0, steps))
    motions = np.stack([rigid_motion_px(config, g, times) for g in grasps]) if grasps else np.zeros((0, steps, 2))
    # The LED blink: whole-array events in closed form, one blink per grasp, each on its own clock.
    blinks = []
    for g, rng in zip(grasps, noise_rngs):
        on = g.camera_start_us + g.preroll_us
        blinks.append(dvs.led_events(config, camera, on, on + g.led_on_us, rng))
    residual = np.stack([b[1] for b in blinks]) if blinks else None
    contacts = dvs.simulate_contacts(config, camera, grasps, forces, motions, residual, progress) if grasps else []
    result = []
    for i, g in enumerate(grasps):
        rng = noise_rngs[i]
        t0 = g.led_off_camera_us
        first, last = g.camera_start_us, t0 + g.end_us
        ct, cx, cy, cp = contacts[i]
        keep = ct < g.end_us  # the recording is [camera start, LED-off + duration)
        led_t, led_x, led_y, led_p = blinks[i][0]
        nt, nx, ny, np_ = dvs.noise_events(config, camera, first, last, rng)
        t = np.concatenate([led_t, ct[keep] + t0, nt])
        x = np.concatenate([led_x, cx[keep], nx])
        y = np.concatenate([led_y, cy[keep], ny])
        p = np.concatenate([led_p, cp[keep], np_])
        inside = (t >= first) & (t < last)
        order = np.argsort(t[inside], kind="stable")
        sel = np.flatnonzero(inside)[order]
        force_t, measured, truth = _force_log(config, g, rng)
        result.append(Trial(g, t[sel], x[sel].astype(np.uint16), y[sel].astype(np.uint16), p[sel].astype(np.uint8),
                            force_t, measured, truth))
    return result


def _force_log(config, grasp, rng):
    """The force log: 500 Hz on the micro-controller clock from LED-off, through the sensor model."""
    fine = np.arange(0, grasp.end_us + SENSOR_STEP_US, SENSOR_STEP_US, dtype=float)
    truth = true_force(config, grasp, fine)
    moving = ((fine >= grasp.contact_us) & (fine <= grasp.loaded_us)) | ((fine >= grasp.release_us) & (fine <= grasp.released_us))
    reading = force_sensor.measure(config, truth, SENSOR_STEP_US, moving.astype(float), rng)
    log_t = np.arange(0, grasp.end_us, config.force_period_us, dtype=np.int64)
    index = np.minimum(np.round(log_t / SENSOR_STEP_US).astype(int), fine.size - 1)
    return log_t, reading[index].astype(np.float32), truth[index].astype(np.float32)


# ---------------------------------------------------------------- outputs


def manifest_rows(simulation: Simulation) -> list[dict]:
    rows = []
    for trial in simulation.trials:
        g = trial.grasp
        rows.append({
            "trial": g.trial,
            "events": f"{g.trial}.aedat",
            "force": f"{g.trial}_force.csv",
            **g.labels,
            "true_t0_us": g.led_off_camera_us,
            "true_peak_force_n": f"{g.peak_force_n:.3f}",
            "true_contact_ms": f"{g.contact_us / 1000:.3f}",
            "true_loaded_ms": f"{g.loaded_us / 1000:.3f}",
            "true_release_ms": f"{g.release_us / 1000:.3f}",
            "true_released_ms": f"{g.released_us / 1000:.3f}",
            "true_duration_ms": f"{g.end_us / 1000:.3f}",
            **{f"true_{name}": f"{value:.6g}" for name, value in g.extra.get("physics", {}).items()},
        })
    return rows


FORCE_HEADER = "t_ms,force_N\n"


def force_lines(t_us: np.ndarray, force_n: np.ndarray) -> str:
    """Force-log rows as the rig's CSV writes them: time in ms, force in N."""
    return "".join(f"{t / 1000:g},{v:.4f}\n" for t, v in zip(t_us.tolist(), force_n.tolist()))


def force_csv(trial: Trial) -> str:
    return FORCE_HEADER + force_lines(trial.force_t_us, trial.force_n)


def write_dataset(simulation: Simulation, folder: str) -> list[str]:
    """Write every trial's camera file and force log, the still recording and manifest.csv; returns the
    paths. All are put in place together once all are written: a run that fails part-way over an
    earlier one's folder left files of both runs beside a manifest of one."""
    from neurotac_cli.io.writers import write_aedat2
    from neurotac_cli.tables import together

    config = simulation.config
    prepare_folder(folder)
    written = []
    with together():
        for trial in simulation.trials:
            path = os.path.join(folder, f"{trial.grasp.trial}.aedat")
            write_aedat2(path, trial.t, trial.x, trial.y, trial.p, config.sensor_width, config.sensor_height)
            force_path = os.path.join(folder, f"{trial.grasp.trial}_force.csv")
            _write_text(force_path, force_csv(trial))
            written += [path, force_path]
        still = os.path.join(folder, "still.aedat")
        write_aedat2(still, *simulation.still, config.sensor_width, config.sensor_height)
        manifest = write_csv(os.path.join(folder, "manifest.csv"), manifest_rows(simulation))
    return written + [still, manifest]


def write_csv(path: str, rows: list[dict], columns: list | None = None) -> str:
    """Rows as a CSV file (`columns` first, then every other key in the order met), written whole or not at all."""
    from neurotac_cli.tables import atomic_file

    names = list(columns or [])
    for row in rows:
        names += [key for key in row if key not in names]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=names, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    with atomic_file(path) as temporary, open(temporary, "w", encoding="utf-8", newline="") as sink:
        sink.write(buffer.getvalue())
    return path


def prepare_folder(folder: str) -> None:
    """Create the output folder (and check it is writable) before minutes of work, not after."""
    from neurotac_cli.errors import NeurotacError

    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as error:
        raise NeurotacError(f"cannot create folder {folder} ({error.strerror}; choose another --out)") from None
    if not os.access(folder, os.W_OK):
        raise NeurotacError(f"cannot write to folder {folder} (permission denied; choose another --out)")


def _write_text(path, text):
    from neurotac_cli.tables import atomic_file

    with atomic_file(path) as temporary, open(temporary, "w", encoding="utf-8", newline="") as sink:
        sink.write(text)


def recordings(simulation: Simulation, keep_led: bool = False):
    """The `recordings` table: each trial's events and measured force relative to the true LED-off instant."""
    from neurotac_cli import schema

    from neurotac_cli.ops.led import led_burst_end_us

    config = simulation.config
    rows = []
    for trial in simulation.trials:
        g = trial.grasp
        t0 = g.led_off_camera_us
        t = trial.t - t0
        # as `neurotac sync` does by default: the blink marks the instant, it is not touch
        kept = slice(None) if keep_led else slice(int(np.searchsorted(t, led_burst_end_us(t, trial.p))), None)
        rows.append({
            "trial": g.trial,
            "t0": t0,
            "events": (t[kept], trial.x[kept], trial.y[kept], trial.p[kept]),
            "force": (trial.force_t_us, trial.force_n),
            "labels": dict(g.labels),
        })
    sync = {"method": "simulated", "note": "t0 is the true LED-off instant", "offsets": {r["trial"]: r["t0"] for r in rows}}
    table = schema.recordings_table(rows, config.sensor_width, config.sensor_height, sync=sync)
    return table
