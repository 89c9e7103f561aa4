"""Parameters of the grasp simulator, the thesis's three experiment designs as presets, and materials.

Every field of `SimConfig` can be overridden from the command line (`--set NAME=VALUE`); fields ending
in `_us` are durations (µs). Sources of the defaults are given in docs/simulator.md.
"""

import dataclasses
import math
from dataclasses import dataclass

from neurotac_cli.errors import NeurotacError, SchemaError, UsageError
from neurotac_cli.ops.forcelog import RANGE_N
from neurotac_cli.schema import check_label_names


@dataclass(frozen=True)
class Material:
    """An object material: Young's modulus (Pa), Poisson's ratio, and stress relaxation under a held squeeze."""

    name: str
    youngs_pa: float
    poisson: float
    relaxation: float  # share of the force lost during a long hold at fixed gripper position
    relaxation_us: int  # time constant of that relaxation


# Handbook ranges (docs/simulator.md): flexible PU foam 0.1-1 MPa, soft silicone rubber 1-5 MPa
# (shore 30-60A), natural/nitrile rubber 2-10 MPa, steel 200 GPa.
MATERIALS = {
    "foam": Material("foam", 0.3e6, 0.25, 0.22, 250_000),
    "silicone": Material("silicone", 1.2e6, 0.48, 0.08, 200_000),
    "rubber": Material("rubber", 6.0e6, 0.49, 0.05, 200_000),
    "steel": Material("steel", 200e9, 0.30, 0.0, 200_000),
}


@dataclass(frozen=True)
class ObjectShape:
    """The face the object presses into the membrane: `hex` (flat hexagon, `size_mm` across flats,
    flat-punch contact) or `sphere` (rounded, radius `size_mm / 2`, Hertz contact)."""

    name: str  # label written to the manifest: hex, bolt8, sphere10, ...
    face: str  # "hex" or "sphere"
    size_mm: float  # across flats (hex) or diameter (sphere)
    length_mm: float  # object length along the squeeze (its compliance column)
    size_label: str


def parse_object(text: str) -> ObjectShape:
    """`hex`, `hex7` (or `hex:7`), `bolt12`, `sphere10` -> ObjectShape. Bolts are pressed by their hexagonal head."""
    text = text.strip()
    if text == "hex" or text.startswith("hex:"):
        try:
            size = float(text.split(":", 1)[1]) if ":" in text else 6.5
        except ValueError:
            size = -1.0
        if 0 < size < math.inf:
            return ObjectShape("hex", "hex", size, 35.5, "7.5x6.5x35.5" if ":" not in text else f"{size:g}")
    for prefix, face, length in (("bolt", "hex", 30.0), ("sphere", "sphere", 0.0), ("hex", "hex", 35.5)):
        if text.startswith(prefix):
            try:
                size = float(text[len(prefix):])
            except ValueError:
                break
            if not 0 < size < math.inf:  # NaN and infinity pass `size <= 0` and fail deep in the contact model
                break
            return ObjectShape(text, face, size, length or size, f"{size:g}")
    raise UsageError(f"unknown object {text!r} (use hex, hexSIZE_MM, boltSIZE_MM such as bolt12, or sphereDIAMETER_MM)")


