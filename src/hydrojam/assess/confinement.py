"""Does the wall hold the gel? (docs/assess.md): the contact pressure between the
particles and the membrane in a state, against the confined swelling pressure of the gel, the
pressure it would exert if held at its as-prepared size. Units: MPa, mm; forces N/mm per unit
depth in 2D, N in 3D."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hydrojam.actuator.model import ActuatorModel
from hydrojam.materials.energies import HydrogelParams, nominal_stresses


def confined_swelling_pressure(params: HydrogelParams, mu: float, T: float) -> float:
    """Pressure [MPa] a gel held at its as-prepared size (stretch lambda0 from the dry network
    in all three directions) exerts on what holds it at stimulus (mu [k_B T], T [K]): minus its
    Cauchy stress sigma = s(lambda0) / lambda0^2 x k_B T/nu, s the nominal stress of
    :func:`~hydrojam.materials.energies.nominal_stresses`. Zero at the as-prepared stimulus
    (mu0, T0); positive where the gel would swell, negative where it would shrink (it pulls).
    The same in plane strain: the out-of-plane stretch is held at lambda0 there too."""
    lam = params.lambda0
    s = nominal_stresses(params, [lam, lam, lam], mu, T)[0]
    return float(-params.kT_over_nu * s / lam**2)


@dataclass(frozen=True)
class ContactPressure:
    """Contact pressure on the cavity wall from the particles [MPa]: ``mean`` = the total
    contact force on the wall over the length (2D) or area (3D) in contact, ``maximum`` = the
    largest nodal pressure; ``contact_length`` [mm per unit depth in 2D; mm^2 in 3D],
    ``total_force`` [N/mm in 2D; N in 3D]; ``nodal`` (n,) [MPa]: each wall node's pressure (zero
    off the wall and out of contact), the surface field written to a VTU."""

    mean: float
    maximum: float
    contact_length: float
    total_force: float
    nodal: np.ndarray | None = None


def segment_pressure(segments: np.ndarray, x: np.ndarray, forces: np.ndarray, threshold: float = 1e-6) -> ContactPressure:
    """Contact pressure from nodal forces ``forces`` (n, d) [N/mm in 2D, N in 3D] on a wall made
    of straight ``segments`` (k, 2) in 2D or flat triangles (k, 3) in 3D (node indices) at
    positions x (n, d) [mm]: each node's force over its share of the wall, the current length
    (area) of the pieces next to it over their node count (the lumped, area-weighted traction of
    IPC's barrier on straight collision pieces). A node is in contact where |f_a| >
    ``threshold`` x the largest; mean = total force over the length (area) in contact."""
    x = np.asarray(x, dtype=float)
    segments = np.asarray(segments)
    a, b = x[segments[:, 0]], x[segments[:, 1]]
    if segments.shape[1] == 2:
        size = np.linalg.norm(b - a, axis=1)
    else:
        size = 0.5 * np.linalg.norm(np.cross(b - a, x[segments[:, 2]] - a), axis=1)
    k = segments.shape[1]
    share = np.bincount(segments.ravel(), weights=np.repeat(size / k, k), minlength=len(x))
    nodes = np.unique(segments)
    f = np.linalg.norm(np.asarray(forces, dtype=float)[nodes], axis=1)
    nodal = np.zeros(len(x))
    if not np.any(f > 0):
        return ContactPressure(0.0, 0.0, 0.0, 0.0, nodal)
    on = f > threshold * f.max()
    p = f[on] / share[nodes][on]
    nodal[nodes[on]] = p
    return ContactPressure(float(f[on].sum() / share[nodes][on].sum()), float(p.max()),
                           float(share[nodes][on].sum()), float(f[on].sum()), nodal)


def wall_contact_pressure(model: ActuatorModel, x: np.ndarray, threshold: float = 1e-6) -> ContactPressure:
    """Contact pressure the particles exert on the cavity wall at positions x (n, d) [mm]: the IPC
    barrier's forces on the wall's nodes (ipctk's gradient with area weighting: a nodal force is
    the traction integrated over the node's share of the wall; the quadratic edges (triangles)
    enter the collision mesh as two (four) straight pieces each) through :func:`segment_pressure`.
    Zero when nothing touches. In a 3D half model the mean and maximum are the whole wall's (by
    symmetry)."""
    return segment_pressure(model.cavity_segments, x, model.contact.between_components().nodal_forces(x), threshold)
