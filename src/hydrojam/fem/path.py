"""The adaptive load path (docs/solver.md, "Load path"): s from 0 to 1 in increments, each a Newton
minimisation (:mod:`hydrojam.fem.newton`) of a :class:`~hydrojam.fem.problem.Problem`'s terms."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from hydrojam.fem._env import blas_limited
from hydrojam.fem.linsolve import LinearSolver, LinearSolveError
from hydrojam.fem.newton import (NewtonOptions, NewtonResult, NewtonStatus, Timings, lowest_mode, minimize,
                                 negative_curvature, sum_energy)
from hydrojam.fem.problem import Problem
from hydrojam.fem.terms import DampedTerm


@dataclass(frozen=True)
class ReleaseOptions:
    """Taking a damped term (a viscous stabilisation, :attr:`PathOptions.damped_term`) off at a
    state by proximal rounds (:func:`release`): minimise with the damping centred on the last
    state and every lagged quantity (friction) frozen there, again and again, the damping lowered
    ``lower``x after every converged round and raised ``growth``x after a failed one, until the
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
class PathOptions:
    """Adaptive load stepping in s: grow ``grow``x after easy steps (<= ``easy_iterations``),
    halve on failure (and grow back after it: ``recover``); below ``ds_min`` one last attempt
    with ``last_resort_factor`` x the Newton iteration budget, then give up."""

    ds0: float = 0.25
    ds_min: float = 1e-4
    ds_max: float = 1.0
    grow: float = 1.5
    easy_iterations: int = 6
    newton: NewtonOptions = NewtonOptions()
    last_resort_factor: int = 10
    """The last attempt's Newton budget, in units of ``newton.max_iter``."""
    end_tolerance: float = 1e-12
    """s within this of 1 counts as the end of the path."""
    recover: bool = True
    """After a cut, every accepted step grows the increment ``grow``x again, easy or not, up to
    the largest increment that was cut (an easy step may still grow it further). Without it
    only easy steps grow the increment, and a path whose steps all take more than
    ``easy_iterations`` (3D actuators) never recovers from a cut (docs/solver.md, "Recovery
    after a cut"). A path without a cut is not touched, to the bit."""
    stability_check: bool = True
    """Count the negative eigenvalues of the physical Hessian at every accepted state
    (:func:`~hydrojam.fem.newton.negative_curvature`, one more factorisation a step; see
    :attr:`StepRecord.negative_eigenvalues`)."""
    unphysical_terms: tuple[str, ...] = ("stabilisation",)
    """Names of the terms that are not physics (a viscous stabilisation): left out of the
    stability check."""
    settle: str = "final"
    """Where a state found unstable by the stability check (a saddle: Newton converges to any
    stationary point) is moved off it to a stable one (:func:`settle`): "final" (the end of the
    path), "every" (every accepted state) or "never"."""
    settle_perturbation: float = 1e-5
    """The first move along an unstable state's mode, as the largest nodal move relative to the
    reference's bounding box diagonal (doubled while the energy falls, :func:`settle`)."""
    damped_term: str = "stabilisation"
    """Name of the term whose ``scale`` (a viscous stabilisation's) the adaptive damping sets."""
    damping_growth: float = 10.0
    """Adaptive damping (as ABAQUS's adaptive automatic stabilisation): a step whose Newton
    minimisation fails (out of iterations, no descent) is retried at the same increment with the
    damped term's scale times this (up to ``max_damping``) before the increment is cut; every
    easy step divides it again, down to where the path started. 1: off. A snap that the weak
    damping lets travel far within one step then travels in several damped steps."""
    max_damping: float = 100.0
    """Largest scale of the damped term, relative to the scale it was built with."""
    damping_start: float = 1.0
    """The damped term's scale where the path starts and to which easy steps lower it again,
    relative to the scale it was built with. 0: every step is first tried undamped, and the
    damping (the built scale, then ``damping_growth`` times more) comes in only for a step that fails
    without it, as ABAQUS's adaptive automatic stabilisation."""
    extrapolate: bool = True
    """Start every step after the first from the linear extrapolation of the last increment (the
    positions' change over the last accepted step, scaled to this one's ds; ABAQUS's default
    predictor), shortened (1, 1/2, 1/4, 0) until admissible and collision-free like any step."""
    undamped_blocks: int = 1
    """An undamped attempt (the damped term at scale 0, :attr:`damping_start` 0) that runs out of
    iterations goes on from its last iterate (admissible, and lower in energy) for up to this many
    blocks of ``newton.max_iter`` iterations in all before the damping comes in: a snap must
    travel, and undamped Newton travels it without the release a damped step then needs. 1: off."""
    damped_from_blocks: bool = False
    """Where the last undamped block ran out too, the damped attempts of the step start from its
    last iterate, with the lagged quantities (friction, the damping's centre) frozen there as at
    a step's start, instead of from the step's start: the blocks' travel is kept, and the damping
    does not hold the state back to where the step began."""
    release: ReleaseOptions = ReleaseOptions()
    """How the damped term is taken off at every accepted step (:class:`ReleaseOptions`)."""
    damping_relax_after: int = 0
    """With N > 0, a raised damping is also divided by ``damping_growth`` after N accepted steps
    in a row at its level, easy or not (as :attr:`recover` for the increment); 0: only easy
    steps lower it. A path whose damping was never raised is not touched, to the bit. Off in
    these generic defaults; the actuator's path (:data:`hydrojam.actuator.simulate.ACTUATOR_PATH`)
    relaxes after every step, since it starts every step undamped (docs/solver.md, "Relaxing the damping")."""


