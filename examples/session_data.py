"""Sessions strung from simulated single grasps: one long recording of many grasps with rests between.

A session here is what a robot's sensor sees: grasps of mixed objects at random times, 0.3-3 s
rests of background activity between them, one force log, no LED blink before each grasp. The
grasps come from `simulate` (one seed), each kept from the end of its LED burst to the end of its
recording and moved onto the session clock; the rests are the simulator's still-scene recording
(background activity and hot pixels) cut in turn. The same grasps are also framed as trials (each
from its own LED-off instant, as `neurotac frame` does) so a model can be scored both ways.

    frames_session, frames_trials, grasps = build(seed=7, grasps=6)

Frames are cut `box` (x, y, w, h) from the 240x180 sensor and sum-pooled by `pool`; `phase` is
each grasp's true phase (none between grasps) and `grasp` its index (null at rest).
"""

from dataclasses import dataclass

import numpy as np
import pyarrow as pa

from neurotac_cli import schema as sch
from neurotac_cli.ops.crop import crop_event_arrays
from neurotac_cli.ops.frame import count_frames, frame_force
from neurotac_cli.ops.sync import led_burst_end_us
from neurotac_cli.sim.config import preset_config
from neurotac_cli.sim.run import simulate

BOX = (60, 30, 120, 120)  # about the sensor's centre, where the simulated objects land
POOL = (4, 4)  # 120x120 -> 30x30: a CPU trains the LSTM and ConvLSTM on sessions at this size
WINDOW_US = 10_000
FORCE_PERIOD_US = 2_000


@dataclass
class GraspTruth:
    index: int
    trial: str
    obj: str
    material: str
    peak_n: float
    contact_us: int  # session clock
    loaded_us: int
    release_us: int
    released_us: int


def build(seed: int, grasps: int, preset: str = "ch4", rest_s=(0.3, 3.0), window_us: int = WINDOW_US,
          box=BOX, pool=POOL, name: str | None = None, empty: bool = False):
    """(session frames, the same grasps framed as trials, [GraspTruth]); `empty`: the rests only."""
    rng = np.random.default_rng([seed, 101])
    rests = rng.uniform(*rest_s, size=grasps + 1) * 1e6
    config = preset_config(preset, still_us=int(rests.sum()) + 1_000_000)
    simulation = simulate(config, seed, trials=grasps)
    trials = [simulation.trials[i] for i in rng.permutation(len(simulation.trials))]
    still_t, still_x, still_y, still_p = simulation.still
    still_t = still_t - still_t[0]
    parts, force_parts, truths, cursor = [], [], [], 0
    for index, trial in enumerate([] if empty else trials):
        g = trial.grasp
        t = trial.t - g.led_off_camera_us
        begin = max(0, led_burst_end_us(t, trial.p))
        start = cursor + int(rests[index])
        parts.append(_rest(still_t, still_x, still_y, still_p, cursor, start))
        offset = start - begin
        keep = (t >= begin) & (t < g.end_us)
        parts.append((t[keep] + offset, trial.x[keep], trial.y[keep], trial.p[keep]))
        logged = trial.force_t_us >= begin
        force_parts.append((trial.force_t_us[logged] + offset, trial.force_n[logged]))
        truths.append(GraspTruth(index, g.trial, g.labels["object"], g.material, g.peak_force_n, g.contact_us + offset,
                                 g.loaded_us + offset, g.release_us + offset, g.released_us + offset))
        cursor = offset + g.end_us
    end = cursor + int(rests[-1])
    parts.append(_rest(still_t, still_x, still_y, still_p, cursor, end))
    events = [np.concatenate(column) for column in zip(*parts)]
    session = _frames(name or f"session-{seed}", events, _force_log(force_parts, end), end, truths, window_us, box, pool)
    cut = pa.concat_tables([_trial_frames(trial, truth, window_us, box, pool) for trial, truth in
                            zip(trials, truths)]) if truths else None
    return session, cut, truths


def _rest(t, x, y, p, start, end):
    """Still-scene events moved onto [start, end) of the session (the still recording is long enough)."""
    keep = t < end - start
    return t[keep] + start, x[keep], y[keep], p[keep]


def _force_log(parts, end):
    """A 500 Hz log: zero at rest, each grasp's measured force inside its recording."""
    times = np.arange(0, end, FORCE_PERIOD_US, dtype=np.int64)
    values = np.zeros(len(times), dtype=np.float32)
    for t, v in parts:
        index = np.clip(t // FORCE_PERIOD_US, 0, len(times) - 1)
        values[index] = v
    return times, values


def _frames(trial_id, events, force, end, truths, window_us, box, pool):
    t, x, y, p = events
    order = np.argsort(t, kind="stable")
    (t, x, y, p), _ = crop_event_arrays(t[order], x[order], y[order], p[order], box, pool)
    width, height = box[2] // pool[0], box[3] // pool[1]
    n = -(-end // window_us)
    counts = count_frames(t, x, y, p, window_us, n, height, width)
    forces = frame_force(force[0], force[1], window_us, n)
    phase, grasp = _truth_per_frame(truths, n, window_us)
    schema = sch.frames_schema(height, width, window_us=window_us, extra=[("grasp", pa.int32())])
    columns = [
        pa.array([trial_id] * n, pa.string()), pa.array(np.arange(n, dtype=np.int32)),
        pa.array(np.arange(n, dtype=np.int64) * window_us), sch.counts_array(counts),
        pa.array(forces, pa.float32()), pa.array(phase.tolist(), pa.string()),
        pa.array(grasp, pa.int32(), mask=grasp < 0),
    ]
    return pa.Table.from_arrays(columns, schema=schema)


def _truth_per_frame(truths, n, window_us):
    """Each frame labelled by the true state at its end (the force is read there too)."""
    ends = (np.arange(n, dtype=np.int64) + 1) * window_us
    phase = np.full(n, "none", dtype=object)
    grasp = np.full(n, -1, dtype=np.int32)
    for g in truths:
        for label, lo, hi in (("grasping", g.contact_us, g.loaded_us), ("holding", g.loaded_us, g.release_us),
                              ("releasing", g.release_us, g.released_us)):
            inside = (ends > lo) & (ends <= hi)
            phase[inside] = label
            grasp[inside] = g.index
    return phase, grasp


def _trial_frames(trial, truth, window_us, box, pool):
    """One grasp framed as a trial from its LED-off instant, the LED burst left out (as `sync` does)."""
    g = trial.grasp
    t = trial.t - g.led_off_camera_us
    begin = max(0, led_burst_end_us(t, trial.p))
    keep = (t >= begin) & (t < g.end_us)
    local = GraspTruth(0, g.trial, truth.obj, truth.material, truth.peak_n, g.contact_us, g.loaded_us, g.release_us, g.released_us)
    return _frames(g.trial, (t[keep], trial.x[keep], trial.y[keep], trial.p[keep]),
                    (trial.force_t_us, trial.force_n), g.end_us, [local], window_us, box, pool)