@dataclass(frozen=True)
class SimConfig:
    # ------------------------------------------------------------ the experiment design
    preset: str = "ch4"
    # trial groups: "material:object:count[:label=value...]" entries
    groups: tuple = ()
    force_min_n: float = 1.8  # peak force of a grasp is drawn uniformly in [force_min_n, force_max_n]
    force_max_n: float = 3.12
    contact_delay_us: tuple = (8_000, 25_000)  # LED-off to first touch, uniform range
    grasp_us: int = 120_000  # LED-off to the end of loading (the grasping phase)
    hold_us: int = 190_000  # holding phase
    release_us: int = 60_000  # releasing phase: the gripper opens
    tail_us: int = 20_000  # recording after the releasing phase
    max_duration_us: int = 0  # longest recording from LED-off (0 = no limit): the hold is shortened to fit
    duration_jitter: float = 0.08  # grasp-to-grasp spread of the phase durations (relative s.d.)
    gripper_speed_mm_s: float = 150.0  # closing speed once in contact
    servo_settle_us: int = 30_000  # the shortest loading or unloading ramp of the servo
    force_sensor: str = "nano17"  # nano17 | flexiforce
    force_period_us: int = 2_000  # 500 Hz force log
    force_lag_us: int = 0  # 0 = the sensor's own default (nano17 1 ms, flexiforce 25 ms)
    force_noise_n: float = -1.0  # < 0 = the sensor's own default
    # ------------------------------------------------------------ contact mechanics
    membrane_youngs_pa: float = 0.5e6  # soft transparent silicone membrane (thesis ch. 3: 4.0 x 2.0 x 0.2 cm)
    membrane_confinement: float = 3.0  # stiffening of a thin bonded, nearly incompressible layer
    membrane_poisson: float = 0.48
    membrane_thickness_mm: float = 2.0
    saturation_force_n: float = 4.0  # membrane compaction: effective force F / (1 + (F / Fs)^n)^(1/n)
    saturation_sharpness: float = 4.0  # n: how abruptly the membrane stops deforming
    creep: float = 0.15  # share of the membrane's deformation that follows with a delay (creep)
    creep_us: int = 120_000  # creep time constant
    tilt_deg: float = 0.15  # s.d. of the misalignment of the object face to the membrane
    edge_factor_max: float = 2.5  # flat-punch edge pressure concentration, capped by edge rounding
    pressure_scale_pa: float = 25e3  # pressure at which the membrane darkens to 63% of the object's contrast
    # ------------------------------------------------------------ optics
    pixel_pitch_mm: float = 0.2  # 0.04 mm^2 per pixel on the membrane (thesis 3.6)
    sensor_width: int = 240
    sensor_height: int = 180
    object_contrast: float = 0.85  # a black object on the lit membrane: 1 - I_contact / I_membrane (below 0: a bright object, contact brightens)
    vignetting: float = 0.3  # brightness lost at the corners
    texture: float = 0.03  # fixed-pattern brightness variation of the membrane (relative s.d.)
    dark_level: float = 0.01  # dark current, relative to the lit membrane
    position_jitter_px: float = 6.0  # s.d. of where the object lands on the membrane
    settle_px: float = 0.6  # rigid motion of the object when it settles after loading (px)
    settle_hz: float = 25.0
    settle_us: int = 40_000
    vibration_px: float = 0.12  # rigid vibration during the hold (px)
    vibration_hz: float = 30.0
    force_vibration: float = 0.02  # force ripple during the hold, share of the peak force
    drift_px: float = 0.3  # slow drift of the object during the hold (px)
    # ------------------------------------------------------------ LED
    led_gain: float = 1.0  # LED on: the field brightens by this share
    led_box: tuple = ()  # X,Y,W,H of the part of the field the LED lights (empty: the whole field)
    led_on_us: tuple = (15_000, 25_000)  # LED on-time, uniform range
    preroll_us: tuple = (30_000, 80_000)  # recording before LED-on, uniform range
    camera_offset_us: tuple = (2_000_000, 60_000_000)  # camera clock at the first recorded instant
    # ------------------------------------------------------------ pixels (DVS)
    on_threshold: float = 0.30  # log-intensity contrast threshold, ON
    off_threshold: float = 0.22  # OFF (lower: ON noise is suppressed by a higher ON threshold, thesis 3.3)
    threshold_mismatch: float = 0.03  # per-pixel relative s.d. of the thresholds
    refractory_us: int = 300
    cutoff_hz: float = 400.0  # photoreceptor bandwidth at the lit membrane (scales with intensity)
    background_rate_hz: float = 0.1  # background activity per pixel
    background_on_share: float = 0.8  # most background events are ON (leak)
    hot_pixels: int = 3
    hot_rate_hz: float = 40.0
    step_us: int = 250  # simulation step; events are timed to the µs inside it
    still_us: int = 2_000_000  # length of the still-scene (noise only) recording
    # ------------------------------------------------------------ gripper control
    gripper: str = "position"  # position: the squeeze relaxes with the material; force: the grip holds its force
    # ------------------------------------------------------------ sessions (simulate --session)
    session_rest_us: tuple = (300_000, 3_000_000)  # rest before each grasp, uniform range
    session_hold_us: tuple = (500_000, 6_000_000)  # holding time of a grasp, uniform range
    session_speed: tuple = (0.3, 3.0)  # gripper speed factor of a grasp, log-uniform range
    regrasp_share: float = 0.2  # share of grasps that loosen and tighten again while held
    change_share: float = 0.3  # share of grasps whose force changes while held
    partial_share: float = 0.2  # share of grasps released partly before the final release
    slip_share: float = 0.3  # share of grasps in which the object slips
    bright_share: float = 0.0  # share of grasps whose object is brighter than the membrane (a white or polished face) ...
    bright_contrast: float = -1.5  # ... its object_contrast: the contact brightens, a press makes ON events
    slip_speed_mm_s: tuple = (5.0, 40.0)  # speed of the contact patch along the membrane during a slip
    slip_us: tuple = (50_000, 300_000)  # length of a slip
    slip_force_drop: tuple = (0.0, 0.5)  # share of the normal force lost during a slip
    illumination_drift: float = 0.0  # slow drift of the lighting: relative amplitude (0.05 = +-5%)
    illumination_period_us: int = 60_000_000  # period of that drift
    force_drift_n_per_min: float = 0.0  # the force log's zero drifting over the session (a strain gauge warming), N a minute