@dataclass(frozen=True)
class StepRecord:
    """One accepted load step: s reached, increment ds, Newton iterations, residual [N], energy
    [mJ], wall time [s] and the stability of the state reached (``negative_eigenvalues``)."""

    s: float
    ds: float
    iterations: int
    residual: float
    energy: float
    seconds: float
    negative_eigenvalues: int | None = None
    """Negative eigenvalues of the physical energy's unprojected Hessian over the free DOFs at
    the accepted state (terms in ``PathOptions.unphysical_terms`` left out): 0 for a stable
    equilibrium; > 0 where the state is not a minimum of the physics (the path passes an
    instability: a saddle reached by symmetry, or a state the stabilisation holds while it
    travels through a snap). None without the check or without the inertia (SciPy)."""
    damping: float | None = None
    """Scale of the damped term (``PathOptions.damped_term``) in the step, relative to its scale
    at the start of the path (1 unless the adaptive damping raised it); None without the term."""
    rejected: int = 0
    """Attempts at this step that failed before it was accepted (each raised the damping or cut
    the increment); 0 in a record written before it was kept."""
    tolerance: float | None = None
    """The residual tolerance [N] that ``residual`` is held to (rtol x the forces in play at the
    state); None in a record written before it was kept."""
    release_rounds: int = 0
    """Proximal rounds that took the damped term off at this step (:func:`release`); their Newton
    iterations are counted in ``iterations``."""
    release_iterations: int = 0
    """Newton iterations of those rounds (part of ``iterations``)."""
    damped_energy: float = 0.0
    """Energy [mJ] of the damped term at the stabilised state the step converged to, before its
    release: what the stabilisation held back in the step."""


@dataclass(frozen=True)
class PathResult:
    """Outcome of a load path: the last converged state and the step history."""

    x: np.ndarray  # last converged positions (n, d) [mm]
    s: float  # load parameter reached
    converged: bool  # reached s = 1
    message: str
    history: list[StepRecord]
    timings: Timings
    rejected_steps: int

    @property
    def newton_iterations(self) -> int:
        """Newton iterations of all accepted steps."""
        return sum(h.iterations for h in self.history)

    @property
    def unstable_at_s(self) -> float | None:
        """Load parameter of the first accepted state with a negative eigenvalue of the physical
        Hessian (:attr:`StepRecord.negative_eigenvalues`); None if there is none."""
        return first_unstable_s(self.history)


