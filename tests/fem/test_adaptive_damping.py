"""Adaptive damping of the load path (hydrojam.fem.path, PathOptions.damping_growth): a step that
runs out of Newton iterations is retried, at the same increment, with the viscous stabilisation
raised, and easy steps lower it again. Checked on a one-DOF snap whose critical load is known."""

import math

import numpy as np
import pytest

from hydrojam.fem.solver import NewtonOptions, PathOptions, Problem, fixed, solve_path
from hydrojam.fem.terms import EnergyTerm, ViscousStabilisation

A, F = 1.0, 3.0  # the double well's depth [mJ] and the load at s = 1 [N]
S_CRITICAL = 8 * A / (3 * math.sqrt(3)) / F  # the left well vanishes here (E' has no root below 0)


class DoubleWell(EnergyTerm):
    """E = A (u^2 - 1)^2 - s F u for node 0's x displacement u from -1 (its reference): the
    left well (u = -1 at s = 0) disappears at s = S_CRITICAL and the state snaps to the right one."""

    name = "well"

    def __init__(self, s):
        self.s = s

    def energy(self, x):
        u = np.ravel(x)[0]
        return A * (u * u - 1) ** 2 - self.s * F * u

    def gradient(self, x):
        u = np.ravel(x)[0]
        g = np.zeros(np.size(x))
        g[0] = 4 * A * u * (u * u - 1) - self.s * F
        return g

    def hessian(self, x, project=False):
        import scipy.sparse as sp

        u = np.ravel(x)[0]
        h = np.zeros(np.size(x))
        h[0] = A * (12 * u * u - 4)
        return sp.diags(h, format="csr")


def _path(growth):
    stab = ViscousStabilisation(np.ones(1), 0.05, 2)  # weak: 0.05 against the well's curvature -4 A
    problem = Problem(np.array([[-1.0, 0.0]]), lambda s: [DoubleWell(s), stab], [fixed([0], 2, [1])])
    options = PathOptions(ds0=0.1, ds_max=0.1, ds_min=1e-3, easy_iterations=4, damping_growth=growth,
                          newton=NewtonOptions(max_iter=6), stability_check=False)
    return solve_path(problem, options), stab


def test_a_snap_is_crossed_with_raised_damping_instead_of_cut_increments():
    """Without adaptation the snap's step fails and the increment is cut (rejected steps); with
    it the same increment is retried at 10x or 100x the damping (raised only once the left well
    is gone), never cut, the damping falls back to its start after the last, easy step, and the
    path ends in the right well (u > 0)."""
    plain, _ = _path(1.0)
    adaptive, stab = _path(10.0)
    assert plain.rejected_steps > 0
    assert adaptive.converged and adaptive.x[0, 0] > 0
    scales = [h.damping for h in adaptive.history]
    assert max(scales) in (10.0, 100.0)
    assert all(h.ds == pytest.approx(0.1) for h in adaptive.history[:-1] if h.damping > 1)  # not cut
    raised = [h.s for h in adaptive.history if h.damping > 1]
    assert min(raised) > S_CRITICAL - 0.1  # raised only at the snap
    assert stab.scale == 1.0
    assert adaptive.rejected_steps < plain.rejected_steps


def test_without_a_damped_term_nothing_adapts():
    """A problem without the damped term (or with it switched off) records no damping scale."""
    problem = Problem(np.array([[-1.0, 0.0]]), lambda s: [DoubleWell(0.2 * s)], [fixed([0], 2, [1])])
    res = solve_path(problem, PathOptions(ds0=0.5, stability_check=False))
    assert res.converged and all(h.damping is None for h in res.history)
