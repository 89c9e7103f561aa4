"""Sessions: one long recording of many grasps, as a robot's sensor sees them.

One LED blink at the start (its switch-off is the session's time 0, where the force log starts),
then grasps of objects drawn from a pool, each after a rest, at its own gripper speed, with events
while held: re-grasps, force changes, partial releases and slips. Background activity runs
throughout, and the lighting can drift slowly.

What each event is (the labels of `ops.phases.label_session` follow these definitions):

- **re-grasp**: the gripper loosens fast to 10-30% of the held force (the object stays touching)
  and tightens again to a new level: releasing, then grasping, inside the same grasp.
- **force change while held**: the held force moves by 10-40% over 150-400 ms, at the grip's
  regulation speed (slower than a grasp or a release): still holding.
- **partial release**: the gripper opens fast to 30-60% of the held force and holds there until the
  final release: releasing, then holding.
- **slip**: the contact patch moves along the membrane at `slip_speed_mm_s` for `slip_us` while the
  normal force drops by a share drawn from `slip_force_drop` (0: it does not drop); the object stays
  where it slid to.

    plan_session(config, rng, n_grasps, pool, min_duration_us) -> Session
    write_sessions(config, seed, ...) -> paths        AEDAT 2.0 + force log per session, manifest.csv, grasps.csv

Memory stays bounded: the recording is generated and written one grasp (and the rest before it) at
a time; the largest thing held is one grasp's events.
"""

import os
from dataclasses import dataclass, field, replace

import numpy as np

from neurotac_cli.errors import UsageError
from neurotac_cli.sim import dvs, force_sensor
from neurotac_cli.sim.config import SimConfig, parse_groups
from neurotac_cli.sim.grasp import Grasp, loading_us, rigid_motion_px

LEAD_US = 10_000  # a grasp's local clock starts this long before its first touch
SETTLE_US = 30_000  # and its pixels are stepped this long after contact is lost
FORCE_STEP_US = 250


@dataclass
class Slip:
    start_us: int  # local clock of the grasp
    end_us: int
    speed_mm_s: float
    direction: tuple  # unit vector on the sensor (x, y)
    force_drop: float  # share of the normal force lost by the slip's end


@dataclass
class SessionGrasp:
    index: int
    grasp: Grasp  # contact_us .. released_us on the local clock; center, pose, shape, material
    offset_us: int  # session time (µs from LED-off) of the local clock's 0
    segments: list  # (t0, t1, f0, f1, kind): kind load | unload | ramp | hold, on the local clock
    speed: float  # gripper speed factor
    events: dict = field(default_factory=dict)  # regrasp / change / partial: local start time (µs)
    slip: Slip | None = None
    slip_drawn: bool = False  # a slip was drawn for this grasp (slip_share); `slip` stays None where no plateau could hold it
    config: SimConfig | None = None  # the grasp's own physics, where the objects family is drawn per grasp
    physics: dict = field(default_factory=dict)  # what was drawn for this grasp

    @property
    def stop_us(self) -> int:
        """End of the grasp's window on the local clock: contact lost plus the pixels' settling."""
        return self.grasp.released_us + SETTLE_US


@dataclass
class Session:
    name: str
    grasps: list
    duration_us: int  # from LED-off to the end of the recording
    camera_start_us: int
    preroll_us: int
    led_on_us: int

    @property
    def led_off_camera_us(self) -> int:
        return self.camera_start_us + self.preroll_us + self.led_on_us


# ---------------------------------------------------------------- planning


def object_pool(config: SimConfig) -> list[tuple]:
    """(material, shape, weight, labels) of every object a session draws from: the trial groups, weighted by count."""
    return [(material, shape, count, labels) for material, shape, count, labels in parse_groups(config.groups) if count > 0]