@dataclass(frozen=True)
class PathCheckpoint:
    """Everything :func:`solve_path` needs to go on from an accepted state as if it had not
    stopped: positions x (flat) [mm], load parameter s, the next increment ds, the damped term's
    scale relative to its start (``damping``), the accepted steps so far, the rejected attempts
    and the time spent."""

    x: np.ndarray
    s: float
    ds: float
    damping: float
    history: tuple[StepRecord, ...]
    rejected: int
    timings: Timings
    solver_pattern: tuple[np.ndarray, np.ndarray] | None = None
    """The linear solver's union pattern (:attr:`~hydrojam.fem.linsolve.LinearSolver.pattern`):
    restored, the resumed path sees the same matrices' patterns, hence the same round-off."""
    ds_cut: float | None = 0.0
    """The largest increment cut so far, to which :attr:`PathOptions.recover` grows back (0: none
    cut); None where unknown (a checkpoint written before it was kept): taken as the path's
    first increment ``ds0`` if any step was rejected, else 0."""
    previous: tuple[np.ndarray, float] | None = None
    """The accepted state before this one (flat positions [mm]) and the increment between them: the
    extrapolation's (:attr:`PathOptions.extrapolate`); None at the first step or where unknown."""


def _steps_at(history, damping: float) -> int:
    """Accepted steps in a row, the last ones, whose damping scale is ``damping``, counted back to
    the last step that failed first (where the damping may have been raised back to this level
    after a relaxation that failed: the count starts again there)."""
    n = 0
    for rec in reversed(history):
        if rec.damping is None or abs(rec.damping - damping) > 1e-9 * damping:
            break
        n += 1
        if rec.rejected:
            break
    return n


def first_unstable_s(history) -> float | None:
    """The ``s`` of the first record in ``history`` (:class:`StepRecord`-like: ``s``,
    ``negative_eigenvalues``) with a negative eigenvalue; None if there is none."""
    for h in history:
        if h.negative_eigenvalues:
            return h.s
    return None


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


def physical_residual(terms, x: np.ndarray, free: np.ndarray, force_scale: float, options: NewtonOptions,
                      unphysical: tuple[str, ...] = ("stabilisation",)) -> tuple[float, float]:
    """(residual, tolerance) [N] of the physics alone at x (n, d) [mm]: the norm over the free
    DOFs of the summed gradients of ``terms`` whose names are not in ``unphysical``, and the Newton
    tolerance for it (rtol x the largest such term's forces in play, floored at round-off)."""
    xs = np.asarray(x, dtype=float)
    fidx = np.flatnonzero(free)
    physical = [t for t in terms if t.name not in unphysical]
    grads = [t.gradient(xs) for t in physical]
    in_play = max(float(np.linalg.norm(t.force_flux(xs, g)[fidx])) for t, g in zip(physical, grads))
    return (float(np.linalg.norm(sum(grads)[fidx])),
            max(options.rtol * in_play, options.residual_floor * force_scale))


def _held_since_failure(rounds, k: int) -> bool:
    """Whether the converged rounds since the last failed one (``rounds``: (scale, iterations,
    converged)) number k 2^(f-1), f the failed rounds so far."""
    failures = sum(1 for r in rounds if not r[2])
    held = next((i for i, r in enumerate(reversed(rounds)) if not r[2]), len(rounds))
    return failures > 0 and held >= k * 2 ** (failures - 1)