# Parameters a run of trials alone reads (a trial's own timing, the still recording): set for sessions,
# they would change nothing (the same bytes, measured).
TRIAL_PARAMETERS = ("tail_us", "contact_delay_us", "max_duration_us", "grasp_us", "duration_jitter", "still_us")

# Parameters only a session simulation reads (`simulate --session`): set for trials, they would change nothing.
SESSION_PARAMETERS = ("session_rest_us", "session_hold_us", "session_speed", "regrasp_share", "change_share", "partial_share",
                      "slip_share", "bright_share", "bright_contrast", "slip_speed_mm_s", "slip_us", "slip_force_drop",
                      "illumination_drift", "illumination_period_us", "force_drift_n_per_min")


def _groups(*entries):
    return tuple(entries)


PRESETS = {
    # Thesis 3.6: 48 grasps of hexagonal prisms (0.75 x 0.65 x 3.55 cm) of four materials, 0-3.7 N,
    # hold 700 ms, FlexiForce A201, 144 frames of 7 ms: grasping 1-22, holding 23-122, releasing 123-144.
    "ch3": dict(
        groups=_groups("foam:hex:11", "rubber:hex:9", "silicone:hex:14", "steel:hex:14"),
        force_min_n=0.8, force_max_n=3.7, contact_delay_us=(5_000, 20_000), grasp_us=154_000,
        hold_us=700_000, release_us=154_000, tail_us=0, duration_jitter=0.0, max_duration_us=1_008_000,
        force_sensor="flexiforce", saturation_force_n=4.5, pressure_scale_pa=50e3, servo_settle_us=30_000, gripper_speed_mm_s=40.0,
    ),
    # Thesis 4.5: 35 grasps of steel bolts of 8, 12 and 16 mm, up to 3.12 N, at most 410 ms, Nano17.
    "ch4": dict(
        groups=_groups("steel:bolt8:12", "steel:bolt12:12", "steel:bolt16:11"),
        force_min_n=1.6, force_max_n=3.12, grasp_us=110_000, hold_us=180_000, release_us=60_000,
        tail_us=15_000, duration_jitter=0.08, max_duration_us=410_000, force_sensor="nano17", saturation_force_n=4.5,
    ),
    # Thesis 5.4: 60 grasps of bolts of 12, 15, 18 mm (20 each), 0-25 N, at most 360 ms, two gripper
    # settings, a thicker membrane (8 mm, shore 50A), Nano17; frames: first 5 / 6-30 / last 5 of 36.
    "ch5": dict(
        groups=_groups(
            "steel:bolt12:10:gripper_force=low", "steel:bolt12:10:gripper_force=high",
            "steel:bolt15:10:gripper_force=low", "steel:bolt15:10:gripper_force=high",
            "steel:bolt18:10:gripper_force=low", "steel:bolt18:10:gripper_force=high",
        ),
        force_min_n=8.0, force_max_n=25.0, contact_delay_us=(3_000, 10_000), grasp_us=50_000,
        hold_us=250_000, release_us=50_000, tail_us=5_000, duration_jitter=0.04, max_duration_us=360_000,
        force_sensor="nano17", membrane_youngs_pa=2.4e6, membrane_thickness_mm=8.0,
        saturation_force_n=30.0, pressure_scale_pa=120e3, servo_settle_us=25_000,
        gripper_speed_mm_s=250.0,
    ),
}

# ch5's two gripper settings: the share of [force_min_n, force_max_n] each one's peak force falls in.
GRIPPER_FORCE_BANDS = {"low": (0.0, 0.4), "high": (0.6, 1.0)}


def field_names() -> list[str]:
    return [f.name for f in dataclasses.fields(SimConfig)]


