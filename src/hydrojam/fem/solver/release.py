"""Releasing a damped term (a viscous stabilisation) at a state by proximal rounds: the one
release loop, used by the load path at every accepted step, by the actuator at the end of a
path, and by the vacuum-jammed chamber (:mod:`hydrojam.assess`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hydrojam.fem.solver.events import Observer, ReleaseRound, notify
from hydrojam.fem.solver.linsolve import LinearSolver
from hydrojam.fem.solver.newton import NewtonOptions, NewtonStatus, Timings, minimize
from hydrojam.fem.solver.total import physical_residual


@dataclass(frozen=True)
class ReleaseOptions:
    """Taking a damped term (a viscous stabilisation, the term "stabilisation" of a load path) off at a
    state by proximal rounds (:func:`release`): minimise with the damping centred on the last
    state and every lagged quantity (friction) frozen there, again and again, the damping lowered
    ``lower`` times after every converged round and raised ``growth`` times after a failed one, until the
    residual of the physics alone (the damped term left out) is within the Newton tolerance
    (rtol x the forces in play): the state is then an equilibrium without the damping.
    """

    each_step: bool = True
    """Release at every accepted load step, so that every state the path reports is an
    equilibrium of the physics alone and the next step starts from one. False: only the caller
    releases (at the end of the path), and the path's states are stabilised states."""
    max_rounds: int = 240
    """Most rounds of one release; a release that runs out is not released."""
    lower: float = 10.0
    """Divisor of the damping after a converged round."""
    growth: float = 10.0
    """Factor on the damping after a failed round (up to ``cap``)."""
    easy_after_failure: int = 20
    """After a failed round the damping is lowered again after a round of at most this many Newton
    iterations, or after ``backoff_rounds`` x 2^(f-1) converged rounds in a row at its level (f:
    the failed rounds so far): a state still travelling would otherwise alternate between a round
    that converges and a lower one that fails, or creep at a high damping for many rounds."""
    backoff_rounds: int = 4
    """See ``easy_after_failure``."""
    cap: float = 1e3
    """Highest damping, relative to the damped term's scale at the start of the path. A round that
    runs out of iterations is kept as progress at any damping (its last iterate is admissible and
    lower in energy: the next round is centred there); any other failure at the cap (no
    admissible descent) ends the release, not released."""
    floor: float = 1e-8
    """Lowest damping, relative to the damped term's scale at the start of the path."""


@dataclass(frozen=True)
class ReleaseState:
    """A release between two rounds (what it takes to go on): the next round's centre x (n, d)
    [mm], Newton iterations so far, the next round's damping ``scale`` (the term's own, absolute),
    whether a round has failed since the damping was last lowered, the rounds so far as
    (scale, iterations, converged), the linear solver's union pattern and the Newton work so far."""

    x: np.ndarray
    iterations: int
    scale: float
    failed: bool
    rounds: tuple[tuple[float, int, bool], ...]
    solver_pattern: tuple[np.ndarray, np.ndarray] | None = None
    timings: Timings | None = None


@dataclass(frozen=True)
class ReleaseResult:
    """Outcome of :func:`release`: the state x (n, d) [mm] (the last converged round's, or a kept
    failed round's), Newton iterations of all rounds, whether the damping is off (``released``),
    the rounds as (scale, iterations, converged), the physics' residual [N] at x and its
    tolerance [N], and the Newton work."""

    x: np.ndarray
    iterations: int
    released: bool
    rounds: list[tuple[float, int, bool]]
    residual: float
    tolerance: float
    timings: Timings


def _held_since_failure(rounds, k: int) -> bool:
    """Whether the converged rounds since the last failed one (``rounds``: (scale, iterations,
    converged)) number k 2^(f-1), f the failed rounds so far."""
    failures = sum(1 for r in rounds if not r[2])
    held = next((i for i, r in enumerate(reversed(rounds)) if not r[2]), len(rounds))
    return failures > 0 and held >= k * 2 ** (failures - 1)