def release(terms, damped, x: np.ndarray, free: np.ndarray, force_scale: float, newton: NewtonOptions,
            solver: LinearSolver, options: ReleaseOptions = ReleaseOptions(), base_scale: float = 1.0,
            unphysical: tuple[str, ...] = ("stabilisation",), resume: ReleaseState | None = None,
            on_round: Callable[[ReleaseState], None] | None = None) -> ReleaseResult:
    """Take the damped term ``damped`` (one of ``terms``, with a ``scale``) off at positions x
    (n, d) [mm] by proximal rounds (:class:`ReleaseOptions`), from its present scale.

    Before the first round the state is tested as it is: an undamped step, or one that barely
    moved, is released without a round. ``base_scale``: the damped term's scale at the start of the path, to which
    ``options.cap`` and ``options.floor`` are relative. The damped term's scale is left where the
    last round set it. ``on_round(state)`` after every round that the release goes on from;
    ``resume``: such a state to go on from (``x`` unused)."""
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
        r, tol = checked or physical_residual(terms, x, free, force_scale, newton, unphysical)
        return ReleaseResult(x, its, ok, rounds, r, tol, spent)

    def equilibrium(roundoff: bool = False):
        """(residual, tolerance) of the physics at x where it is an equilibrium: within its
        tolerance, or, after a round that stopped at the energy's round-off (``roundoff``), with no
        viscous force above it left (the physics is then at its round-off too); None otherwise."""
        r, tol = physical_residual(terms, x, free, force_scale, newton, unphysical)
        if r <= tol or (roundoff and float(np.linalg.norm(damped.gradient(x)[free])) <= tol):
            return r, tol
        return None

    if resume is None and (checked := equilibrium()):
        return result(True, checked)
    for _ in range(options.max_rounds - len(rounds)):
        damped.scale = scale
        for t in terms:  # each round is a step: the damping centred and lagged quantities frozen at its start
            t.begin_step(x)
        res = minimize(terms, x, free, force_scale, newton, solver)
        its += res.iterations
        spent.add(res.timings)
        rounds.append((scale, res.iterations, res.converged))
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


def _safe_move(terms, x: np.ndarray, step: np.ndarray) -> bool:
    """Whether the move from x by ``step`` (both (n, d) [mm]) is collision-free in full (no term's
    step cap, contact CCD, cuts it) and lands on a state of finite energy (admissible)."""
    return min([1.0] + [t.max_step(x, step) for t in terms]) >= 1.0 and np.isfinite(sum_energy(terms, x + step))


def _predictor(problem, terms, x, x_bc, free, solver):
    """Start of a load step whose prescribed DOFs move (x -> x_bc on them): the linearised response
    of the free DOFs, shortened until the move from x is admissible and collision-free (every
    term's step cap, so contact CCD sees the predictor like any Newton step). None if even moving
    the prescribed DOFs alone is not."""
    shape = problem.X.shape
    delta = x_bc - x
    if not np.any(delta):
        return x_bc
    fidx = np.flatnonzero(free)
    xs = x.reshape(shape)
    du = None
    H = sp.csr_matrix(sum(t.hessian(xs, True) for t in terms))
    try:
        du = solver.solve(H[fidx][:, fidx], -(H[fidx] @ delta))
    except LinearSolveError:
        pass
    for scale in (1.0, 0.5, 0.25, 0.0) if du is not None else (0.0,):
        trial = x_bc.copy()
        if scale:
            trial[fidx] += scale * du
        if _safe_move(terms, xs, (trial - x).reshape(shape)):
            return trial
    return None


def _extrapolated(terms, x, x_start, previous, ds, free, shape):
    """``x_start`` (flat [mm]) moved on the free DOFs by the last accepted increment (x - x_prev
    over ds_prev, ``previous`` = (x_prev, ds_prev)) scaled to ``ds``, shortened (1, 1/2, 1/4)
    until every term admits it and caps no part of it (contact CCD); ``x_start`` if none does."""
    x_prev, ds_prev = previous
    if ds_prev <= 0:
        return x_start
    delta = np.where(free, (x - np.asarray(x_prev).ravel()) * (ds / ds_prev), 0.0)
    if not np.any(delta):
        return x_start
    xs = x_start.reshape(shape)
    for scale in (1.0, 0.5, 0.25):
        if _safe_move(terms, xs, (scale * delta).reshape(shape)):
            return x_start + scale * delta
    return x_start


@dataclass(frozen=True)
class Settled:
    """Outcome of :func:`settle`: positions x (n, d) [mm], the negative eigenvalues left there,
    Newton iterations, the physics' residual and tolerance [N] and the Newton work."""

    x: np.ndarray
    negative: int | None
    iterations: int
    residual: float
    tolerance: float
    timings: Timings