def plan_session(config: SimConfig, rng: np.random.Generator, n_grasps: int, name: str = "session",
                 min_duration_us: int = 0, variation=None) -> Session:
    """Draw a session's grasps: objects, peak forces, rests, speeds, events while held, slips, poses.

    A `variation` that varies the `objects` family draws it again for every grasp (its pose, tilt,
    rim and motions are the object's, not the sensor's)."""
    pool = object_pool(config)
    weights = np.array([entry[2] for entry in pool], float)
    camera_start = int(rng.uniform(*config.camera_offset_us))
    preroll = int(rng.uniform(*config.preroll_us))
    led_on = int(rng.uniform(*config.led_on_us))
    now = 0  # session time, µs from LED-off
    grasps = []
    for index in range(n_grasps):
        material, shape, _, labels = pool[int(rng.choice(len(pool), p=weights / weights.sum()))]
        now += int(rng.uniform(*config.session_rest_us))  # at least LEAD_US + SETTLE_US + 10 ms (config.validate)
        own, physics = (config, {}) if variation is None else variation.draw_family(config, rng, "objects")
        planned = _plan_grasp(own, rng, index, material, shape, labels, offset_us=now - LEAD_US)
        if physics:
            planned.config, planned.physics = own, physics
        if config.bright_share > 0:  # drawn only where asked: other seeds keep their bytes
            contrast = config.bright_contrast if rng.random() < config.bright_share else own.object_contrast
            planned.config = replace(own, object_contrast=contrast)
            planned.physics = {**planned.physics, "object_contrast": contrast}
        grasps.append(planned)
        now = planned.offset_us + planned.grasp.released_us
    rest = int(rng.uniform(*config.session_rest_us))
    end = now + rest if grasps or not min_duration_us else 0  # a session of no grasps lasts --duration exactly
    return Session(name, grasps, max(end, min_duration_us), camera_start, preroll, led_on)


def _plan_grasp(config, rng, index, material, shape, labels, offset_us) -> SessionGrasp:
    peak = float(rng.uniform(config.force_min_n, config.force_max_n))
    speed = float(np.exp(rng.uniform(*np.log(config.session_speed))))
    load_us = _ramp_us(config, material, shape, peak, speed)
    hold_us = int(rng.uniform(*config.session_hold_us))
    wanted = [kind for kind, share in (("change", config.change_share), ("regrasp", config.regrasp_share)) if rng.random() < share]
    rng.shuffle(wanted)
    if rng.random() < config.partial_share:
        wanted.append("partial")  # a partial release ends the hold: the object is then released from there
    pieces = _split_hold(rng, hold_us, len(wanted) + 1)
    t = LEAD_US
    segments = [(t, t + load_us, 0.0, peak, "load")]
    t += load_us
    level = peak
    events = {}
    plateaus = []
    for kind, piece in zip(wanted + [None], pieces):
        segments.append((t, t + piece, level, level, "hold"))
        plateaus.append(len(segments) - 1)
        t += piece
        level = _end_level(config, material, segments[-1])
        if kind is None:
            break
        events[kind] = t
        t, level = _event(config, rng, material, shape, kind, segments, t, level, peak, speed)
    unload_us = max(2_000, int(0.5 * _ramp_us(config, material, shape, level, speed)))
    segments.append((t, t + unload_us, level, 0.0, "unload"))
    released = t + unload_us
    grasp = _pose(config, rng, index, material, shape, labels, peak, segments, released)
    planned = SessionGrasp(index, grasp, offset_us, segments, speed, events)
    if rng.random() < config.slip_share:
        planned.slip_drawn = True
        planned.slip = _plan_slip(config, rng, grasp, [segments[i] for i in plateaus])
    return planned


def _ramp_us(config, material, shape, force_n, speed) -> int:
    """Loading time at a gripper speed factor: the servo's shortest ramp plus the travel at that speed."""
    travel = loading_us(config, material, shape, max(force_n, 1e-3)) - config.servo_settle_us
    return int(config.servo_settle_us + travel / speed)


def _split_hold(rng, hold_us, parts) -> list[int]:
    """The hold cut into `parts` plateaus of random lengths, each at least 150 ms."""
    floor = 150_000
    free = max(0, hold_us - floor * parts)
    shares = rng.dirichlet(np.ones(parts))
    return [floor + int(free * share) for share in shares]