def preset_config(name: str, **overrides) -> SimConfig:
    if name not in PRESETS:
        raise UsageError(f"unknown preset {name!r} (choose one of {', '.join(PRESETS)})")
    values = dict(PRESETS[name], preset=name)
    overrides = {k: v for k, v in overrides.items() if v is not None}
    if "max_duration_us" not in overrides and {"grasp_us", "hold_us", "release_us", "tail_us"} & set(overrides):
        values["max_duration_us"] = 0  # phases set by hand are kept as given, not cut to the preset's longest trial
    values.update(overrides)
    unknown = set(values) - set(field_names())
    if unknown:
        raise UsageError(f"unknown simulator parameter(s) {', '.join(sorted(unknown))} (see docs/simulator.md for the list)")
    config = SimConfig(**values)
    validate(config)
    return config


def parse_value(name: str, text: str):
    """A `--set NAME=VALUE` value, typed by the field it sets: durations for *_us, ranges as A..B."""
    from neurotac_cli.units import parse_duration_us

    fields = {f.name: f for f in dataclasses.fields(SimConfig)}
    if name not in fields:
        raise UsageError(f"unknown simulator parameter {name!r} (see docs/simulator.md for the list)")
    default = fields[name].default
    if name == "led_box":
        try:
            box = tuple(int(part) for part in str(text).split(",") if part.strip())
        except ValueError:
            box = (0,)
        if len(box) not in (0, 4) or any(v < 0 for v in box):
            raise UsageError(f"led_box={text!r}: write X,Y,W,H in pixels, e.g. led_box=0,0,40,180")
        return box
    if isinstance(default, tuple) and name != "groups":
        parts = str(text).split("..")
        if len(parts) != 2:
            raise UsageError(f"{name} is a range: write LOW..HIGH, e.g. {name}=10ms..20ms")
        return tuple(_scalar(name, part, default[0], parse_duration_us) for part in parts)
    if name == "groups":
        return tuple(part for part in str(text).split(",") if part)
    return _scalar(name, text, default, parse_duration_us)


def _scalar(name, text, default, parse_duration_us):
    text = str(text).strip()
    if name.endswith("_us"):
        try:
            return parse_duration_us(text)
        except NeurotacError as error:
            raise UsageError(f"{name}: {error}") from None
    if isinstance(default, str):
        return text
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"{name}={text!r} is not a number") from None
    return int(value) if isinstance(default, int) and value.is_integer() else value


SESSION_SPEED_FLOOR = 0.01  # a hundred times slower than the gripper's speed: loading takes seconds
SESSION_REST_FLOOR_US = 50_000  # sim.session: LEAD_US + SETTLE_US + 10 ms between two grasps

# Each number's bounds: (lowest, highest, lowest excluded, highest excluded). Past them a simulation
# fails deep in numpy (a negative dark level's log), runs for hours (a threshold of 1e9 or 1e-6: the
# LED blink crosses it billions of times) or simulates what no camera records (a negative duration).
_POSITIVE, _NOT_NEGATIVE = (0.0, math.inf, True, False), (0.0, math.inf, False, False)
_SHARE, _BELOW_ONE = (0.0, 1.0, False, False), (0.0, 1.0, False, True)
BOUNDS = {
    **dict.fromkeys(("pixel_pitch_mm", "membrane_youngs_pa", "membrane_thickness_mm", "saturation_force_n",
                     "saturation_sharpness", "pressure_scale_pa", "membrane_confinement", "cutoff_hz", "gripper_speed_mm_s",
                     "step_us", "force_period_us", "grasp_us", "illumination_period_us"), _POSITIVE),
    **dict.fromkeys(("hot_rate_hz", "led_gain", "refractory_us", "hold_us", "release_us", "tail_us",
                     "hot_pixels", "creep_us", "servo_settle_us", "settle_us", "still_us", "force_lag_us", "max_duration_us",
                     "duration_jitter", "texture", "dark_level", "position_jitter_px", "settle_px", "vibration_px",
                     "drift_px", "tilt_deg", "force_vibration", "edge_factor_max", "settle_hz", "vibration_hz"), _NOT_NEGATIVE),
    **dict.fromkeys(("regrasp_share", "change_share", "partial_share", "slip_share", "background_on_share", "bright_share"), _SHARE),
    **dict.fromkeys(("creep", "vignetting", "threshold_mismatch", "illumination_drift"), _BELOW_ONE),
    "on_threshold": (1e-3, 10.0, False, False), "off_threshold": (1e-3, 10.0, False, False),
    "background_rate_hz": (0.0, 50.0, False, False),
    "force_drift_n_per_min": (-60.0, 60.0, False, False),
    "object_contrast": (-4.0, 1.0, False, True), "bright_contrast": (-4.0, 0.0, False, True), "membrane_poisson": (0.0, 0.5, False, False),
}
WHY = {"background_rate_hz": "per pixel; DVS pixels leak at 0.01-10 Hz, and each Hz is 43,200 events a second on "
       "a DAVIS240C, held in memory: 200 Hz took 1.4 GB for one grasp", "on_threshold": "a log-intensity contrast; DVS pixels have 0.1-0.5", "off_threshold": "a log-intensity contrast; DVS "
       "pixels have 0.1-0.5", "object_contrast": "at 0 the camera cannot see the object; below 0 the object is brighter than the membrane", "membrane_poisson": "0.5: incompressible"}