def _down_the_mode(terms, x: np.ndarray, mode: np.ndarray, first: float, longest: float) -> np.ndarray | None:
    """The lowest-energy state of x + a mode (x (n, d) [mm]; mode (n, d), largest nodal move 1)
    over a = ``first`` x 2^k <= ``longest`` [mm], the mode's sign taken downhill (g . mode <= 0),
    up to the bottom of its well or the step cap of the terms (contact CCD): every trial
    collision-free and admissible. None where no trial lowers the energy."""
    g = sum(t.gradient(x) for t in terms).ravel()
    step = (-mode if g @ mode.ravel() > 0 else mode) * longest
    cap = min([1.0] + [t.max_step(x, step) for t in terms])
    E0 = sum_energy(terms, x)
    best, E_best = None, E0
    a = first / longest
    while a <= cap:
        E = sum_energy(terms, x + a * step)
        if not np.isfinite(E):
            break
        if E < E_best:
            best, E_best = a, E
        elif best is not None:  # past the bottom of the well
            break
        a *= 2.0
    return None if best is None else x + best * step


def settle(terms, x: np.ndarray, free: np.ndarray, force_scale: float, options: "PathOptions",
           solver: LinearSolver, checker: LinearSolver, tries: int = 3) -> Settled:
    """Move an unstable equilibrium x (n, d) [mm] of ``terms`` (the physics) off its saddle, along
    its unstable mode: the Hessian's lowest eigenpair (:func:`~hydrojam.fem.newton.lowest_mode`),
    followed downhill from a largest nodal move of ``options.settle_perturbation`` x the bounding
    box diagonal, doubled while the energy falls (:func:`_down_the_mode`), then the full Newton
    from the lowest state on it. Below the saddle's energy the monotone descent cannot come back
    to it. Up to ``tries`` times, from each unstable equilibrium reached; the result is the first
    stable state, or x itself with its count where none was reached."""
    xs = np.asarray(x, dtype=float)
    size = float(np.linalg.norm(xs.max(axis=0) - xs.min(axis=0)))
    spent, its = Timings(), 0
    negative, current = None, xs
    for _ in range(tries):
        value, mode = lowest_mode(terms, current, free, checker, options.newton)
        if not value < 0:
            break
        start = _down_the_mode(terms, current, mode, options.settle_perturbation * size, size)
        if start is None:
            break
        res = minimize(terms, start, free, force_scale, options.newton, solver)
        spent.add(res.timings)
        its += res.iterations
        if not res.converged:
            break
        negative = negative_curvature(terms, res.x, free, checker, options.newton)
        if negative == 0:
            r, tol = physical_residual(terms, res.x, free, force_scale, options.newton, ())
            return Settled(res.x, 0, its, r, tol, spent)
        current = res.x
    r, tol = physical_residual(terms, xs, free, force_scale, options.newton, ())
    return Settled(xs, negative, its, r, tol, spent)


@dataclass
class _Walk:
    """What :func:`solve_path` carries from one attempt to the next: the last accepted state, the
    increment and its history, the damped term's level, and an attempt that goes on (a run-out
    undamped block, or the damped attempts' restart)."""

    solver: LinearSolver
    checker: LinearSolver | None
    free: np.ndarray
    shape: tuple
    x: np.ndarray  # the last accepted state, flat [mm]
    newton: NewtonOptions
    damped: DampedTerm | None = None
    base: float | None = None  # the damped term's built scale
    s: float = 0.0
    ds: float = 0.0
    rejected: int = 0
    ds_cut: float = 0.0
    previous: tuple[np.ndarray, float] | None = None  # the last accepted state but one, and ds since
    history: list[StepRecord] = dataclasses.field(default_factory=list)
    timings: Timings = dataclasses.field(default_factory=Timings)
    last_resort: bool = False
    failed_here: int = 0
    carry: np.ndarray | None = None  # an undamped attempt that ran out, going on (undamped_blocks)
    carried: int = 0
    carried_its: int = 0
    restart: np.ndarray | None = None  # where the step's damped attempts start (damped_from_blocks)

    def result(self, converged: bool, message: str) -> PathResult:
        """The path's outcome at the last accepted state."""
        return PathResult(self.x.reshape(self.shape), self.s, converged, message, self.history, self.timings,
                          self.rejected)


