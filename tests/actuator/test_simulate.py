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
    contact-free: every node stays where it is (DESIGN.md section 3, reference configuration)."""
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


@pytest.mark.parametrize("variant", [{}, {"inexact": True, "keep_failed": True}], ids=["release", "inexact_keep"])
def test_the_final_state_is_an_equilibrium_without_stabilisation(variant, monkeypatch):
    """The release at s = 1 (docs/actuator.md, "Stabilisation"): at the final state the physics
    alone (elastic and contact terms at the target stimulus, no viscous term), computed here from
    the terms directly, is in equilibrium: its residual over the free DOFs is within a few times
    the solver's tolerance (rtol x the elastic forces in play: the last round's own residual plus
    the viscous force left, each at most the tolerance unless that round stopped at energy
    round-off), and far below the residual of the stabilised state that the path ended in.
    Frictionless: lagged friction is frozen at each release round's start, which the final state
    does not record, so with friction the physics alone is not what the final state balances.
    The same for the release variant with inexact rounds that keeps failed rounds' states
    (docs/actuator.md, "Two release variants"): its last round runs at rtol."""
    import functools

    import hydrojam.actuator.simulate as simulate_module

    monkeypatch.setattr(simulate_module, "_release", functools.partial(simulate_module._release, **variant))
    model = _model("particle_layers=1", "mesh.size=4", "friction=0")
    ends = []
    res = simulate(model, on_step=lambda st: ends.append(st.x) if st.s == 1.0 else None)
    assert res.converged and res.metrics["stabilisation_released"], res.message
    assert len(ends) == 2  # the stabilised end of the path, then the released final state
    problem = model.problem()
    free = problem.free_mask()
    terms = problem.terms(1.0)
    newton = NewtonOptions()

    def residual(x):
        return np.linalg.norm(sum(t.gradient(x) for t in terms)[free])

    in_play = np.linalg.norm(terms[0].force_flux(res.final.x)[free])
    tol = max(newton.rtol * in_play, newton.residual_floor * problem.force_scale)
    assert residual(res.final.x) <= 10 * tol, (residual(res.final.x), tol)
    assert residual(res.final.x) <= 1e-2 * residual(ends[0])
    assert np.isfinite(sum(t.energy(res.final.x) for t in terms))  # admissible: no barrier crossed


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


_TARGET = np.array([[1.0, 0.0]])  # the release stand-ins' equilibrium x* [mm]


def _spring():
    """The release stand-ins' physics: k/2 |x - x*|^2 with k = 1 N/mm, x* = _TARGET, and 1 N per
    DOF of forces in play."""
    import scipy.sparse as sp

    from hydrojam.fem.terms import EnergyTerm

    class Spring(EnergyTerm):
        name = "elastic"

        def energy(self, x):
            return 0.5 * float(np.sum((np.ravel(x) - _TARGET.ravel()) ** 2))

        def gradient(self, x):
            return np.ravel(x) - _TARGET.ravel()

        def hessian(self, x, project=False):
            return sp.identity(np.size(x), format="csr")

        def force_flux(self, x, gradient=None):
            return np.ones(np.size(x))

    return Spring()


def _proximal_stand_in(monkeypatch, fails_beyond: float | None, easy: bool = True, fails=None):
    """The release on a stand-in: the physics k/2 |x - x*|^2 (k = 1, x* at 1 mm), each round an
    exact proximal step x <- (x* + c x)/(1 + c) at damping scale c, 30 Newton iterations unless
    the move is below 1e-3 mm (then 5: easy; never with ``easy`` False). A round below scale 1
    fails (200 iterations) while the distance to x* exceeds ``fails_beyond`` (always with None);
    with ``fails(c, n)`` (n: the round's index from 0 on this stand-in) instead, round n fails with the status it
    returns (None: it converges). A round that runs out of iterations leaves its last iterate
    halfway to the proximal step (admissible and lower in energy); any other failure, the start.
    Returns (sim, problem, stab)."""
    import hydrojam.actuator.simulate as sim
    from hydrojam.fem.newton import NewtonResult, NewtonStatus, Timings
    from hydrojam.fem.problem import Problem
    from hydrojam.fem.terms import ViscousStabilisation

    stab = ViscousStabilisation(np.ones(1), 1.0, 2)
    problem = Problem(np.zeros((1, 2)), lambda s: [_spring(), stab], force_scale=1.0)
    count = [0]

    def fake_minimize(terms, x, free, force_scale, options, solver):
        x = np.asarray(x, dtype=float)
        n, count[0] = count[0], count[0] + 1
        new = (_TARGET + stab.scale * x) / (1 + stab.scale)
        if fails is not None:
            status = fails(stab.scale, n)
        elif stab.scale < 1 and (fails_beyond is None or np.abs(_TARGET - x).max() > fails_beyond):
            status = NewtonStatus.MAX_ITERATIONS
        else:
            status = None
        if status is not None:
            last = x + 0.5 * (new - x) if status is NewtonStatus.MAX_ITERATIONS else x
            return NewtonResult(last, status, 200, 1.0, 0.0, "", [], Timings())
        its = 30 if np.abs(new - x).max() > 1e-3 or not easy else 5
        return NewtonResult(new, NewtonStatus.CONVERGED, its, 0.0, 0.0, "", [], Timings())

    monkeypatch.setattr(sim, "minimize", fake_minimize)
    return sim, problem, stab


def _release_on(stand_in, scale: float = 1.0, **kw):
    """One release on a stand-in ((sim, problem, stab) of :func:`_proximal_stand_in`) from x = 0,
    its damping at ``scale`` x the path's; at most 80 rounds unless ``max_rounds`` says."""
    from hydrojam.fem.newton import Timings

    sim, problem, stab = stand_in
    stab.scale = scale
    return sim._release(problem, stab, np.zeros((1, 2)), sim.ACTUATOR_PATH, problem.terms, Timings(),
                        **{"max_rounds": 80, **kw})


def test_the_release_lowers_the_damping_after_a_failure_only_after_an_easy_round(monkeypatch):
    """The release's control (actuator.simulate._release) on a stand-in minimisation: rounds at
    damping scale >= 1 converge, each moving halfway to the physics' equilibrium x* (iterations
    30, then 5 once the move is small), rounds below 1 fail (200 iterations). After the first
    failure the scale stays at 1 until a round is easy (<= 20 iterations), instead of trying 0.1
    after every converged round; the state is released once the viscous force is below the
    tolerance."""
    x, its, released, rounds = _release_on(_proximal_stand_in(monkeypatch, fails_beyond=None))  # at 1: halfway
    scales = [r[0] for r in rounds]
    assert scales[:2] == [1.0, 0.1] and not rounds[1][2]  # lowered after the first round, failed
    first_easy = next(i for i, r in enumerate(rounds) if r[2] and r[1] <= 20)
    assert first_easy > 3 and all(sc == 1.0 for sc in scales[2:first_easy + 1])  # held until easy
    for i in range(2, len(rounds) - 1):  # every lowering after the first failure follows an easy round
        if scales[i + 1] < scales[i]:
            assert rounds[i][2] and rounds[i][1] <= 20
    assert released and np.allclose(x, _TARGET, atol=1e-5)


def test_the_release_with_backoff_lowers_after_k_rounds_and_doubles_k_after_each_failure(monkeypatch):
    """backoff_rounds = 2 (a variant, off by default): where the lower damping becomes possible
    once the state is near (within 0.2 mm), the release lowers after 2 rounds at the raised level
    instead of waiting for an easy one, and releases in fewer rounds and iterations; where it
    never becomes possible (rounds below scale 1 always fail), the waits double (2, 4, 8, ...), so
    the failed rounds grow with the logarithm of the rounds. Without it the rounds are those of
    the rule in use."""
    stand_in = _proximal_stand_in(monkeypatch, fails_beyond=0.2)

    def release(**kw):
        return _release_on(stand_in, **kw)

    plain, backoff = release(), release(backoff_rounds=2)
    assert plain[2] and backoff[2]  # both released
    assert len(backoff[3]) < len(plain[3]) and backoff[1] < plain[1]
    scales = [r[0] for r in backoff[3]]
    assert scales[:4] == [1.0, 0.1, 1.0, 1.0] and not backoff[3][1][2]  # the failure, then 2 rounds at 1
    assert scales[4] == pytest.approx(0.1) and backoff[3][4][2]  # lowered without an easy round: converged
    assert release(backoff_rounds=None)[3] == plain[3]

    x, its, released, rounds = _release_on(_proximal_stand_in(monkeypatch, fails_beyond=None, easy=False),
                                           max_rounds=60, backoff_rounds=2)
    failed = [i for i, r in enumerate(rounds) if not r[2]]
    waits = [b - a - 1 for a, b in zip(failed, failed[1:])]
    assert released and waits[:3] == [2, 4, 8]  # converged rounds at scale 1 between failed tries at 0.1
    assert len(failed) <= 5  # about log2 of the rounds, not one failure every other round


def test_a_release_with_backoff_resumed_from_any_round_goes_on_as_in_one_go(monkeypatch):
    """The backoff is counted from the rounds, which the release's checkpoint holds: resumed
    after any round, the release takes the same rounds to the same state."""
    stand_in = _proximal_stand_in(monkeypatch, fails_beyond=None, easy=False)

    def release(**kw):
        return _release_on(stand_in, max_rounds=60, backoff_rounds=2, **kw)

    saved = []
    whole = release(on_round=saved.append)
    assert whole[2] and len(saved) == len(whole[3]) - 1  # every round but the releasing one
    for ck in saved:
        again = release(resume=ck)
        assert again[3] == whole[3] and np.array_equal(again[0], whole[0]) and again[1] == whole[1]


def _capped(status):
    """A release like the quick 3D 15-layer chamber's (docs/reproduce.md): its first round, at
    the path's 100x, fails; rounds at 1000x converge, never easy; round 4, at 1000x, fails with
    ``status``; nothing else fails."""
    from hydrojam.fem.newton import NewtonStatus

    return lambda scale, n: (NewtonStatus.MAX_ITERATIONS if n == 0 else status if n == 4 else None)


def _release_from_100x(monkeypatch, fails, **kw):
    """One release on a fresh stand-in (``fails`` as in :func:`_proximal_stand_in`, rounds never
    easy), its stabilisation at 100x of the path's."""
    return _release_on(_proximal_stand_in(monkeypatch, fails_beyond=None, easy=False, fails=fails), 100.0, **kw)


def test_the_release_goes_on_where_the_damping_would_pass_the_cap(monkeypatch):
    """A round that runs out of iterations at 1000x (the cap) no longer ends the release: its last
    iterate is kept as the next centre, the damping stays at 1000x, and it is lowered after
    4 x 2^(f-1) converged rounds (f = 2 failed rounds: 8); the state is then released at x*.
    Before that round, the rounds are those of the rule that gave up there (beyond_cap=False,
    which returns the last converged round's state, not released); a release that never fails at
    the cap takes the same rounds either way."""
    from hydrojam.fem.newton import NewtonStatus

    old = _release_from_100x(monkeypatch, _capped(NewtonStatus.MAX_ITERATIONS), beyond_cap=False)
    x, its, released, rounds = _release_from_100x(monkeypatch, _capped(NewtonStatus.MAX_ITERATIONS))
    assert not old[2] and len(old[3]) == 5 and rounds[:5] == old[3]
    scales = [r[0] for r in rounds]
    assert scales[:5] == [100.0] + [1000.0] * 4 and not rounds[4][2]
    assert scales[5:13] == [1000.0] * 8 and all(r[2] for r in rounds[5:13])  # held 4 x 2 rounds
    assert scales[13] == pytest.approx(100.0)
    assert released and np.allclose(x, _TARGET, atol=1e-5)

    # the failed round's iterate is kept: one more round at 1000x from the old end lands short of it
    at_old_end = (_TARGET + 1000.0 * old[0]) / 1001.0
    kept = old[0] + 0.5 * (at_old_end - old[0])
    again = _release_from_100x(monkeypatch, _capped(NewtonStatus.MAX_ITERATIONS), max_rounds=6)
    assert np.allclose(again[0], (_TARGET + 1000.0 * kept) / 1001.0, rtol=0, atol=1e-12)

    never = lambda scale, n: NewtonStatus.MAX_ITERATIONS if n in (0, 3) and scale < 1000 else None  # noqa: E731
    assert _release_from_100x(monkeypatch, never)[3] == _release_from_100x(monkeypatch, never, beyond_cap=False)[3]


def test_a_failure_at_the_cap_without_descent_still_ends_the_release(monkeypatch):
    """Only a round that ran out of iterations is progress; one with no admissible descent at
    1000x would fail again from the same centre, so the release ends there as before: not
    released, the last converged round's state."""
    from hydrojam.fem.newton import NewtonStatus

    old = _release_from_100x(monkeypatch, _capped(NewtonStatus.LINE_SEARCH_FAILED), beyond_cap=False)
    new = _release_from_100x(monkeypatch, _capped(NewtonStatus.LINE_SEARCH_FAILED))
    assert not new[2] and new[3] == old[3] and len(new[3]) == 5 and np.array_equal(new[0], old[0])


def test_a_release_beyond_the_cap_resumed_from_any_round_goes_on_as_in_one_go(monkeypatch):
    """Whether the release is past the cap is read from the rounds, which the checkpoint holds:
    resumed after any round, the same rounds to the same state."""
    from hydrojam.fem.newton import NewtonStatus

    saved = []
    whole = _release_from_100x(monkeypatch, _capped(NewtonStatus.MAX_ITERATIONS), on_round=saved.append)
    assert whole[2] and len(saved) == len(whole[3]) - 1
    for ck in saved:
        # the stand-in counts rounds from 0: resumed after round i, the next is round i + 1
        n0 = len(ck.rounds)
        fails = _capped(NewtonStatus.MAX_ITERATIONS)
        again = _release_from_100x(monkeypatch, lambda scale, n: fails(scale, n + n0), resume=ck)
        assert again[3] == whole[3] and np.array_equal(again[0], whole[0]) and again[1] == whole[1]
