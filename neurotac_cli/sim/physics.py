"""Domain randomisation: the simulator's physics drawn from wide ranges, one parameter family at a time.

A family groups the parameters of one part of the sensor (pixels, membrane, optics, noise, force
sensor, objects). Each parameter is drawn uniformly in its drawing scale (linear or log) between LOW
and HIGH, as an absolute value or as a factor on the preset's own value (so a thicker, stiffer ch5
membrane is varied around itself). A family can be held out: training data draws it from the lower
two thirds of each of its parameters' ranges only (`seen`), test data from the upper third only
(`unseen`), so a model can be scored on physics that training never saw.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np

from neurotac_cli.errors import NeurotacError, UsageError
from neurotac_cli.sim.force_sensor import DEFAULT_NOISE_N, sensor_lag_us

SEEN_SHARE = 2 / 3  # the seen part of a held-out range: its lower two thirds in the drawing scale


@dataclass(frozen=True)
class Range:
    low: float
    high: float
    log: bool = False  # drawn uniformly in log scale
    factor: bool = False  # a factor on the preset's value, not the value itself
    integer: bool = False


FAMILIES = {
    "pixels": {
        "on_threshold": Range(0.15, 0.5),
        "off_threshold": Range(0.12, 0.4),
        "threshold_mismatch": Range(0.01, 0.08),
        "refractory_us": Range(50, 1_000, log=True, integer=True),
        "cutoff_hz": Range(0.4, 4.0, log=True, factor=True),
    },
    "membrane": {
        "membrane_youngs_pa": Range(0.4, 2.5, log=True, factor=True),
        "membrane_thickness_mm": Range(0.5, 2.0, log=True, factor=True),
        "membrane_confinement": Range(2.0, 5.0),
        "saturation_force_n": Range(0.6, 1.6, log=True, factor=True),
        "creep": Range(0.0, 0.35),
        "creep_us": Range(0.33, 3.0, log=True, factor=True),
        "pressure_scale_pa": Range(0.5, 2.0, log=True, factor=True),
    },
    "optics": {
        "object_contrast": Range(0.5, 0.95),
        "vignetting": Range(0.0, 0.5),
        "texture": Range(0.0, 0.08),
        "dark_level": Range(0.002, 0.05, log=True),
        "pixel_pitch_mm": Range(0.75, 1.33, log=True, factor=True),
        "led_gain": Range(0.5, 1.5),
    },
    "noise": {
        "background_rate_hz": Range(0.02, 1.0, log=True),
        "background_on_share": Range(0.5, 0.95),
        "hot_pixels": Range(0, 20, integer=True),
        "hot_rate_hz": Range(5.0, 200.0, log=True),
    },
    "sensor": {
        "force_lag_us": Range(0.3, 4.0, log=True, factor=True, integer=True),
        "force_noise_n": Range(0.3, 3.0, log=True, factor=True),
    },
    "objects": {
        "tilt_deg": Range(0.0, 0.6),
        "edge_factor_max": Range(1.5, 4.0),
        "position_jitter_px": Range(2.0, 15.0),
        "settle_px": Range(0.1, 1.5),
        "vibration_px": Range(0.02, 0.4, log=True),
        "drift_px": Range(0.0, 1.0),
        "force_vibration": Range(0.0, 0.05),
    },
}


@dataclass(frozen=True)
class Variation:
    """Which families to draw, and which one (if any) is held out: `seen` for training, `unseen` for testing."""

    families: tuple = ()
    held_out: str | None = None
    side: str = "seen"

    def __post_init__(self):
        unknown = [name for name in (*self.families, self.held_out) if name is not None and name not in FAMILIES]
        if unknown:
            raise NeurotacError(f"unknown parameter family {unknown[0]!r} (choose from {', '.join(FAMILIES)}, or all)")
        if self.side not in ("seen", "unseen"):
            raise NeurotacError(f"held-out side must be seen or unseen, got {self.side!r}")
        if self.held_out is not None and self.held_out not in self.families:
            raise NeurotacError(f"family {self.held_out!r} is held out but not varied (add it to --vary, or use --vary all)")

    def draw(self, config, rng: np.random.Generator):
        """A copy of `config` with every varied parameter drawn; returns (config, {name: value})."""
        from neurotac_cli.sim.config import validate

        values = {}
        for family in self.families:  # in FAMILIES order: the same seed draws the same physics
            part = (0.0, 1.0)
            if family == self.held_out:
                part = (0.0, SEEN_SHARE) if self.side == "seen" else (SEEN_SHARE, 1.0)
            for name, spec in FAMILIES[family].items():
                values[name] = _draw(spec, _base(config, name), rng.uniform(*part))
        varied = dataclasses.replace(config, **values)
        validate(varied)
        return varied, values


    def draw_family(self, config, rng: np.random.Generator, family: str):
        """(config, values) with only `family` drawn, if this variation varies it; else (config, {})."""
        if family not in self.families:
            return config, {}
        return Variation((family,), self.held_out if self.held_out == family else None, self.side).draw(config, rng)

    def replaces(self, names) -> list[tuple[str, str]]:
        """(name, family) of each of `names` that a draw of this variation sets outright (a parameter
        drawn as a factor is drawn about the value given, so it is not replaced)."""
        return [(name, family) for family in self.families for name, spec in FAMILIES[family].items()
                if name in names and not spec.factor]

    def without(self, family: str) -> "Variation":
        """The same variation, `family` left out."""
        return Variation(tuple(f for f in self.families if f != family), None if self.held_out == family else self.held_out, self.side)


def parse_variation(families: str | None, held_out: str | None = None, unseen: str | None = None) -> Variation | None:
    """`--vary pixels,membrane` (or `all`), `--hold-out FAMILY` (seen part only), `--unseen FAMILY` (unseen part only)."""
    if held_out and unseen:
        raise UsageError("give --hold-out (training data) or --unseen (test data), not both")
    names = [] if families is None else [part.strip() for part in families.split(",")]
    if "" in names:
        raise UsageError(f"--vary {families!r} has an empty family name (give families separated by commas, from "
                         f"{', '.join(FAMILIES)}, or all)")
    if names == ["all"]:
        names = list(FAMILIES)
    elif "all" in names:
        raise UsageError(f"--vary {families!r}: all names every family, so it stands alone (give all, or families)")
    family = held_out or unseen
    if family == "all":
        raise UsageError(f"--{'hold-out' if held_out else 'unseen'} takes one family, not all (choose from {', '.join(FAMILIES)})")
    unknown = [name for name in (*names, family) if name is not None and name not in FAMILIES]
    if unknown:
        raise UsageError(f"unknown parameter family {unknown[0]!r} (choose from {', '.join(FAMILIES)}, or all)")
    if family and family not in names:
        names.append(family)  # the held-out family is varied on its own side of the range
    if not names:
        return None
    order = [name for name in FAMILIES if name in names] + [name for name in names if name not in FAMILIES]
    return Variation(tuple(order), family, "unseen" if unseen else "seen")


def _base(config, name):
    if name == "force_lag_us":
        return sensor_lag_us(config)
    if name == "force_noise_n":
        return config.force_noise_n if config.force_noise_n >= 0 else DEFAULT_NOISE_N[config.force_sensor]
    return getattr(config, name)


def _draw(spec: Range, base, u: float):
    if spec.log:
        value = float(np.exp(np.log(spec.low) + u * (np.log(spec.high) - np.log(spec.low))))
    else:
        value = spec.low + u * (spec.high - spec.low)
    if spec.factor:
        value *= base
    return int(round(value)) if spec.integer else float(value)


def ranges_table() -> list[tuple[str, str, str]]:
    """(family, parameter, range) rows for the docs: factors are written `x0.4..x2.5`."""
    rows = []
    for family, specs in FAMILIES.items():
        for name, spec in specs.items():
            text = f"x{spec.low:g}..x{spec.high:g}" if spec.factor else f"{spec.low:g}..{spec.high:g}"
            rows.append((family, name, text + (" (log)" if spec.log else "")))
    return rows