@blas_limited
def solve_path(
    problem: Problem,
    options: PathOptions = PathOptions(),
    callback: Callable[[float, np.ndarray, StepRecord], None] | None = None,
    on_attempt: Callable[[float, float, NewtonResult], None] | None = None,
    resume: PathCheckpoint | None = None,
    on_checkpoint: Callable[[PathCheckpoint], None] | None = None,
) -> PathResult:
    """Follow s from 0 to 1 in adaptive increments, each an energy minimisation, from the
    reference positions.

    On failure below the minimum increment, returns with the last converged state and a message
    saying where and why. ``callback(s, x, record)`` runs after
    every accepted step, ``on_attempt(s_try, ds, newton_result)`` after every attempt (progress).
    Every term's ``begin_step`` runs at the start of the path (s = 0: nothing lagged survives
    from an earlier path on the same terms) and of every step. With
    ``options.stability_check`` every accepted state's physical Hessian is tested for negative
    eigenvalues (:attr:`StepRecord.negative_eigenvalues`, :attr:`PathResult.unstable_at_s`).
    A term named ``options.damped_term`` with a ``scale`` (a viscous stabilisation) is damped
    adaptively (:attr:`PathOptions.damping_growth`); its scale is left where the path ended.

    ``on_checkpoint(checkpoint)`` runs after every accepted step (after ``callback``) with what
    it takes to go on from there; ``resume``: such a checkpoint, from which the path goes on
    (the equilibration at s = 0 skipped) instead of starting from the reference positions.
    """
    walk = _start(problem, options, resume)
    if isinstance(walk, PathResult):
        return walk
    while walk.s < 1.0 - options.end_tolerance:
        walk.ds = min(walk.ds, 1.0 - walk.s)
        s_try = walk.s + walk.ds
        t0 = time.perf_counter()
        terms, res = _attempt(problem, walk, s_try, options)
        walk.timings.add(res.timings)
        if on_attempt is not None:
            on_attempt(s_try, walk.ds, res)
        rel = None
        damped = walk.damped
        damped_energy = 0.0 if damped is None or not res.converged else damped.energy(res.x)
        if res.converged and damped is not None and options.release.each_step:
            path_scale = damped.scale
            rel = release(terms, damped, res.x, walk.free, problem.force_scale, options.newton, walk.solver,
                          options.release, walk.base, options.unphysical_terms)
            walk.timings.add(rel.timings)
            damped.scale = path_scale
        if res.converged and (rel is None or rel.released):
            _accept(problem, walk, s_try, terms, res, rel, damped_energy, t0, options, callback, on_checkpoint)
        else:
            stop = _reject(walk, s_try, res, rel, options)
            if stop is not None:
                return stop
    return walk.result(True, "converged")


def _start(problem: Problem, options: PathOptions, resume: PathCheckpoint | None) -> _Walk | PathResult:
    """The walk at s = 0 (the reference positions equilibrated, every lagged quantity begun there)
    or at ``resume``'s state; a PathResult where s = 0 cannot be equilibrated."""
    solver = LinearSolver(options.newton.linear_solver)
    # the stability check's own solver: its matrices never touch the Newton solver's pattern
    # and analysis, so the check leaves the path's round-off as it was
    checker = LinearSolver(options.newton.linear_solver) if options.stability_check else None
    x = problem.X.ravel().copy()
    problem.apply_dirichlet(x, 0.0)
    walk = _Walk(solver, checker, problem.free_mask(), problem.X.shape, x, options.newton, ds=options.ds0)
    terms0 = problem.terms(0.0)
    damped = next((t for t in terms0 if t.name == options.damped_term), None)
    if isinstance(damped, DampedTerm) and damped.scale:  # none, or one switched off: nothing to adapt
        walk.damped, walk.base = damped, damped.scale
        damped.scale = walk.base * options.damping_start
    if resume is None:
        for t in terms0:  # nothing lagged (friction) survives from an earlier path on the same terms
            t.begin_step(x.reshape(walk.shape))
        res0 = minimize(terms0, x.reshape(walk.shape), walk.free, problem.force_scale, options.newton, solver)
        walk.timings.add(res0.timings)
        if not res0.converged:
            return walk.result(False, f"could not equilibrate the initial state (s = 0): {res0.message}")
        walk.x = res0.x.ravel().copy()
        return walk
    walk.x = np.asarray(resume.x, dtype=float).ravel().copy()
    walk.previous = resume.previous
    walk.s, walk.ds, walk.rejected = float(resume.s), float(resume.ds), int(resume.rejected)
    walk.ds_cut = float(resume.ds_cut) if resume.ds_cut is not None else (options.ds0 if walk.rejected else 0.0)
    walk.history.extend(resume.history)
    walk.timings.add(resume.timings)
    solver.restore_pattern(resume.solver_pattern)
    if walk.damped is not None:
        walk.damped.scale = walk.base * resume.damping
    return walk


