"""The release of a damped term by proximal rounds (hydrojam.fem.solver.release.release), on a stand-in whose
rounds are exact proximal steps of a spring: the control (when the damping is lowered, raised,
held at its cap), resumption from any round, and the test before the first round."""

import numpy as np
import pytest
import scipy.sparse as sp

import hydrojam.fem.solver.release as release_module
from hydrojam.fem.solver.linsolve import LinearSolver
from hydrojam.fem.solver.newton import NewtonOptions, NewtonResult, NewtonStatus, Timings
from hydrojam.fem.solver.release import ReleaseOptions, release
from hydrojam.fem.terms import EnergyTerm, ViscousStabilisation

_TARGET = np.array([[1.0, 0.0]])  # the stand-in's equilibrium x* [mm]


class _Spring(EnergyTerm):
    """k/2 |x - x*|^2 with k = 1 N/mm and 1 N per DOF of forces in play."""

    name = "elastic"

    def energy(self, x):
        return 0.5 * float(np.sum((np.ravel(x) - _TARGET.ravel()) ** 2))

    def gradient(self, x):
        return np.ravel(x) - _TARGET.ravel()

    def hessian(self, x, project=False):
        return sp.identity(np.size(x), format="csr")

    def force_flux(self, x, gradient=None):
        return np.ones(np.size(x))


def _stand_in(monkeypatch, fails=None, easy=True):
    """Rounds are exact proximal steps x <- (x* + c x)/(1 + c) at damping scale c, of 30 Newton
    iterations unless the move is below 1e-3 mm (then 5: easy; never with ``easy`` False). Round n
    (from 0) fails with the status ``fails(c, n)`` returns (None: converges); one that runs out of
    iterations leaves its last iterate halfway to the proximal step, any other failure the start.
    Returns (terms, stab)."""
    stab = ViscousStabilisation(np.ones(1), 1.0, 2)
    count = [0]

    def fake_minimize(terms, x, free, force_scale, options, solver, observers=()):
        x = np.asarray(x, dtype=float)
        n, count[0] = count[0], count[0] + 1
        new = (_TARGET + stab.scale * x) / (1 + stab.scale)
        status = None if fails is None else fails(stab.scale, n)
        if status is not None:
            last = x + 0.5 * (new - x) if status is NewtonStatus.MAX_ITERATIONS else x
            return NewtonResult(last, status, 200, 1.0, 0.0, "", [], Timings())
        its = 30 if np.abs(new - x).max() > 1e-3 or not easy else 5
        return NewtonResult(new, NewtonStatus.CONVERGED, its, 0.0, 0.0, "", [], Timings())

    monkeypatch.setattr(release_module, "minimize", fake_minimize)
    return [_Spring(), stab], stab


def _release(terms, stab, scale=1.0, x=None, moved=True, **kw):
    """One release from x (default: 0, 1 mm from x*), the damping at ``scale`` and centred 0.5 mm
    behind x (``moved``: a step that travelled) or on x; at most 80 rounds."""
    stab.scale = scale
    x0 = np.zeros((1, 2)) if x is None else x
    stab.begin_step(x0 - 0.5 if moved else x0)
    opts = ReleaseOptions(max_rounds=kw.pop("max_rounds", 80))
    return release(terms, stab, x0, np.ones(2, dtype=bool), 1.0, NewtonOptions(), LinearSolver("scipy"), opts,
                   **kw)


def test_an_equilibrium_of_the_physics_is_released_without_a_round(monkeypatch):
    """A state where the physics alone is already in equilibrium (an undamped step) takes no
    round and is left as it is; one where the damping pulls but the physics is not (x = 0, the
    spring's force 1 N) takes rounds."""
    terms, stab = _stand_in(monkeypatch)
    out = _release(terms, stab, x=_TARGET.copy(), moved=False)
    assert out.released and out.rounds == [] and out.iterations == 0
    assert np.array_equal(out.x, _TARGET) and out.residual <= out.tolerance
    terms, stab = _stand_in(monkeypatch)
    assert _release(terms, stab, x=np.zeros((1, 2)), moved=False).rounds


