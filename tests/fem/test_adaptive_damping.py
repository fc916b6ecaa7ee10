"""Adaptive damping of the load path (hydrojam.fem.solver.path, PathOptions.damping_growth): a step that
runs out of Newton iterations is retried, at the same increment, with the viscous stabilisation
raised, and easy steps lower it again (or, with PathOptions.damping_relax_after, steps in a row
at its level). And the increment's recovery after a cut. Checked on a
one-DOF snap whose critical load is known."""

import dataclasses
import math

import numpy as np
import pytest

from hydrojam.fem import NewtonOptions, PathOptions, Problem, fixed, solve_path
from hydrojam.fem.solver.release import ReleaseOptions
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


def _snap(growth, easy=4, load=1.0, relax=0):
    """The double well under ``load`` x F with a weak stabilisation, and path options whose
    Newton budget (6) the snap exceeds: (problem, options, stabilisation)."""
    stab = ViscousStabilisation(np.ones(1), 0.05, 2)  # weak: 0.05 against the well's curvature -4 A
    problem = Problem(np.array([[-1.0, 0.0]]), lambda s: [DoubleWell(load * s), stab], [fixed([0], 2, [1])])
    options = PathOptions(ds0=0.1, ds_max=0.1, ds_min=1e-3, easy_iterations=easy, damping_growth=growth,
                          newton=NewtonOptions(max_iter=6), stability_check=False,
                          damping_relax_after=relax, release=ReleaseOptions(each_step=False), extrapolate=False)
    return problem, options, stab


def _path(growth, easy=4, load=1.0, relax=0):
    problem, options, stab = _snap(growth, easy, load, relax)
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


def test_the_increment_grows_back_after_a_cut_even_where_no_step_is_easy():
    """No step counts as easy (easy_iterations 0, as 3D actuator steps of 40-290 iterations
    against the 30 that count as easy) and the damping does not adapt, so the snap cuts the
    increment. Every accepted step after the cut grows it 1.5x (or to what is left of the path),
    up to the 0.1 that was cut and no further, and the path ends in the right well."""
    recovered, _ = _path(1.0, easy=0)
    assert recovered.converged and recovered.x[0, 0] > 0
    cut = next(i for i, h in enumerate(recovered.history) if h.ds < 0.1 - 1e-12)
    steps = recovered.history[cut:]
    for a, b in zip(steps, steps[1:]):
        assert b.ds <= 0.1 + 1e-12
        # grew 1.5x, or was capped by the increment cut, or by the end of the path, or cut again
        assert b.ds == pytest.approx(min(1.5 * a.ds, 0.1, 1 - a.s)) or b.ds < a.ds
    assert max(h.ds for h in steps[1:]) == pytest.approx(0.1)


def test_a_path_resumed_after_a_cut_grows_back_as_in_one_go():
    """The increment that was cut is part of the checkpoint: a path stopped in its recovery and
    resumed takes the same steps to the same state as the path in one go."""
    whole, _ = _path(1.0, easy=0)
    cut = next(i for i, h in enumerate(whole.history) if h.ds < 0.1 - 1e-12)
    saved = []

    class Stop(Exception):
        pass

    def keep(ck):
        saved.append(ck)
        if len(ck.history) == cut + 2:
            raise Stop

    problem, options, _ = _snap(1.0, easy=0)
    with pytest.raises(Stop):
        solve_path(problem, options, on_checkpoint=keep)
    assert saved[-1].ds_cut == pytest.approx(0.1)
    resumed = solve_path(problem, options, resume=saved[-1])
    assert [h.ds for h in resumed.history] == [h.ds for h in whole.history]
    assert np.array_equal(resumed.x, whole.x)
    forgotten = solve_path(problem, options, resume=dataclasses.replace(saved[-1], ds_cut=0.0))
    assert len(forgotten.history) > len(whole.history)  # without it, the increment stays cut


def test_a_raised_damping_comes_down_after_steps_at_its_level_even_where_no_step_is_easy():
    """No step counts as easy (as in 3D), so the damping raised at the snap stays raised to the
    end of the path; with damping_relax_after = 2 it is divided by 10 after 2 accepted steps in a
    row at its level (counted again from a step that failed first: a relaxation that failed and
    was raised back), down to where it started. The relaxed path ends nearer the equilibrium,
    which the damping at 100x lags behind."""
    load = 2.0  # the snap at s = S_CRITICAL / 2: room for the relaxation after it
    stuck, stuck_stab = _path(10.0, easy=0, load=load)
    relaxed, relaxed_stab = _path(10.0, easy=0, relax=2, load=load)
    assert stuck.converged and relaxed.converged
    raised = next(i for i, h in enumerate(stuck.history) if h.damping > 1)
    assert all(h.damping == stuck.history[raised].damping for h in stuck.history[raised:])
    assert stuck_stab.scale > 1.0 and len(stuck.history) - raised > 4
    levels = [h.damping for h in relaxed.history]
    assert max(levels) > 1 and levels[-1] == 1.0 and relaxed_stab.scale == 1.0
    lowered = [i for i in range(1, len(levels)) if levels[i] < levels[i - 1]]
    assert len(lowered) == 2  # 100x -> 10x -> 1x
    for i in lowered:
        assert levels[i] == pytest.approx(levels[i - 1] / 10)
        prev = relaxed.history[i - 2: i]
        assert all(h.damping == levels[i - 1] for h in prev) and prev[-1].rejected == 0
    u_eq = max(np.roots([4 * A, 0.0, -4 * A, -load * F]).real)  # E'(u) = 0 at s = 1, right well
    assert abs(relaxed.x[0, 0] - u_eq) < abs(stuck.x[0, 0] - u_eq)