def _attempt(problem: Problem, walk: _Walk, s_try: float, options: PathOptions):
    """One attempt at the step to ``s_try``: (its terms, Newton's result). Lagged quantities
    (friction, stabilisation) freeze at the step's start, or where its damped attempts restart;
    Newton starts from a run-out block's last iterate, that restart, or the predicted (and
    extrapolated) state."""
    x, shape = walk.x, walk.shape
    terms = problem.terms(s_try)
    x_bc = x.copy()
    problem.apply_dirichlet(x_bc, s_try)
    for t in terms:
        t.begin_step((x if walk.restart is None else walk.restart).reshape(shape))
    if walk.carry is not None:
        x_start = walk.carry
    elif walk.restart is not None:
        x_start = walk.restart
    else:
        x_start = _predictor(problem, terms, x, x_bc, walk.free, walk.solver)
        if x_start is not None and walk.previous is not None and options.extrapolate:
            x_start = _extrapolated(terms, x, x_start, walk.previous, walk.ds, walk.free, shape)
    if x_start is None:
        return terms, NewtonResult(x.reshape(shape), NewtonStatus.INADMISSIBLE_START, 0, np.inf, np.inf,
                                   "the prescribed displacement increment is not admissible", [], Timings())
    return terms, minimize(terms, x_start.reshape(shape), walk.free, problem.force_scale, walk.newton, walk.solver)


def _accept(problem: Problem, walk: _Walk, s_try: float, terms, res: NewtonResult, rel: ReleaseResult | None,
            damped_energy: float, t0: float, options: PathOptions, callback, on_checkpoint) -> None:
    """Accept the step to ``s_try``: its state (released, and settled off a saddle where asked),
    its record and the callbacks, the next increment and damping, the checkpoint."""
    walk.newton, walk.last_resort = options.newton, False
    walk.s = s_try
    x_new = res.x if rel is None else rel.x
    walk.previous = (walk.x, walk.ds)
    walk.x = x_new.ravel().copy()
    negative = None
    its = walk.carried_its + res.iterations + (0 if rel is None else rel.iterations)
    walk.carry, walk.carried, walk.carried_its, walk.restart = None, 0, 0, None
    if rel is not None:
        residual, tolerance = rel.residual, rel.tolerance
    else:  # undamped, or a stabilised state whose residual includes the viscous force
        tolerance = physical_residual(terms, x_new, walk.free, problem.force_scale, options.newton, ())[1]
        residual = res.residual
    if walk.checker is not None:
        physical = [t for t in terms if t.name not in options.unphysical_terms]
        negative = negative_curvature(physical, x_new, walk.free, walk.checker, options.newton)
        final = walk.s >= 1.0 - options.end_tolerance
        if negative and (options.settle == "every" or (options.settle == "final" and final)):
            settled = settle(physical, x_new, walk.free, problem.force_scale, options, walk.solver, walk.checker)
            walk.timings.add(settled.timings)
            its += settled.iterations
            if settled.negative == 0:
                x_new, negative = settled.x, 0
                walk.x = x_new.ravel().copy()
                residual, tolerance = settled.residual, settled.tolerance
    damped, base = walk.damped, walk.base
    energy = res.energy if x_new is res.x else sum_energy(terms, x_new)
    rec = StepRecord(walk.s, walk.ds, its, residual, energy,
                     time.perf_counter() - t0, negative, None if damped is None else damped.scale / base,
                     walk.failed_here, tolerance, 0 if rel is None else len(rel.rounds),
                     0 if rel is None else rel.iterations, damped_energy)
    walk.failed_here = 0
    walk.history.append(rec)
    if callback is not None:
        callback(walk.s, x_new, rec)
    easy = its <= options.easy_iterations
    if easy:
        walk.ds = min(walk.ds * options.grow, options.ds_max)
    elif options.recover and walk.ds < walk.ds_cut:
        walk.ds = min(walk.ds * options.grow, walk.ds_cut)
    lowest = None if damped is None else base * options.damping_start
    if damped is not None and damped.scale > lowest and (
            easy or (options.damping_relax_after > 0
                     and _steps_at(walk.history, damped.scale / base) >= options.damping_relax_after)):
        damped.scale = (lowest if damped.scale <= base * (1 + 1e-12)
                        else max(damped.scale / options.damping_growth, base))
    if on_checkpoint is not None:
        on_checkpoint(PathCheckpoint(walk.x.copy(), walk.s, walk.ds, 1.0 if damped is None else damped.scale / base,
                                     tuple(walk.history), walk.rejected, dataclasses.replace(walk.timings),
                                     walk.solver.pattern, walk.ds_cut, walk.previous))