def test_after_a_failure_the_release_lowers_the_damping_after_an_easy_round_or_a_backoff(monkeypatch):
    """Rounds at scale >= 1 converge, each halfway to x* (30 iterations, then 5 once the move is
    small); rounds below 1 run out of iterations, their last iterate kept as progress. After the
    f-th failure the scale stays at 1 for 4 x 2^(f-1) converged rounds, or until a round is easy
    (<= 20 iterations), before 0.1 is tried again; the state is released once the viscous force
    is within the tolerance (rtol x 1 N), so x is within the spring's compliance times it of x*."""
    fails = lambda c, n: NewtonStatus.MAX_ITERATIONS if c < 1 else None  # noqa: E731
    terms, stab = _stand_in(monkeypatch, fails)
    out = _release(terms, stab)
    scales = [r[0] for r in out.rounds]
    assert scales[:2] == [1.0, 0.1] and not out.rounds[1][2]
    failures = [i for i, r in enumerate(out.rounds) if not r[2]]
    assert len(failures) >= 2
    for f, i in enumerate(failures, start=1):
        after = out.rounds[i + 1:(failures[f] if f < len(failures) else len(out.rounds))]
        held = [r for r in after if r[0] == 1.0]
        assert all(r[2] for r in held)
        # held for the whole backoff, or released / lowered early by an easy round
        assert len(held) == 4 * 2 ** (f - 1) or (held and held[-1][1] <= 20)
    tol = NewtonOptions().rtol
    assert out.released and np.abs(out.x - _TARGET).max() <= 10 * tol
    assert out.iterations == sum(r[1] for r in out.rounds)


def _capped(status):
    """Round 0 (at 100x) fails; rounds at the cap (1000x) converge, never easy; round 4 fails with
    ``status``."""
    return lambda scale, n: (NewtonStatus.MAX_ITERATIONS if n == 0 else status if n == 4 else None)


def test_the_release_goes_on_where_the_damping_reaches_its_cap(monkeypatch):
    """A round that runs out of iterations at the cap (1000x) is kept as progress: the damping
    stays there, its last iterate is the next centre, and the damping is lowered after 4 x 2^(f-1)
    converged rounds (f = 2 failed rounds: 8); the state is then released at x*."""
    terms, stab = _stand_in(monkeypatch, _capped(NewtonStatus.MAX_ITERATIONS), easy=False)
    out = _release(terms, stab, 100.0)
    scales = [r[0] for r in out.rounds]
    assert scales[:5] == [100.0] + [1000.0] * 4 and not out.rounds[4][2]
    assert scales[5:13] == [1000.0] * 8 and all(r[2] for r in out.rounds[5:13])
    assert scales[13] == pytest.approx(100.0)
    assert out.released and np.allclose(out.x, _TARGET, atol=1e-5)


def test_a_failure_at_the_cap_without_descent_ends_the_release(monkeypatch):
    """Only a round that ran out of iterations is progress; one with no admissible descent at the
    cap would fail again from the same centre: not released, the last kept round's state."""
    terms, stab = _stand_in(monkeypatch, _capped(NewtonStatus.LINE_SEARCH_FAILED), easy=False)
    out = _release(terms, stab, 100.0)
    assert not out.released and len(out.rounds) == 5
    x3 = 0.5 * _TARGET / 101.0  # round 0 (at 100x) ran out halfway to its proximal step: kept
    for c in (1000.0, 1000.0, 1000.0):  # rounds 1-3 converged at the cap
        x3 = (_TARGET + c * x3) / (1 + c)
    # each round at 1000x moves x by about 1e-3 mm: 1e-6 mm tells the rounds apart, far above round-off
    assert np.allclose(out.x, x3, rtol=0, atol=1e-6)


def test_a_release_resumed_from_any_round_goes_on_as_in_one_go(monkeypatch):
    """Everything the control reads is in the state passed to ``on_round``: resumed after any
    round, the release takes the same rounds to the same state."""
    saved = []
    fails = _capped(NewtonStatus.MAX_ITERATIONS)
    terms, stab = _stand_in(monkeypatch, fails, easy=False)
    whole = _release(terms, stab, 100.0, on_round=saved.append)
    assert whole.released and len(saved) == len(whole.rounds) - 1
    for ck in saved:
        n0 = len(ck.rounds)
        terms, stab = _stand_in(monkeypatch, lambda c, n: fails(c, n + n0), easy=False)
        again = _release(terms, stab, 100.0, resume=ck)
        assert again.rounds == whole.rounds and np.array_equal(again.x, whole.x)
        assert again.iterations == whole.iterations