def test_relaxing_leaves_a_path_whose_damping_was_never_raised_as_it_was():
    """A load below the snap never raises the damping: the same path to the bit either way."""
    on, _ = _path(10.0, easy=0, load=0.5, relax=2)
    off, _ = _path(10.0, easy=0, load=0.5, relax=0)
    assert all(h.damping == 1.0 for h in on.history)
    assert [h.ds for h in on.history] == [h.ds for h in off.history]
    assert np.array_equal(on.x, off.x)


def test_a_path_resumed_while_relaxing_its_damping_goes_on_as_in_one_go():
    """The steps at a damping level are counted from the history, which the checkpoint holds
    (with each step's failed attempts): a path stopped after any step from the raise to the end
    of the relaxation and resumed (on a fresh problem, as a new run would: a stopped path leaves
    its damped term's scale raised) takes the same steps to the same state as in one go."""
    whole, _ = _path(10.0, easy=0, relax=2, load=2.0)
    raised = next(i for i, h in enumerate(whole.history) if h.damping > 1)
    relaxed = next(i for i, h in enumerate(whole.history) if i > raised and h.damping == 1.0)

    class Stop(Exception):
        pass

    for stop in range(raised + 1, relaxed + 1):
        saved = []

        def keep(ck):
            saved.append(ck)
            if len(ck.history) == stop:
                raise Stop

        problem, options, _ = _snap(10.0, easy=0, load=2.0, relax=2)
        with pytest.raises(Stop):
            solve_path(problem, options, on_checkpoint=keep)
        problem, options, _ = _snap(10.0, easy=0, load=2.0, relax=2)
        resumed = solve_path(problem, options, resume=saved[-1])
        assert [(h.ds, h.damping, h.rejected) for h in resumed.history] == \
            [(h.ds, h.damping, h.rejected) for h in whole.history], stop
        assert np.array_equal(resumed.x, whole.x), stop



def test_an_undamped_step_that_runs_out_goes_on_in_blocks_before_the_damping_comes_in():
    """Every step first tried undamped (``damping_start`` 0), with a Newton budget of 2 that the
    stable steps before the snap (3-5 iterations) exceed. With one block they run out and are
    retried damped; with ``undamped_blocks`` 4 each goes on from its last iterate and converges
    undamped, its record counting every block's iterations, on the left root of E' = 0 (the
    state before the snap), within its residual over the curvature."""
    from scipy.optimize import brentq

    def path(blocks):
        problem, options, _ = _snap(10.0)  # a fresh stabilisation each time: a path leaves its scale
        options = dataclasses.replace(options, damping_start=0.0, release=ReleaseOptions(), undamped_blocks=blocks,
                                      newton=dataclasses.replace(options.newton, max_iter=2))
        return solve_path(problem, options, callback=lambda s, x, rec: states.append((s, x[0, 0], rec)))

    states = []
    one = path(1)
    assert any(rec.damping > 0 for s, _, rec in states if s < S_CRITICAL)
    states = []
    blocks = path(4)
    assert one.converged and blocks.converged
    # the steps of ds 0.1 before the snap's (which fails without descent, not by running out)
    before = [(s, u, rec) for s, u, rec in states if s < S_CRITICAL - 0.01]
    assert before and all(rec.damping == 0 for _, _, rec in before)
    assert max(rec.iterations for _, _, rec in before) > 2
    for s, u, rec in before:
        root = brentq(lambda v: 4 * A * v * (v * v - 1) - s * F, -1.5, -1 / math.sqrt(3))
        # the error of a state is its residual over the curvature (a round-off stop leaves the
        # residual within stall_factor of the tolerance)
        assert abs(u - root) <= 2 * max(rec.residual, rec.tolerance) / (A * (12 * root * root - 4))


def test_damped_attempts_start_where_the_undamped_blocks_stopped():
    """With ``damped_from_blocks`` a step whose undamped block ran out (a Newton budget of 2, one
    block, against the 3-5 iterations the stable steps need) is retried damped from the
    blocks' last iterate, its damping centred there, and released: every state before the snap
    is still on the analytic branch, and each step's record counts the blocks' iterations too."""
    from scipy.optimize import brentq

    problem, options, _ = _snap(10.0)
    options = dataclasses.replace(options, damping_start=0.0, release=ReleaseOptions(), undamped_blocks=1,
                                  damped_from_blocks=True, newton=dataclasses.replace(options.newton, max_iter=2))
    states = []
    res = solve_path(problem, options, callback=lambda s, x, rec: states.append((s, x[0, 0], rec)))
    assert res.converged
    before = [(s, u, rec) for s, u, rec in states if s < S_CRITICAL - 0.01]
    assert before and any(rec.damping > 0 for _, _, rec in before)
    for s, u, rec in before:
        root = brentq(lambda v: 4 * A * v * (v * v - 1) - s * F, -1.5, -1 / math.sqrt(3))
        assert abs(u - root) <= 2 * max(rec.residual, rec.tolerance) / (A * (12 * root * root - 4))
        assert rec.iterations >= 2 or rec.damping == 0