def _reject(walk: _Walk, s_try: float, res: NewtonResult, rel: ReleaseResult | None,
            options: PathOptions) -> PathResult | None:
    """What follows a failed attempt at ``s_try``: an undamped block that ran out goes on, a
    damped retry of the same increment, the increment halved, one last long attempt at the
    smallest one; the path's (failed) result where none is left, else None (try again)."""
    damped, base = walk.damped, walk.base
    ran_out_undamped = damped is not None and damped.scale == 0 and res.status is NewtonStatus.MAX_ITERATIONS
    if ran_out_undamped and walk.carried + 1 < options.undamped_blocks:
        walk.carry, walk.carried = res.x.ravel().copy(), walk.carried + 1
        walk.carried_its += res.iterations
        return None
    if ran_out_undamped and options.damped_from_blocks:
        walk.restart, walk.carried_its = res.x.ravel().copy(), walk.carried_its + res.iterations
    elif walk.restart is None:
        walk.carried_its = 0
    walk.carry, walk.carried = None, 0
    walk.rejected += 1
    walk.failed_here += 1
    if rel is not None:  # the step converged stabilised but could not be released: a shorter one
        res = dataclasses.replace(res, status=NewtonStatus.MAX_ITERATIONS, message=(
            f"the stabilisation could not be released in {len(rel.rounds)} rounds"))
        return _halve(walk, s_try, res, options, long_attempt=False)
    if (damped is not None and res.status is not NewtonStatus.INADMISSIBLE_START and options.damping_growth > 1
            and damped.scale * options.damping_growth <= options.max_damping * base * (1 + 1e-12)):
        # retry the same increment, more damped (an undamped attempt: at the built damping)
        damped.scale = base if damped.scale < base else damped.scale * options.damping_growth
        return None
    return _halve(walk, s_try, res, options, long_attempt=True)


def _halve(walk: _Walk, s_try: float, res: NewtonResult, options: PathOptions,
           long_attempt: bool) -> PathResult | None:
    """Halve the increment after the failed attempt ``res`` at ``s_try``; below ``ds_min`` one last
    attempt with a long Newton budget where Newton ran out (``long_attempt``), else the path ends
    (its result, the last converged state kept). None: try again."""
    walk.ds_cut = max(walk.ds_cut, walk.ds)
    walk.ds *= 0.5
    walk.restart, walk.carried_its = None, 0
    if (long_attempt and walk.ds < options.ds_min and not walk.last_resort
            and res.status is NewtonStatus.MAX_ITERATIONS):
        # A snap (jammed particles rearranging) has no nearby equilibrium: the state must
        # travel, which takes many iterations, not a smaller increment. One long attempt.
        walk.last_resort, walk.ds = True, 2.0 * walk.ds
        walk.newton = dataclasses.replace(options.newton,
                                          max_iter=options.last_resort_factor * options.newton.max_iter)
        return None
    if walk.ds < options.ds_min:
        return walk.result(False, f"load step failed at s = {s_try:.6g} (increment {2 * walk.ds:.3g} < minimum "
                                  f"{options.ds_min:g}): {res.message}; last converged state kept at s = {walk.s:.6g}")
    return None