def _event(config, rng, material, shape, kind, segments, t, level, peak, speed):
    """Append an event's ramps; returns the time and force level after it."""
    top = max(config.force_max_n, peak)
    if kind == "change":
        step = float(rng.uniform(0.1, 0.4)) * (1 if rng.random() < 0.5 else -1)
        new = float(np.clip(level * (1 + step), 0.2 * peak, top))
        ramp = int(rng.uniform(150_000, 400_000))
        segments.append((t, t + ramp, level, new, "ramp"))
        return t + ramp, new
    low = level * float(rng.uniform(0.1, 0.3) if kind == "regrasp" else rng.uniform(0.3, 0.6))
    fall = max(5_000, int(0.5 * _ramp_us(config, material, shape, level - low, speed)))
    segments.append((t, t + fall, level, low, "ramp"))
    t += fall
    if kind == "partial":
        return t, low
    pause = int(rng.uniform(30_000, 150_000))
    segments.append((t, t + pause, low, low, "hold"))
    t += pause
    new = float(np.clip(peak * rng.uniform(0.8, 1.2), 0.2 * peak, top))
    rise = _ramp_us(config, material, shape, new - low, speed)
    segments.append((t, t + rise, low, new, "ramp"))
    return t + rise, new


def _relaxation(config, material):
    from neurotac_cli.sim.config import MATERIALS

    mat = MATERIALS[material]
    return (mat.relaxation if config.gripper == "position" else 0.0), mat.relaxation_us


def _end_level(config, material, segment) -> float:
    share, tau = _relaxation(config, material)
    t0, t1, f0, _, _ = segment
    return f0 * (1.0 - share * -np.expm1(-(t1 - t0) / tau))


def _pose(config, rng, index, material, shape, labels, peak, segments, released) -> Grasp:
    w, h = config.sensor_width, config.sensor_height
    center = (w / 2 + config.position_jitter_px * rng.standard_normal(), h / 2 + config.position_jitter_px * rng.standard_normal())
    angles = rng.uniform(0, 2 * np.pi, 3)
    final = [s for s in segments if s[4] == "unload"][0]
    return Grasp(
        trial=f"grasp{index:03d}", material=material, shape=shape,
        labels={"material": material, "object": shape.name, "size_mm": shape.size_label, **labels},
        peak_force_n=peak, contact_us=LEAD_US, loaded_us=int(segments[0][1]), release_us=int(final[0]),
        released_us=int(released), end_us=int(released) + SETTLE_US, center_px=center,
        orientation=float(rng.uniform(0, np.pi / 3)),
        tilt=abs(float(rng.standard_normal())) * np.deg2rad(config.tilt_deg),
        tilt_dir=(float(np.cos(angles[0])), float(np.sin(angles[0]))),
        vibration_phase=float(rng.uniform(0, 2 * np.pi)),
        settle_dir=(float(np.cos(angles[1])), float(np.sin(angles[1]))),
        drift_dir=(float(np.cos(angles[2])), float(np.sin(angles[2]))),
        camera_start_us=0, preroll_us=0, led_on_us=0, ripple_seed=int(rng.integers(0, 2**63 - 1)),
    )


def _plan_slip(config, rng, grasp, plateaus) -> Slip | None:
    """A slip inside one of the plateaus, kept on the sensor: it stops before the face's centre leaves a 20 px margin."""
    long_enough = [s for s in plateaus if s[1] - s[0] >= config.slip_us[0] + 60_000]
    if not long_enough:
        return None
    t0, t1, *_ = long_enough[int(rng.integers(len(long_enough)))]
    length = int(min(rng.uniform(*config.slip_us), t1 - t0 - 60_000))
    start = int(rng.uniform(t0 + 30_000, t1 - 30_000 - length))
    angle = rng.uniform(0, 2 * np.pi)
    direction = (float(np.cos(angle)), float(np.sin(angle)))
    speed = float(rng.uniform(*config.slip_speed_mm_s))
    drop = float(rng.uniform(*config.slip_force_drop))
    room = _room_px(config, grasp.center_px, direction)
    length = int(min(length, room * config.pixel_pitch_mm / max(speed, 1e-9) * 1e6))
    return Slip(start, start + max(length, 1_000), speed, direction, drop)


def _room_px(config, center, direction) -> float:
    """How far the face's centre can move along `direction` before it comes within 20 px of the border."""
    margin = 20.0
    limits = []
    for value, d, size in ((center[0], direction[0], config.sensor_width), (center[1], direction[1], config.sensor_height)):
        if d > 1e-9:
            limits.append((size - margin - value) / d)
        elif d < -1e-9:
            limits.append((value - margin) / -d)
    return max(0.0, min(limits, default=0.0))