RANGES = ("session_rest_us", "session_hold_us", "session_speed", "slip_speed_mm_s", "slip_us", "slip_force_drop",
          "contact_delay_us", "led_on_us", "preroll_us", "camera_offset_us")


def parse_groups(groups) -> list[tuple]:
    """"material:object:count[:label=value...]" -> (material, ObjectShape, count, labels)."""
    parsed = []
    for text in groups:
        parts = str(text).split(":")
        if len(parts) < 3:
            raise UsageError(f"cannot read trial group {text!r} (write MATERIAL:OBJECT:COUNT, e.g. steel:bolt12:10)")
        material, obj, count, *rest = parts
        if material not in MATERIALS:
            raise UsageError(f"unknown material {material!r} in {text!r} (use {', '.join(MATERIALS)})")
        try:
            count = int(count)
        except ValueError:
            raise UsageError(f"trial count {count!r} in {text!r} is not a whole number") from None
        if count < 0:
            raise UsageError(f"trial count {count} in {text!r} is negative (give 0 or more grasps)")
        labels = {}
        for item in rest:
            name, sep, value = item.partition("=")
            if not sep:
                raise UsageError(f"cannot read label {item!r} in {text!r} (write NAME=VALUE)")
            if name in labels:  # one value would be dropped without a word
                raise UsageError(f"label {name!r} given twice in {text!r} (give each label once)")
            labels[name] = value
        reserved = [name for name in labels if name in ("material", "object", "size_mm")]
        if reserved:
            raise UsageError(f"label {reserved[0]!r} in {text!r} is set by the simulator from the group itself")
        try:
            check_label_names(labels)
        except SchemaError as error:  # an option given wrong, like the reserved names above
            raise UsageError(f"in {text!r}: {error}") from None
        parsed.append((material, parse_object(obj), count, labels))
    if not parsed:
        raise UsageError("no trials to simulate (give --objects/--materials or a preset)")
    return parsed


WHOLE = ("sensor_width", "sensor_height", "hot_pixels")  # counts of pixels: sizes of arrays


def _type_problems(config: SimConfig) -> list[str]:
    """Each setting of its default's type: the library passes Python values as given, and a string
    threshold or a fractional sensor width failed deep in numpy with a TypeError."""
    import numbers

    problems = []
    number = lambda v: isinstance(v, numbers.Real) and not isinstance(v, bool)  # noqa: E731
    for item in dataclasses.fields(config):
        value = getattr(config, item.name)
        like = item.default if item.default is not dataclasses.MISSING else item.default_factory()
        if isinstance(like, str):
            kind, fits = "a string", isinstance(value, str)
        elif item.name == "groups":
            kind, fits = "a tuple of object groups (strings)", isinstance(value, tuple) and all(isinstance(v, str) for v in value)
        elif isinstance(like, tuple):
            kind = f"a tuple of {len(like) or 4} numbers"
            fits = isinstance(value, tuple) and len(value) in ({len(like)} if like else {0, 4}) and all(map(number, value))
        elif item.name in WHOLE:
            kind, fits = "a whole number", isinstance(value, numbers.Integral) and not isinstance(value, bool)
        else:  # durations in µs may fall between two (drawn physics scales them)
            kind, fits = "a number", number(value)
        if not fits:
            problems.append(f"{item.name} must be {kind}, got {value!r}")
    return problems


