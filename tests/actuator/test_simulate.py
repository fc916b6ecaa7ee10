"""Actuator simulations end to end (hydrojam.actuator.simulate): the undeformed-state check, failure
handling, and (slow) the bending direction and its temperature trend."""

import json
import math

import numpy as np
import pytest

from hydrojam.actuator.design import apply_overrides, default_design
from hydrojam.actuator.model import build_model
from hydrojam.actuator.simulate import simulate
from hydrojam.fem import NewtonOptions, PathOptions
from undeformed import assert_nothing_moved


def _model(*overrides):
    return build_model(apply_overrides(default_design(), list(overrides)))


def test_nothing_moves_when_the_stimulus_stays_at_the_as_prepared_state():
    """With the target stimulus equal to (mu0, T0) the as-prepared state is stress-free and
    contact-free: every node stays where it is (docs/model.md, "Reference state")."""
    d = default_design()
    mu0, T0 = d.hydrogel.mu0, d.hydrogel.T0
    model = _model("particle_layers=2", f"stimulus.mu={mu0!r}", f"stimulus.temperature={T0!r}")
    assert_nothing_moved(model, simulate(model))


def test_a_solver_that_cannot_converge_says_so_and_keeps_the_last_converged_state():
    """Newton allowed one iteration and a large minimum increment: the path stops early, the
    result says where and why, and every number in it is finite (no NaN)."""
    model = _model("particle_layers=1")
    tight = PathOptions(ds0=0.5, ds_min=0.2, newton=NewtonOptions(max_iter=1))
    res = simulate(model, options=tight)
    assert not res.converged
    assert "last converged state kept" in res.message
    assert res.final.s < 1.0
    assert np.all(np.isfinite(res.final.x))
    text = json.dumps(res.metrics, allow_nan=False)  # raises on NaN / inf
    assert '"converged": false' in text


def test_every_reported_state_is_an_equilibrium_of_the_physics_alone():
    """docs/solver.md, "Release at every step": every state the run reports (each history row, not only the last) is
    an equilibrium without any stabilisation. Checked from the terms directly: at each state the
    physics alone (elastic and contact terms at the state's stimulus, no viscous term) has a
    residual over the free DOFs within a few times the solver's tolerance (rtol x the elastic
    forces in play), and the run's own record of that residual is within Newton's convergence
    test of the tolerance it states. Frictionless: lagged friction is frozen at each round's start, which a state does not
    record, so with friction the physics alone is not what a state balances. The final state is
    stable (no negative eigenvalue of the physical Hessian)."""
    model = _model("particle_layers=1", "mesh.size=4", "friction=0")
    res = simulate(model)
    assert res.converged and res.metrics["stabilisation_released"], res.message
    problem = model.problem()
    free = problem.free_mask()
    newton = NewtonOptions()
    for st in res.states:
        terms = problem.terms(st.s)
        residual = np.linalg.norm(sum(t.gradient(st.x) for t in terms)[free])
        in_play = np.linalg.norm(terms[0].force_flux(st.x)[free])
        tol = max(newton.rtol * in_play, newton.residual_floor * problem.force_scale)
        assert residual <= 10 * tol, (st.s, residual, tol)
        # the run's record: within the tolerance, or within stall_factor of it where Newton
        # stopped at the energy's round-off (NewtonStatus.CONVERGED_DECREMENT / _NO_DESCENT)
        assert st.residual <= newton.stall_factor * st.tolerance, (st.s, st.residual, st.tolerance)
        assert np.isfinite(sum(t.energy(st.x) for t in terms))  # admissible: no barrier crossed
    assert res.final.negative_eigenvalues == 0


@pytest.mark.slow
def test_actuator_bends_toward_the_strain_limit_layer_and_less_when_warmer():
    """Paper Sec. IV-A (Figs. 6-7): cold water (275 K) swells the particles more than 295 K
    water, so the actuator bends toward the strain-limit layer (-x, positive angle), more at
    275 K; its tip moves to -x and down. One particle layer and a coarse mesh keep it fast;
    the default design's figures are in benchmarks/actuator.py."""
    out = {}
    for T in (275.0, 295.0):
        res = simulate(_model("particle_layers=1", "mesh.size=3.0", f"stimulus.temperature={T}"))
        assert res.converged, res.message
        out[T] = res.metrics
    cold, warm = out[275.0], out[295.0]
    assert cold["bending_angle_deg"] > warm["bending_angle_deg"] > 0.0
    assert cold["tip_dx_mm"] < warm["tip_dx_mm"] < 0.0
    assert cold["tip_dz_mm"] < 0.0 and warm["tip_dz_mm"] < 0.0
    assert cold["mean_swelling_ratio"] > warm["mean_swelling_ratio"] > 1.0
    assert math.isfinite(cold["packing_fraction"]) and cold["contacts_per_particle"] >= 1.0