# ---------------------------------------------------------------- the grasp over time


def grasp_force(config: SimConfig, planned: SessionGrasp, t_us: np.ndarray) -> np.ndarray:
    """The true contact force (N) at local times t: the segments, relaxation on plateaus, ripple, the slip's drop."""
    config = planned.config or config
    t = np.asarray(t_us, dtype=float)
    force = np.zeros_like(t)
    share, tau = _relaxation(config, planned.grasp.material)
    for t0, t1, f0, f1, kind in planned.segments:
        inside = (t >= t0) & (t < t1)
        u = (t[inside] - t0) / max(1.0, t1 - t0)
        if kind == "load":
            force[inside] = f0 + (f1 - f0) * u**1.5
        elif kind == "unload":
            force[inside] = f1 + (f0 - f1) * (1 - u) ** 1.5
        elif kind == "ramp":
            force[inside] = f0 + (f1 - f0) * (3 * u**2 - 2 * u**3)
        else:
            force[inside] = f0 * (1.0 - share * -np.expm1(-(t[inside] - t0) / tau))
    g = planned.grasp
    held = (t >= g.loaded_us) & (t < g.release_us)
    from neurotac_cli.sim.grasp import _ripple

    force = force * (1.0 + config.force_vibration * _ripple(config, g, t) * held)
    if planned.slip is not None:  # the grip stays looser after a slip: every later level is lower by its drop
        s = planned.slip
        force = force * (1.0 - s.force_drop * np.clip((t - s.start_us) / max(1, s.end_us - s.start_us), 0, 1))
    return np.clip(force, 0.0, None)


def grasp_motion(config: SimConfig, planned: SessionGrasp, t_us: np.ndarray) -> np.ndarray:
    """Displacement of the face on the sensor (px, (n, 2)): settling, drift, vibration, and the slip."""
    config = planned.config or config
    t = np.asarray(t_us, dtype=float)
    motion = rigid_motion_px(config, planned.grasp, t)
    if planned.slip is not None:
        s = planned.slip
        moved_px = s.speed_mm_s / config.pixel_pitch_mm * np.clip(t - s.start_us, 0, s.end_us - s.start_us) * 1e-6
        motion = motion + moved_px[:, None] * np.asarray(s.direction)[None, :]
    return motion


def gripper_moving(planned: SessionGrasp, t_us: np.ndarray) -> np.ndarray:
    """1 where the gripper moves (loading, unloading, ramps): the FlexiForce is noisier then."""
    t = np.asarray(t_us, dtype=float)
    moving = np.zeros(t.shape)
    for t0, t1, _, _, kind in planned.segments:
        if kind != "hold":
            moving[(t >= t0) & (t < t1)] = 1.0
    return moving


# ---------------------------------------------------------------- writing, one grasp at a time


class _Drift:
    """Events of a slow, uniform drift of the lighting, L(t) = 1 + A sin(2 pi t / T + phase), from LED-off on.

    Every pixel's log level moves by log L(t); stepped on a coarse grid (the drift is slow beside any
    threshold crossing) with the pixel model's own threshold and refractory logic, over the whole array.
    """

    STEP_US = 50_000

    def __init__(self, config, camera, residual, rng):
        self.config = config
        self.on = camera.on_threshold.ravel().astype(np.float64)
        self.off = camera.off_threshold.ravel().astype(np.float64)
        self.phase = float(rng.uniform(0, 2 * np.pi))
        self.reference = residual.ravel().astype(np.float64) + self.level(0.0)
        self.last = np.full(self.reference.size, -1e12)
        self.width = camera.shape[1]

    def level(self, t_us):
        c = self.config
        return float(np.log1p(c.illumination_drift * np.sin(2 * np.pi * t_us / c.illumination_period_us + self.phase)))

    def events(self, start_us: int, end_us: int):
        parts = []
        for t0 in range(max(0, start_us), end_us, self.STEP_US):
            step = min(self.STEP_US, end_us - t0)
            before = np.full(self.reference.size, self.level(t0))
            after = np.full(self.reference.size, self.level(t0 + step))
            fired = dvs._fire(before, after, self.reference, self.on, self.off, self.last, float(t0), step, self.config.refractory_us)
            if fired is not None:
                parts.append(fired)
        if not parts:
            return _no_events()
        pixel, t, p = (np.concatenate([part[j] for part in parts]) for j in range(3))
        return np.round(t).astype(np.int64), pixel % self.width, pixel // self.width, p


