"""A beam model of the actuator's walls with a helical strain-limit strip under a uniform axial
eigenstrain of the membrane, written apart from the simulator (docs/chambers.md, "A helical
strip"): the independent computation the helical strip's elastic check compares with.

The strip is the sleeve of thickness h round the membrane's box cut by the band {x' <= 0,
|y'| <= b / (2 cos a)} of the frame turned by phi(z) = turn (-z) / L about the axis
(:func:`hydrojam.actuator.geometry.helix_twist_rad`): its sections turn at the rate
k = -turn / L per unit z. Each section is plane and turns rigidly (no warping, exact for a
square box), with generalised strains e = (eps, k1, k2, tau): axial strain eps + k1 x + k2 y,
twist rate tau, and in every wall the shear tau d along the wall, d = max(|x|, |y|) the
distance from the axis across the wall (thin-walled closed section: Bredt's shear of a square
box). The membrane carries uniaxial stress E (eps_zz - eps0) and shear G tau d. The strip is
narrow: it carries only stress along its own length (a fibre; its stress across its width and
its in-plane shear are released at its edges), whose direction on a wall is at beta to the axis,
tan beta = k rho^2 / d (the turning band's trace on the flat wall), so that its strain is
cos^2 beta (eps_zz + tan beta tau d) (the hoop strain's sin^2 beta term left out).

The free end is unloaded, so every section's resultants vanish: e solves the section's 4 x 4
stiffness system locally, and the free end's rotation is the integral of (k2, -k1, tau) from the
clamp. Section integrals on a grid of cells dx square, the length in nz slices.
"""

from __future__ import annotations

import math

import numpy as np

from hydrojam.actuator.geometry import helix_twist_rad


def _grid(half: float, dx: float) -> tuple[np.ndarray, np.ndarray]:
    g = np.arange(-half + dx / 2, half, dx)
    x, y = np.meshgrid(g, g, indexing="ij")
    return x.ravel(), y.ravel()


def strip_section(x: np.ndarray, y: np.ndarray, z: float, geometry: dict, helix_deg: float) -> np.ndarray:
    """Whether the points (x, y) of the section at z [mm] lie in the helical strip (``geometry``:
    cavity_width, cavity_depth, cavity_length, side_wall, end_wall, strain_limit, strip_width [mm])."""
    g = geometry
    x_out, y_out = g["cavity_width"] / 2 + g["side_wall"], g["cavity_depth"] / 2 + g["side_wall"]
    h, length = g["strain_limit"], g["cavity_length"] + 2 * g["end_wall"]
    turn = helix_twist_rad(x_out, h, length, helix_deg)
    phi = turn * (-z) / length
    xr, yr = math.cos(phi) * x + math.sin(phi) * y, -math.sin(phi) * x + math.cos(phi) * y
    box = (np.abs(x) <= x_out) & (np.abs(y) <= y_out)
    sleeve = (np.abs(x) <= x_out + h) & (np.abs(y) <= y_out + h) & ~box
    return sleeve & (xr <= 0) & (np.abs(yr) <= g["strip_width"] / (2 * math.cos(math.radians(helix_deg))))


def strip_volume(geometry: dict, helix_deg: float, dx: float = 0.02, nz: int = 400) -> float:
    """The helical strip's volume [mm^3], its sections' areas summed on the grid."""
    g = geometry
    half = max(g["cavity_width"], g["cavity_depth"]) / 2 + g["side_wall"] + g["strain_limit"]
    x, y = _grid(half, dx)
    length = g["cavity_length"] + 2 * g["end_wall"]
    zs = -(np.arange(nz) + 0.5) / nz * length
    return sum(strip_section(x, y, z, g, helix_deg).sum() for z in zs) * dx * dx * length / nz


def free_end_rotation(geometry: dict, helix_deg: float, shear_modulus: float, poisson_ratio: float,
                      strip_shear_modulus: float, eps0: float, dx: float = 0.05, nz: int = 200) -> np.ndarray:
    """The free end's small rotation vector (x, y, z) [rad] of the beam model, the membrane
    under the axial eigenstrain ``eps0`` [-], both elastomers' Young's moduli 2 G (1 + nu) [MPa]."""
    g = geometry
    x_out, y_out = g["cavity_width"] / 2 + g["side_wall"], g["cavity_depth"] / 2 + g["side_wall"]
    h, length = g["strain_limit"], g["cavity_length"] + 2 * g["end_wall"]
    k = -helix_twist_rad(x_out, h, length, helix_deg) / length
    E = 2 * shear_modulus * (1 + poisson_ratio)
    Es = 2 * strip_shear_modulus * (1 + poisson_ratio)
    x, y = _grid(max(x_out, y_out) + h, dx)
    dA = dx * dx
    d = np.maximum(np.abs(x), np.abs(y))
    box = (np.abs(x) <= x_out) & (np.abs(y) <= y_out)
    in_cavity = (np.abs(x) < g["cavity_width"] / 2) & (np.abs(y) < g["cavity_depth"] / 2)
    rate = np.zeros(3)
    for z in -(np.arange(nz) + 0.5) / nz * length:
        cavity = -g["end_wall"] - g["cavity_length"] < z < -g["end_wall"]
        mem = box & ~(in_cavity & cavity)
        strip = strip_section(x, y, z, g, helix_deg)
        P = np.stack([np.ones(mem.sum()), x[mem], y[mem]])
        K = np.zeros((4, 4))
        K[:3, :3] = E * P @ P.T * dA
        K[3, 3] = shear_modulus * (d[mem] ** 2).sum() * dA
        f = np.zeros(4)
        f[:3] = E * eps0 * P.sum(axis=1) * dA
        ds = d[strip]
        tan_b = k * (x[strip] ** 2 + y[strip] ** 2) / ds
        cos2 = 1.0 / (1.0 + tan_b ** 2)
        Q = cos2 * np.stack([np.ones(strip.sum()), x[strip], y[strip], tan_b * ds])
        K += Es * Q @ Q.T * dA
        e = np.linalg.solve(K, f)
        rate += np.array([e[2], -e[1], e[3]])
    return -rate * length / nz  # from the clamp z = 0 to the free end z = -L
