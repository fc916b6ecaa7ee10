"""Swelling kinetics of one gel particle: how fast its water content follows the stimulus.

A gel swells by the collective diffusion of its network in the solvent (Tanaka & Fillmore,
J. Chem. Phys. 70:1214, 1979). Linearised about a state, the volumetric swelling obeys a
diffusion equation with the gel's collective diffusion coefficient D: here for v = ln J (J the
volume ratio to the dry network), in a sphere (3D) or a long cylinder (2D plane strain),

    dv/dt = D (1/r^k) d/dr (r^k dv/dr),   k = 2 (sphere), 1 (cylinder),   0 <= r <= a,

with v(a, t) = the free-swelling equilibrium at the stimulus of time t (the surface is in
contact with the solvent) and dv/dr(0, t) = 0. The particle's state is the volume average
<v>(t). After a step, <v> approaches the new equilibrium as Tanaka & Fillmore's series
(sphere: 1 - (6/pi^2) sum_n n^-2 exp(-n^2 t / tau), tau = a^2 / (pi^2 D)); this module solves the
equation numerically instead (finite volumes in r; in time exactly, mode by mode, for a surface
value that changes linearly between the given times), so that any schedule - steps, ramps,
cycles - is followed, and the series verifies it (tests/materials/test_kinetics.py).

Units: lengths mm, time s, D mm^2/s. Which radius a, and what the shear modulus does to the time
scale (Li & Tanaka 1990), are discussed in docs/kinetics.md.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from scipy.linalg import eigh_tridiagonal

Shape = Literal["sphere", "cylinder"]

#: collective diffusion coefficient of PNIPAM gels in water [mm^2/s] (docs/kinetics.md)
DEFAULT_DIFFUSIVITY = 1.0e-4

_EXPONENT = {"sphere": 2, "cylinder": 1}


def time_constant(radius: float, diffusivity: float) -> float:
    """Tanaka & Fillmore's time constant tau = a^2 / (pi^2 D) of a sphere.

    Parameters
    ----------
    radius : float
        Radius a [mm].
    diffusivity : float
        Collective diffusion coefficient D [mm^2/s].

    Returns
    -------
    float
        tau [s].
    """
    return radius**2 / (np.pi**2 * diffusivity)


def _modes(radius: float, diffusivity: float, shape: Shape, cells: int):
    """Finite volumes on ``cells`` equal shells, dv/dt = L v + s v_surface with L = M^-1 K (M the
    shell volumes, K symmetric): the eigenpairs of the symmetric M^-1/2 K M^-1/2 and what the
    model needs to integrate each mode exactly. Returns (rates lambda <= 0 [1/s], Q, the source in
    modal coordinates, M^1/2, the volume weights of the mean)."""
    k = _EXPONENT[shape]
    edges = np.linspace(0.0, radius, cells + 1)
    dr = edges[1] - edges[0]
    volume = (edges[1:] ** (k + 1) - edges[:-1] ** (k + 1)) / (k + 1)  # per unit solid angle
    inner = diffusivity * edges[1:-1] ** k / dr  # conductance between neighbouring shells
    surface = diffusivity * edges[-1] ** k / (0.5 * dr)  # last shell's centre to the surface
    diag = np.zeros(cells)
    diag[:-1] -= inner
    diag[1:] -= inner
    diag[-1] -= surface
    root = np.sqrt(volume)
    rates, Q = eigh_tridiagonal(diag / volume, inner / (root[:-1] * root[1:]))
    source = np.zeros(cells)
    source[-1] = surface / root[-1]
    return rates, Q, Q.T @ source, root, volume / volume.sum()


def _phi(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """phi1 = (e^x - 1)/x and phi2 = (e^x - 1 - x)/x^2 for x <= 0, accurate near 0."""
    small = np.abs(x) < 1e-4
    xs = np.where(small, 1.0, x)
    phi1 = np.where(small, 1.0 + x / 2 + x * x / 6, np.expm1(xs) / xs)
    phi2 = np.where(small, 0.5 + x / 6 + x * x / 24, (np.expm1(xs) - xs) / (xs * xs))
    return phi1, phi2


def mean_log_swelling(
    times,
    surface,
    radius: float,
    diffusivity: float,
    shape: Shape = "sphere",
    initial: float | None = None,
    cells: int = 400,
) -> np.ndarray:
    """Volume-averaged ln J of a particle at a sequence of times.

    Exact in time for the given surface history (linear between the times); second order in the
    shell width a / ``cells``.

    Parameters
    ----------
    times : array_like, shape (m,)
        Strictly increasing times [s].
    surface : array_like, shape (m,)
        ln J at the surface at each time (the free-swelling equilibrium at the stimulus of that
        time) [-], changing linearly in between.
    radius : float
        Particle radius a [mm], > 0.
    diffusivity : float
        Collective diffusion coefficient D [mm^2/s], > 0.
    shape : {"sphere", "cylinder"}, optional
        A sphere (3D) or a long cylinder (2D plane strain).
    initial : float, optional
        Uniform ln J at ``times[0]`` [-] (default ``surface[0]``: in equilibrium; another value is a
        step at ``times[0]``).
    cells : int, optional
        Number of equal radial shells.

    Returns
    -------
    ndarray, shape (m,)
        The volume average <ln J> at each time [-] (J the volume ratio to the dry network).

    Raises
    ------
    ValueError
        If ``times`` is not strictly increasing, ``surface`` does not hold one finite value per
        time, ``radius`` or ``diffusivity`` is not positive, or ``shape`` is unknown.
    """
    times = np.asarray(times, dtype=float)
    surface = np.asarray(surface, dtype=float)
    if times.ndim != 1 or len(times) == 0 or np.any(np.diff(times) <= 0):
        raise ValueError("times must be a non-empty, strictly increasing 1D array [s]")
    if surface.shape != times.shape or not np.all(np.isfinite(surface)):
        raise ValueError("surface must hold one finite ln J per time")
    if not (radius > 0 and diffusivity > 0):
        raise ValueError(f"radius and diffusivity must be positive (got {radius}, {diffusivity})")
    if shape not in _EXPONENT:
        raise ValueError(f"shape must be 'sphere' or 'cylinder' (got {shape!r})")
    rates, Q, source, root, weights = _modes(radius, diffusivity, shape, cells)
    v0 = surface[0] if initial is None else float(initial)
    z = Q.T @ (root * v0)
    mean = (weights / root) @ Q  # <v> = mean . z
    out = [float(mean @ z)]
    for h, b0, b1 in zip(np.diff(times), surface[:-1], surface[1:]):
        x = rates * h
        phi1, phi2 = _phi(x)
        z = np.exp(x) * z + source * h * (b0 * phi1 + (b1 - b0) * phi2)
        out.append(float(mean @ z))
    return np.asarray(out)