def _no_events():
    return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.uint8)


def _contact_events(config, camera, planned: SessionGrasp, residual, progress=None):
    """One grasp's contact events on the session clock; `residual` (H, W) carries the pixels' state across grasps."""
    config = planned.config or config
    step = config.step_us
    times = np.arange(int(np.ceil(planned.stop_us / step)) + 1) * float(step)
    force = grasp_force(config, planned, times)
    motion = grasp_motion(config, planned, times)
    state = {}
    (t, x, y, p), = dvs.simulate_contacts(config, camera, [planned.grasp], force[None], motion[None], residual[None],
                                          progress, exact=planned.slip is not None, state=state)
    residual[state["y"], state["x"]] = state["residual"]
    keep = t < planned.stop_us
    return t[keep] + planned.offset_us, x[keep], y[keep], p[keep]


def _force_log(config, planned, start_us, end_us, rng):
    """The force log's samples in [start, end) of the session clock (t µs, reading N, truth N)."""
    start = max(0, start_us)
    fine = np.arange(start, end_us + FORCE_STEP_US, FORCE_STEP_US, dtype=float)
    if planned is None:
        truth, moving = np.zeros_like(fine), np.zeros_like(fine)
    else:
        truth = grasp_force(config, planned, fine - planned.offset_us)
        moving = gripper_moving(planned, fine - planned.offset_us)
    zero = config.force_drift_n_per_min * fine / 60e6 if config.force_drift_n_per_min else 0.0  # drifting with the session's clock
    reading = force_sensor.measure(config, truth, FORCE_STEP_US, moving, rng, zero)
    period = config.force_period_us
    log_t = np.arange(-(-start // period) * period, end_us, period, dtype=np.int64)
    index = np.minimum(np.round((log_t - start) / FORCE_STEP_US).astype(int), fine.size - 1)
    return log_t, reading[index], truth[index]


@dataclass
class SessionResult:
    """What a written session holds besides its files: for the manifests and for tests."""

    session: Session
    physics: dict
    events: int = 0
    force_t_us: list = field(default_factory=list)
    true_force_n: list = field(default_factory=list)


@dataclass
class SessionDraw:
    """What a session's seed decides before any event: its physics (`config`, drawn once per session
    with --vary), the plan of its grasps, and the random streams and seeds the simulation goes on with."""

    config: SimConfig
    physics: dict
    session: Session
    streams: list  # physics, camera, plan, LED and drift
    chunk_seeds: np.random.SeedSequence


def draw_session(config: SimConfig, seq: np.random.SeedSequence, n_grasps: int, name: str = "session",
                 variation=None, min_duration_us: int = 0) -> SessionDraw:
    children = seq.spawn(5)
    streams = [np.random.default_rng(s) for s in children[:4]]
    physics = {}
    if variation is not None:  # the sensor's physics once per session; the objects family per grasp (plan_session)
        config, physics = variation.without("objects").draw(config, streams[0])
    session = plan_session(config, streams[2], n_grasps, name, min_duration_us, variation)
    return SessionDraw(config, physics, session, streams, children[4])


def simulate_session(draw: SessionDraw, events_sink, force_sink, progress=None) -> SessionResult:
    """Generate one drawn session chunk by chunk: each chunk, the rest before a grasp and the grasp, goes to
    `events_sink(t_camera_us, x, y, p)` and `force_sink(t_us, reading_n)` before the next is made."""
    config, physics, session, streams = draw.config, draw.physics, draw.session, draw.streams
    camera = dvs.make_camera(config, streams[1])
    (led_t, led_x, led_y, led_p), residual = dvs.led_events(config, camera, -session.led_on_us, 0, streams[3])
    drift = _Drift(config, camera, residual, streams[3]) if config.illumination_drift > 0 else None
    chunk_seeds = draw.chunk_seeds  # spawned in turn, two per chunk: noise, force sensor
    clock = session.led_off_camera_us  # camera time of the session's 0
    result = SessionResult(session, physics)
    for start, end, planned in _chunks(session):
        noise_rng, sensor_rng = (np.random.default_rng(s) for s in chunk_seeds.spawn(2))
        parts = [dvs.noise_events(config, camera, start, end, noise_rng)]
        if start < 0:
            parts.append((led_t, led_x, led_y, led_p))
        if planned is not None:
            parts.append(_contact_events(config, camera, planned, residual, progress))
        if drift is not None:
            parts.append(drift.events(start, end))
        t, x, y, p = (np.concatenate([np.asarray(part[j]) for part in parts]) for j in range(4))
        inside = (t >= start) & (t < end)
        order = np.flatnonzero(inside)[np.argsort(t[inside], kind="stable")]
        events_sink(t[order] + clock, x[order], y[order], p[order].astype(np.uint8))
        result.events += order.size
        log_t, reading, truth = _force_log(config, planned, start, end, sensor_rng)
        force_sink(log_t, reading)
        result.force_t_us.append(log_t)
        result.true_force_n.append(truth.astype(np.float32))
    result.force_t_us = np.concatenate(result.force_t_us)
    result.true_force_n = np.concatenate(result.true_force_n)
    return result


def _refuse_sessions_past_the_clock(sessions: list):
    """Refuse a planned session that would record past the AEDAT 2.0 clock, before the folder is made:
    the writer would otherwise find it after the minutes of simulating what fits."""
    from neurotac_cli.io.writers import AEDAT2_LAST_US

    for session in sessions:
        if session.led_off_camera_us + session.duration_us > AEDAT2_LAST_US:
            fit = sum(session.led_off_camera_us + g.offset_us + g.stop_us <= AEDAT2_LAST_US for g in session.grasps)
            raise UsageError(f"{session.name} would record {session.duration_us / 60e6:.1f} min, past the "
                             f"{AEDAT2_LAST_US / 60e6:.1f} min of an AEDAT 2.0 file's clock (its first {fit} grasps fit); give "
                             "fewer --grasps and more --sessions, or a shorter --duration")


CHUNK_US = 2_000_000  # rests are generated and written in pieces of at most this length


def _chunks(session: Session):
    """(start, end, grasp or None) pieces of the session clock, in order: the blink, each grasp's window, the rests
    between them cut into pieces of at most CHUNK_US. Every event of a grasp falls inside its own piece."""
    now = -(session.led_on_us + session.preroll_us)
    windows = [(g.offset_us, g.offset_us + g.stop_us, g) for g in session.grasps]
    for start, stop, planned in windows + [(session.duration_us, session.duration_us, None)]:
        while now < start:
            end = min(start, now + CHUNK_US, 100_000 if now < 0 else now + CHUNK_US)
            yield now, end, None
            now = end
        if planned is not None:
            yield start, stop, planned
            now = stop


def write_sessions(config: SimConfig, seed: int, n_grasps: int, folder: str, sessions: int = 1, variation=None,
                   min_duration_us: int = 0, progress=None, notes: list | None = None) -> list[str]:
    """Write `sessions` sessions (`sessionNN.aedat`, `sessionNN_force.csv`), manifest.csv and grasps.csv; returns the paths.
    `notes` gets a line where slips drawn had no plateau long enough to hold them."""
    from neurotac_cli.io.writers import aedat2_bytes
    from neurotac_cli.sim.run import FORCE_HEADER, force_lines, prepare_folder, write_csv
    from neurotac_cli.tables import atomic_file

    if n_grasps and not object_pool(config):  # before the folder is made, not after
        raise UsageError(f"--grasps {n_grasps}: every group of --objects has a count of 0, so a session has no object to "
                         "grasp (give a group a count of 1 or more, or --grasps 0 for a session at rest)")
    # every session planned first (plans are cheap beside events), so a session too long is refused before any work
    draws = [draw_session(config, seq, n_grasps, f"session{number:02d}", variation, min_duration_us)
             for number, seq in enumerate(np.random.SeedSequence(seed).spawn(sessions))]
    _refuse_sessions_past_the_clock([draw.session for draw in draws])
    prepare_folder(folder)
    width, height = config.sensor_width, config.sensor_height
    header = len(aedat2_bytes([], [], [], [], width, height))  # chunks after the first are written without it
    rows, grasp_rows, written = [], [], []
    for draw in draws:
        name = draw.session.name
        events_path = os.path.join(folder, f"{name}.aedat")
        force_path = os.path.join(folder, f"{name}_force.csv")
        with atomic_file(events_path) as events_tmp, open(events_tmp, "wb") as events, \
                atomic_file(force_path) as force_tmp, open(force_tmp, "w", encoding="utf-8", newline="") as forces:
            events.write(aedat2_bytes([], [], [], [], width, height))
            forces.write(FORCE_HEADER)
            result = simulate_session(
                draw,
                lambda t, x, y, p: events.write(aedat2_bytes(t, x, y, p, width, height)[header:]),
                lambda t, v: forces.write(force_lines(t, v)),
                progress,
            )
        rows.append(session_row(result))
        grasp_rows += [grasp_row(name, planned) for planned in result.session.grasps]
        written += [events_path, force_path]
    written.append(write_csv(os.path.join(folder, "manifest.csv"), rows))
    written.append(write_csv(os.path.join(folder, "grasps.csv"), grasp_rows, GRASP_COLUMNS))
    grasps = [planned for draw in draws for planned in draw.session.grasps]
    drawn, dropped = sum(g.slip_drawn for g in grasps), sum(g.slip_drawn and g.slip is None for g in grasps)
    if dropped and notes is not None:
        notes.append(f"{dropped} of the {drawn} slips drawn had no hold long enough for them (slip_us {config.slip_us[0] / 1000:g} ms "
                     "and more, with 30 ms either side) and were left out: lengthen session_hold_us or shorten slip_us")
    return written


GRASP_COLUMNS = ["session", "grasp", "material", "object", "size_mm", "peak_force_n", "contact_ms", "loaded_ms",
                 "release_ms", "released_ms", "speed", "regrasp_ms", "change_ms", "partial_ms", "slip_start_ms",
                 "slip_end_ms", "slip_speed_mm_s", "slip_force_drop", "slip_dx_mm", "slip_dy_mm"]


def session_row(result: SessionResult) -> dict:
    session = result.session
    return {
        "trial": session.name, "events": f"{session.name}.aedat", "force": f"{session.name}_force.csv",
        "true_t0_us": session.led_off_camera_us, "true_grasps": len(session.grasps),
        "true_duration_ms": f"{session.duration_us / 1000:.3f}", "true_grasps_file": "grasps.csv",
        **{f"true_{name}": f"{value:.6g}" for name, value in result.physics.items()},
    }


def grasp_row(session_name: str, planned: SessionGrasp) -> dict:
    """The grasp's ground truth on the session clock (ms from LED-off, the force log's clock)."""
    g, offset = planned.grasp, planned.offset_us

    def ms(local_us):
        return f"{(local_us + offset) / 1000:.3f}"

    row = {"session": session_name, "grasp": planned.index, **g.labels, "peak_force_n": f"{g.peak_force_n:.3f}",
           "contact_ms": ms(g.contact_us), "loaded_ms": ms(g.loaded_us), "release_ms": ms(g.release_us),
           "released_ms": ms(g.released_us), "speed": f"{planned.speed:.3f}"}
    row.update({f"{kind}_ms": ms(t) for kind, t in planned.events.items()})
    row.update({f"true_{name}": f"{value:.6g}" for name, value in planned.physics.items()})
    if planned.slip is not None:
        s = planned.slip
        length_mm = s.speed_mm_s * (s.end_us - s.start_us) * 1e-6
        row.update(slip_start_ms=ms(s.start_us), slip_end_ms=ms(s.end_us), slip_speed_mm_s=f"{s.speed_mm_s:.2f}",
                   slip_force_drop=f"{s.force_drop:.3f}", slip_dx_mm=f"{length_mm * s.direction[0]:.3f}",
                   slip_dy_mm=f"{length_mm * s.direction[1]:.3f}")
    return row
