"""The undeformed-state check shared by the 2D and 3D simulation tests (docs/model.md, "Reference state")."""

import math

import numpy as np

from hydrojam.fem.solver.newton import NewtonOptions


def assert_nothing_moved(model, res) -> float:
    """At the as-prepared stimulus (mu0, T0) nothing drives a step; should round-off of the
    stress-free residual ever trigger one, it stops at the residual floor: displacements of order
    floor x the particle size (a stiffness of G d^(dim-2) against forces of floor x G d^(dim-1)).
    Asserts a factor of 100 above that on every node, the tip and the angle, and no contact;
    returns that bound [mm]."""
    assert res.converged
    drift = 100 * NewtonOptions().residual_floor * model.design.particle_diameter
    assert np.abs(res.final.x - model.mesh.points).max() < drift
    m = res.metrics
    assert abs(m["bending_angle_deg"]) < math.degrees(2 * drift / model.design.width)
    assert abs(m["tip_dx_mm"]) < drift and abs(m["tip_dz_mm"]) < drift
    assert m["contacts_per_particle"] == 0
    return drift