def validate(config: SimConfig):
    problems = _type_problems(config)
    if problems:
        raise UsageError("bad simulator parameters: " + "; ".join(problems))
    for item in dataclasses.fields(config):  # NaN passes every comparison below unnoticed
        values = getattr(config, item.name)
        for value in values if isinstance(values, tuple) else (values,):
            if isinstance(value, float) and not math.isfinite(value):
                problems.append(f"{item.name} must be a finite number, got {value}")
    if problems:
        raise UsageError("bad simulator parameters: " + "; ".join(problems))
    parse_groups(config.groups)  # a malformed --objects is refused before any folder is made or grasp simulated
    if config.gripper not in ("position", "force"):
        problems.append(f"gripper={config.gripper!r} (use position or force)")
    if config.force_sensor not in ("nano17", "flexiforce"):
        problems.append(f"force_sensor={config.force_sensor!r} (use nano17 or flexiforce)")
    problems += [_out_of_bounds(name, getattr(config, name), *bounds) for name, bounds in BOUNDS.items()]
    if config.object_contrast == 0:
        problems.append(f"object_contrast must not be 0 ({WHY['object_contrast']})")
    for name in RANGES:
        low, high = getattr(config, name)
        if not 0 <= low <= high:
            problems.append(f"{name} must be a range LOW..HIGH with 0 <= LOW <= HIGH")
        elif name == "session_speed" and low < SESSION_SPEED_FLOOR:  # a grasp's loading takes travel / speed
            problems.append(f"session_speed must start at {SESSION_SPEED_FLOOR:g} or more (slower, one grasp's loading "
                            f"lasts minutes to years and its signals fill the memory), got {low:g}")
    if config.session_rest_us[0] < SESSION_REST_FLOOR_US:
        problems.append(f"session_rest_us must start at {SESSION_REST_FLOOR_US // 1000} ms or more (a grasp's approach "
                        "and the settling of the one before take that long)")
    if not 0 <= config.force_min_n <= config.force_max_n or config.force_max_n <= 0:
        problems.append("force range (need 0 <= force_min_n <= force_max_n, force_max_n > 0)")
    elif config.force_max_n > RANGE_N:  # the logs would read to `sync` as written in another unit
        problems.append(f"force_max_n must be at most {RANGE_N:g} N (the largest range of the rig's force sensors; the presets "
                        f"go up to 25 N), got {config.force_max_n:g}")
    problems += _placement_problems(config)
    problems = [problem for problem in problems if problem]
    if problems:
        raise UsageError("bad simulator parameters: " + "; ".join(problems))


def _out_of_bounds(name: str, value, low: float, high: float, low_open: bool, high_open: bool) -> str:
    """A setting's problem with its bounds ("" where it has none)."""
    if low < value < high or (value == low and not low_open) or (value == high and not high_open):
        return ""
    if high == math.inf:
        bound = f"{'>' if low_open else '>='} {low:g}"
    else:
        bound = f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
    return f"{name} must be {bound}" + (f" ({WHY[name]})" if name in WHY else "") + f", got {value:g}"


def _placement_problems(config: SimConfig) -> list[str]:
    """The sensor's size, and where objects and the LED land on it."""
    problems = []
    if config.sensor_width > 1023 or config.sensor_height > 511 or min(config.sensor_width, config.sensor_height) < 16:
        problems.append("sensor size (AEDAT 2.0 DAVIS addresses hold 16..1023 x 16..511)")
    view_mm = max(config.sensor_width, config.sensor_height) * config.pixel_pitch_mm
    wide = [obj.name for _, obj, count, _ in parse_groups(config.groups) if count and obj.size_mm > view_mm]
    if wide:  # its face would cover the whole picture, and its contact model grows with its area (minutes, gigabytes)
        problems.append(f"object {wide[0]} is wider than the camera's view of the membrane ({view_mm:g} mm: "
                        f"{max(config.sensor_width, config.sensor_height)} px of pixel_pitch_mm {config.pixel_pitch_mm:g})")
    if config.position_jitter_px > max(config.sensor_width, config.sensor_height):
        problems.append("position_jitter_px at most the sensor's larger side (most objects would land off it)")
    if config.led_box:
        x, y, width, height = config.led_box
        if width <= 0 or height <= 0 or not (0 <= x < config.sensor_width and 0 <= y < config.sensor_height):
            problems.append(f"led_box {x},{y},{width},{height}: a box of positive size that begins inside the "
                            f"{config.sensor_width}x{config.sensor_height} sensor (the LED would light no pixel)")
    return problems