@pytest.mark.slow
def test_a_stimulus_next_to_the_as_prepared_state_takes_few_iterations():
    """A target 6e-6 k_B T from mu0 at T0: the particles swell by 1e-5 without touching anything,
    so every load step is a nearly linear problem that Newton solves in a few iterations, and the
    final state is an equilibrium without stabilisation. Counted: every Newton iteration,
    including those of rejected attempts and of the release."""
    model = _model("particle_layers=1", "mesh.size=4", "stimulus.mu=-0.03431", "stimulus.temperature=300")
    res = simulate(model)
    assert res.converged and res.metrics["stabilisation_released"], res.message
    assert res.metrics["contacts_per_particle"] == 0
    assert res.timings["newton_iterations"] <= 100, res.timings["newton_iterations"]


_THREADED_RUN = """
import json
from hydrojam.actuator.design import apply_overrides, default_design
from hydrojam.actuator.model import build_model
from hydrojam.actuator.simulate import simulate
res = simulate(build_model(apply_overrides(default_design(), ["particle_layers=1", "mesh.size=4"])))
m = res.metrics
print(json.dumps([repr(m["bending_angle_deg"]), repr(m["tip_dx_mm"]), m["newton_iterations"], m["converged"]]))
"""


@pytest.mark.slow
def test_a_run_is_bit_identical_on_one_and_two_solver_threads():
    """Determinism across thread settings (docs/solver.md, "Determinism"): the one-layer design
    run in fresh interpreters (MKL reads its thread count when the solver is built) with
    HYDROJAM_SOLVER_THREADS = 1 and 2 gives the same angle, tip and iteration count to the last
    bit. The tolerance is zero on purpose: PARDISO runs in MKL's conditional numerical
    reproducibility mode (iparm(34)), which makes its round-off independent of the thread count;
    without it the two runs differed in the first decimal (46.34 vs 45.94 deg on the 2 mm mesh),
    as the path amplifies any round-off."""
    import os
    import subprocess
    import sys

    out = []
    for threads in ("1", "2"):
        env = {**os.environ, "HYDROJAM_SOLVER_THREADS": threads}
        run = subprocess.run([sys.executable, "-c", _THREADED_RUN], env=env, capture_output=True, text=True,
                             check=True)
        out.append(json.loads(run.stdout.strip().splitlines()[-1]))
    assert out[0][3] and out[0] == out[1], out


def test_the_run_reports_where_the_path_lost_stability():
    """history states carry the physical Hessian's negative-eigenvalue count (None only at s = 0),
    and buckled_at_s is the s of the first state with one (None if none): read back from the
    states here. The check runs on a solver of its own, so switching it off leaves the path
    bit for bit as it was (the same final positions and iterations)."""
    import dataclasses

    from hydrojam.actuator.simulate import ACTUATOR_PATH

    model = _model("particle_layers=1", "mesh.size=4")
    res = simulate(model)
    unchecked = simulate(model, options=dataclasses.replace(ACTUATOR_PATH, stability_check=False))
    assert np.array_equal(res.final.x, unchecked.final.x)
    assert res.newton_iterations == unchecked.newton_iterations
    assert all(st.negative_eigenvalues is None for st in unchecked.states)
    assert unchecked.metrics["buckled_at_s"] is None and unchecked.metrics["unstable_states"] == 0
    assert res.converged, res.message
    assert res.states[0].negative_eigenvalues is None
    counts = [st.negative_eigenvalues for st in res.states[1:]]
    assert all(isinstance(c, int) and c >= 0 for c in counts)
    first = next((st.s for st in res.states if st.negative_eigenvalues), None)
    m = res.metrics
    assert m["buckled_at_s"] == first
    assert m["unstable_states"] == sum(1 for c in counts if c)


def test_a_second_run_on_the_same_model_starts_without_the_first_runs_friction():
    """Friction is lagged (frozen at each load step's start); a run that reused the model's
    contact term would start from the lag where the previous run ended. Two runs of one model,
    with friction on, are the same to the bit."""
    model = _model("particle_layers=1", "mesh.size=4", "friction=0.05")
    first, second = simulate(model), simulate(model)
    assert first.newton_iterations == second.newton_iterations
    assert np.array_equal(first.final.x, second.final.x)