def release(terms, damped, x: np.ndarray, free: np.ndarray, force_scale: float, newton: NewtonOptions,
            solver: LinearSolver | None = None, options: ReleaseOptions = ReleaseOptions(), base_scale: float = 1.0,
            unphysical: tuple[str, ...] = ("stabilisation",), resume: ReleaseState | None = None,
            on_round: Callable[[ReleaseState], None] | None = None,
            observers: Sequence[Observer] = ()) -> ReleaseResult:
    """Take the damped term ``damped`` (one of ``terms``, with a ``scale``) off at positions x
    (n, d) [mm] by proximal rounds (:class:`ReleaseOptions`), from its present scale.

    Before the first round the state is tested as it is: an undamped step, or one that barely
    moved, is released without a round. ``base_scale``: the damped term's scale at the start of the path, to which
    ``options.cap`` and ``options.floor`` are relative. The damped term's scale is left where the
    last round set it. ``on_round(state)`` after every round that the release goes on from (``observers`` see
    every round: :class:`~hydrojam.fem.solver.events.ReleaseRound`);
    ``resume``: such a state to go on from (``x`` unused). ``solver``: the linear solver
    the rounds' Newton solves share (a new one where None)."""
    solver = solver or LinearSolver(newton.linear_solver, observers)
    shape = np.shape(x)
    its, scale, rounds, failed = 0, float(damped.scale), [], False
    spent = Timings()
    x = np.array(x, dtype=float)
    if resume is not None:
        x, its, scale, failed, rounds = (np.array(resume.x, dtype=float).reshape(shape), resume.iterations,
                                         resume.scale, resume.failed, list(resume.rounds))
        solver.restore_pattern(resume.solver_pattern)
        if resume.timings is not None:
            spent.add(resume.timings)
    cap = options.cap * base_scale

    def result(ok, checked=None):
        r, tol = checked or physical_residual(terms, x, free, force_scale, newton.rtol, unphysical,
                                              newton.residual_floor)
        return ReleaseResult(x, its, ok, rounds, r, tol, spent)

    def equilibrium(roundoff: bool = False):
        """(residual, tolerance) of the physics at x where it is an equilibrium: within its
        tolerance, or, after a round that stopped at the energy's round-off (``roundoff``), with no
        viscous force above it left (the physics is then at its round-off too); None otherwise."""
        r, tol = physical_residual(terms, x, free, force_scale, newton.rtol, unphysical, newton.residual_floor)
        if r <= tol or (roundoff and float(np.linalg.norm(damped.gradient(x)[free])) <= tol):
            return r, tol
        return None

    if resume is None and (checked := equilibrium()):
        return result(True, checked)
    for _ in range(options.max_rounds - len(rounds)):
        damped.scale = scale
        for t in terms:  # each round is a step: the damping centred and lagged quantities frozen at its start
            t.begin_step(x)
        res = minimize(terms, x, free, force_scale, newton, solver, observers)
        its += res.iterations
        spent.add(res.timings)
        rounds.append((scale, res.iterations, res.converged))
        if observers:
            notify(observers, "on_release_round", ReleaseRound(scale, res.iterations, res.converged))
        if not res.converged:
            ran_out = res.status is NewtonStatus.MAX_ITERATIONS
            if scale >= cap * (1 - 1e-12) and not ran_out:
                return result(False)
            if ran_out:
                x = res.x
            scale = min(scale * options.growth, cap)
            failed = True
        else:
            x = res.x
            if checked := equilibrium(res.status is not NewtonStatus.CONVERGED):
                return result(True, checked)
            if (not failed or res.iterations <= options.easy_after_failure
                    or _held_since_failure(rounds, options.backoff_rounds)):
                scale = max(scale / options.lower, options.floor * base_scale)
                failed = False
        if on_round is not None:
            on_round(ReleaseState(np.array(x, dtype=float), its, scale, failed, tuple(rounds), solver.pattern,
                                  dataclasses.replace(spent)))
    return result(False)
