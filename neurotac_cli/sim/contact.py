"""Contact mechanics of an object pressed into the silicone membrane.

Rounded faces follow Hertz: a = (3 F R / 4 E*)^(1/3), p(r) = p0 sqrt(1 - r^2/a^2), p0 = 3F / (2 pi a^2).
Flat faces (the thesis's hexagonal prisms, bolt heads) follow a flat punch on a thin layer: the
membrane (thickness h, modulus E_m) in series with the object (length L, modulus E_o) acts as an
elastic foundation of stiffness k = 1 / (h / E_m' + L / E_o') per unit area, the face meets the
membrane with a small tilt, so contact spreads from one edge as the approach delta grows, and the
pressure concentrates towards the rim as in Boussinesq's rigid punch, p ~ 1 / (2 sqrt(1 - rho^2)),
capped where the rim is rounded. Visibility of the contact (how dark a pixel gets) saturates with
pressure: s = 1 - exp(-p / p_s).
"""

import numpy as np

SQRT3_2 = np.sqrt(3.0) / 2.0


def effective_modulus(e1: float, nu1: float, e2: float, nu2: float) -> float:
    """Hertz's contact modulus E*: 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2 (Pa)."""
    return 1.0 / ((1.0 - nu1**2) / e1 + (1.0 - nu2**2) / e2)


def hertz_radius_m(force_n, radius_m: float, e_star: float):
    """Contact radius (m) of a sphere of radius R pressed with force F: a = (3 F R / 4 E*)^(1/3)."""
    force = np.clip(np.asarray(force_n, dtype=float), 0.0, None)
    return np.cbrt(3.0 * force * radius_m / (4.0 * e_star))


def hertz_peak_pressure(force_n, radius_m: float, e_star: float):
    """p0 = 3 F / (2 pi a^2) (Pa); zero where there is no force."""
    force = np.clip(np.asarray(force_n, dtype=float), 0.0, None)
    a = hertz_radius_m(force, radius_m, e_star)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(a > 0, 3.0 * force / (2.0 * np.pi * np.maximum(a, 1e-30) ** 2), 0.0)


def foundation_stiffness(config, material, length_mm: float) -> float:
    """Stiffness per unit area (Pa/m) of the membrane layer in series with the object column.

    A thin bonded layer of nearly incompressible silicone is stiffer than its Young's modulus says
    (it can only bulge at the free rim of the contact): its modulus is scaled by
    `membrane_confinement` (about 3 for a face 2-5 times wider than the layer is thick). The object is
    a free column of its length, compressed at its own Young's modulus.
    """
    compliance = (config.membrane_thickness_mm * 1e-3) / (config.membrane_youngs_pa * config.membrane_confinement)
    compliance += (length_mm * 1e-3) / material.youngs_pa
    return 1.0 / compliance


def hex_norm(u, v, apothem):
    """max over the hexagon's three edge normals of |r . n| / apothem: 1 on the rim, < 1 inside."""
    return np.maximum(np.abs(v), np.maximum(np.abs(SQRT3_2 * u + 0.5 * v), np.abs(SQRT3_2 * u - 0.5 * v))) / apothem


def edge_factor(rho, cap: float):
    """Boussinesq's rigid-punch rim concentration 1 / (2 sqrt(1 - rho^2)), capped by the rounded rim."""
    inside = np.clip(1.0 - np.asarray(rho) ** 2, 1e-6, None)
    return np.minimum(0.5 / np.sqrt(inside), cap)


def flat_pressure(u_mm, v_mm, apothem_mm, tilt, tilt_dir, approach_m, stiffness, cap, pitch_mm):
    """Pressure (Pa) and rim coverage (0..1) of a tilted flat hexagonal face.

    u, v: position relative to the face centre (mm); tilt (rad) along the unit vector tilt_dir (2,);
    approach_m: how far the highest point of the face has pressed in (m). Arrays broadcast.
    """
    rho = hex_norm(u_mm, v_mm, apothem_mm)
    coverage = np.clip(0.5 + (1.0 - rho) * apothem_mm / pitch_mm, 0.0, 1.0)
    # Height of the face above its first-touching corner, in m: the gap the membrane must close.
    corner = apothem_mm / SQRT3_2
    gap = tilt * ((u_mm * tilt_dir[0] + v_mm * tilt_dir[1]) + corner) * 1e-3
    pressure = stiffness * np.clip(approach_m - gap, 0.0, None) * edge_factor(np.minimum(rho, 1.0), cap)
    return pressure, coverage


def flat_force_table(apothem_mm, tilt, tilt_dir, stiffness, cap, pitch_mm, levels=160):
    """Approach (m) -> total force (N) of a flat face, on a grid fine enough to invert by interpolation."""
    corner = apothem_mm / SQRT3_2
    half = int(np.ceil(corner / pitch_mm)) + 2
    grid = (np.arange(-half, half + 1) * pitch_mm)
    u, v = np.meshgrid(grid, grid)
    area = (pitch_mm * 1e-3) ** 2
    # Enough approach to press the whole face in with the largest pressures the presets reach.
    full = tilt * 2 * corner * 1e-3
    top = full + 60.0 / (stiffness * max(area * u.size * 0.3, 1e-12))
    approaches = np.concatenate([[0.0], np.geomspace(top * 1e-5, top, levels - 1)])
    forces = np.empty(levels)
    for index, approach in enumerate(approaches):  # one vectorised map per level, not per pixel
        pressure, coverage = flat_pressure(u, v, apothem_mm, tilt, tilt_dir, approach, stiffness, cap, pitch_mm)
        forces[index] = float((pressure * coverage).sum() * area)
    return approaches, np.maximum.accumulate(forces)
