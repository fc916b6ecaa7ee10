"""Energy minimisation by damped Newton (docs/solver.md, "Newton").

The solver knows only energy terms (:mod:`hydrojam.fem.terms`) and which DOFs are free. Every
accepted state has finite energy (admissible) and respects every term's step cap (contact CCD).
One iteration is: the forces and the convergence test, the Hessian, a *direction* (the damped,
regularised linear solve, :func:`_direction`), a *line search* (:func:`_line_search`) and the
*damping update* (:func:`_marquardt_update`). What a caller may set is a field of
:class:`NewtonOptions`; every other constant is named in this module (``DAMPING_GROWTH``,
``MARQUARDT_MIN``, ...); the outcome is a :class:`NewtonStatus`. Observers
(:mod:`hydrojam.fem.solver.events`) see every direction, line search and accepted iteration.

Convergence: the residual norm over free DOFs ||g_f|| <= ``rtol`` x the forces in play (the
largest term's ``force_flux``: a solid's internal-force flux |f_e| summed without the
cancellation of assembly, a load's or the contact's own force), but never below
``residual_floor`` x the problem's force scale (round-off of the residual: a stress-free mesh of
100 mm already shows 1e-13 N), or, once the residual is within ``stall_factor`` of that, a
Newton decrement below round-off of the energy or a line search that finds no representable
decrease. rtol = 1e-6 by default: six orders of magnitude below the acting forces (ABAQUS's
default is 5e-3); frictionless round particles have near-zero-stiffness rotation modes that a
tighter tolerance chases for hundreds of iterations without changing any result.
"""

from __future__ import annotations

import enum
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp

from hydrojam.fem._env import blas_limited
from hydrojam.fem.solver.events import Direction, Iteration, LineSearch, Observer, notify
from hydrojam.fem.solver.linsolve import LinearSolver, LinearSolveError, NotPositiveDefinite
from hydrojam.fem.solver.total import free_block, free_sum, residual_norm, sum_energy, tolerance
from hydrojam.fem.terms import EnergyTerm


#: Fixed constants of the iteration (measured once, docs/solver.md; no caller varies them).
#: Damped solves tried per iteration before the status SINGULAR.
DAMPING_ATTEMPTS = 16
#: Factor on the damping tau after a direction that fails (no solution, or no descent).
DAMPING_GROWTH = 10.0
#: tau's first non-zero value, relative to diag|H|.
DAMPING_FLOOR = 1e-8
#: tau's first non-zero value after an indefinite K (:attr:`NewtonOptions.definite`), relative to diag|H|.
DEFINITE_FLOOR = 1e-4
#: A Newton decrement below this x |E| is energy round-off: converged (undamped steps only).
DECREMENT_ROUNDOFF = 1e-14
#: The line search accepts an energy rise of this x |E| (round-off): full steps near convergence.
ENERGY_SLACK = 1e-12
#: Conjugate-gradient steps at most that solve an undamped step (tau = 0) on H itself, without
#: the regularisation, preconditioned by the regularised factorisation (:func:`_unshifted`).
UNSHIFTED_STEPS = 10
#: Factor on the step length after a rejected trial of the line search.
BACKTRACK = 0.5
#: Within ``stall_factor`` of the tolerance, a full step (no CCD cap) that fails the energy test
#: is still taken when it cuts the residual to this x ||g|| or less: there the energy change is
#: below the energy's round-off (a freely swelling gel's energy is a sum of cancelling terms),
#: and the residual is the reliable measure of progress.
RESIDUAL_ACCEPTANCE = 0.5
#: The Marquardt damping (:func:`_marquardt_update`): an accepted step shorter than
#: MARQUARDT_SHORT_STEP grows it MARQUARDT_GROWTH x, from MARQUARDT_MIN up to MARQUARDT_MAX
#: (relative to diag|H|); a full step (MARQUARDT_LONG_STEP) divides it by MARQUARDT_DECAY, and
#: drops it to 0 at or below MARQUARDT_CUTOFF.
MARQUARDT_SHORT_STEP, MARQUARDT_GROWTH, MARQUARDT_MIN, MARQUARDT_MAX = 0.1, 10.0, 1e-4, 1e4
MARQUARDT_LONG_STEP, MARQUARDT_DECAY, MARQUARDT_CUTOFF = 1.0, 10.0, 1e-6


@dataclass(frozen=True)
class NewtonOptions:
    """Newton settings: the convergence test, the linear solver, and the choices of the
    direction (inertia correction, where the contact Hessian starts, the step along negative
    curvature). The Hessian is the full one, shifted by tau diag|H| only while its step does not
    descend: projecting a stable but locally non-convex gel (every gel element under lateral
    constraint) discards real curvature (on a swelling layer element-wise projected Newton
    converges linearly where the full Hessian converges quadratically: docs/solver.md, "Choices").
    """

    rtol: float = 1e-6
    """Residual tolerance relative to the forces in play [-] (default 1e-6)."""
    max_iter: int = 40
    """Newton iterations before giving up with the status MAX_ITERATIONS (default 40)."""
    linear_solver: Literal["auto", "pardiso", "scipy"] = "auto"
    """The linear solver (:class:`~hydrojam.fem.solver.linsolve.LinearSolver`): PARDISO, SciPy's
    SuperLU, or "auto", PARDISO where it loads (default)."""
    residual_floor: float = 1e-10
    """Floor of the residual tolerance, times the problem's force scale: round-off of the residual
    (default 1e-10)."""
    stall_factor: float = 1e3
    """A residual within this factor of the tolerance may converge at energy round-off: a Newton
    decrement at round-off, or no representable descent left (default 1e3)."""
    armijo: float = 1e-4
    """Sufficient-decrease constant of the line search [-] (default 1e-4)."""
    min_alpha: float = 1e-8
    """Smallest step length the line search tries [-] (default 1e-8)."""
    regularisation: float = 1e-9
    """eps, times mean|diag H|, added to the diagonal of every factorised K: pins the rigid modes
    of a floating body, in which a singular solve returns an arbitrary drift that no residual
    check sees. An undamped step (tau = 0) is then solved on H itself by conjugate gradients
    preconditioned with that factorisation (:func:`_unshifted`), so the shift does not slow the
    convergence of a mode softer than it, such as a slender structure's bending (default 1e-9)."""
    linear_residual: float = 1e-6
    """A linear solve is accepted when ||K dx + g|| <= this x ||g|| (default 1e-6)."""
    residual_search: bool = False
    """Where a step's energy change lies within the round-off slack (:data:`ENERGY_SLACK` x |E|)
    of the decrease Armijo asks, the energy cannot judge the step: it is then taken only where it
    also lowers the residual (a full step near the tolerance: by :data:`RESIDUAL_ACCEPTANCE`).
    Energy changes at round-off cannot tell a step from its way back: without this, Newton
    cycled between states just above the tolerance until it ran out of iterations
    (docs/solver.md, "Newton"). Default False; the actuator's path: True."""
    definite: bool = False
    """Inertia correction: a damped system K with a negative eigenvalue (the linear solver's
    inertia, where it reports one) counts as a failed direction, so tau grows until K is positive
    definite and the step heads for a minimum, not for a saddle. Default False; the actuator's
    path: True."""
    fallback_start: Literal["full", "krylov_detect"] = "full"
    """Where the terms with ``fallback_projection`` (contact) start each iteration: "full" (default:
    their full Hessian first, projected only after a failed direction) or "krylov_detect" (with
    ``definite``; the actuator's path): the projected K is factorised first and preconditions a few
    conjugate-gradient steps on the full K that only detect its negative curvature; where they meet
    none, the full K is factorised and its solution taken if its factorisation shows it definite;
    after an iteration that took the full K's step, the full K is factorised first. The
    directions of "full" with fewer factorisations."""
    detect_iterations: int = 5
    """Conjugate-gradient iterations at most that look for the full K's negative curvature
    ("krylov_detect"; default 5): negative curvature shows within a few iterations or not at
    all, while converging on a definite K takes several more."""
    curvature_step: float = 0.0
    """With "krylov_detect": where the conjugate gradients met a direction p of negative curvature
    of the full K (p.K.p <= 0), the state after the line search is moved further along p, the
    sign that descends at the iterate, from a largest nodal move of ``curvature_step`` times the
    accepted step's, doubled while the energy falls, at most ``curvature_doublings`` times and
    within the terms' step cap (one CCD over the longest): the lowest state is kept. The
    projected K's step cannot see that curvature. Default 0: off (the actuator's path: 1, with
    one doubling)."""
    curvature_doublings: int = 3
    """Doublings at most of the negative-curvature step (``curvature_step``): up to 2**n times its
    first length (default 3)."""

    def __post_init__(self):
        if self.fallback_start not in ("full", "krylov_detect"):
            raise ValueError(f"fallback_start must be full or krylov_detect, not {self.fallback_start!r}")
        if self.linear_solver not in ("auto", "pardiso", "scipy"):
            raise ValueError(f"linear_solver must be auto, pardiso or scipy, not {self.linear_solver!r}")


class NewtonStatus(enum.Enum):
    """How a minimisation ended."""

    CONVERGED = "converged"
    """Residual within the tolerance."""
    CONVERGED_DECREMENT = "converged (decrement at round-off)"
    """Residual within stall_factor of the tolerance and the Newton decrement at energy round-off."""
    CONVERGED_NO_DESCENT = "converged (no descent left above round-off)"
    """Residual within stall_factor of the tolerance and no representable descent left."""
    MAX_ITERATIONS = "no convergence"
    """max_iter iterations without converging."""
    LINE_SEARCH_FAILED = "line search failed (no admissible descent)"
    """No admissible step along the direction decreases the energy."""
    SINGULAR = "linear solve failed (singular Hessian)"
    """No damped solve gave an accurate descent direction."""
    INADMISSIBLE_START = "initial state is inadmissible (infinite energy)"
    """The start has infinite energy (or, on the load path, the prescribed move is inadmissible)."""
    NOT_FINITE = "residual is not finite"
    """The forces are not finite."""

    @property
    def converged(self) -> bool:
        """True for CONVERGED and its round-off variants."""
        return self in (NewtonStatus.CONVERGED, NewtonStatus.CONVERGED_DECREMENT, NewtonStatus.CONVERGED_NO_DESCENT)


@dataclass
class Timings:
    """Wall time [s] by phase, accumulated over Newton iterations."""

    assembly: float = 0.0
    linear_solve: float = 0.0
    line_search: float = 0.0
    step_cap: float = 0.0
    iterations: int = 0

    def add(self, other: "Timings") -> None:
        """Add another record's times and iterations to this one."""
        for k in ("assembly", "linear_solve", "line_search", "step_cap", "iterations"):
            setattr(self, k, getattr(self, k) + getattr(other, k))


@dataclass(frozen=True)
class NewtonResult:
    """Outcome of one minimisation: positions x (n, d) [mm], how it ended (``status``, and
    ``message`` in words), residual [N] and energy [mJ] at x, the residual of every iteration."""

    x: np.ndarray
    status: NewtonStatus
    iterations: int
    residual: float
    energy: float
    message: str
    residuals: list[float]
    timings: Timings

    @property
    def converged(self) -> bool:
        """Whether the status is a converged one."""
        return self.status.converged


def _reach(terms, xs, fidx):
    """The linear solver's hint (:meth:`LinearSolver.solve`'s ``reach``): a callable giving the
    free block of the terms' Hessian patterns near xs, made only when asked (None where no term
    gives one)."""

    def reach():
        patterns = [p for t in terms if (p := t.hessian_pattern(xs)) is not None]
        return free_block(sum(patterns), fidx) if patterns else None

    return reach


def _direction(terms, xs, hessians, Hff, hdiag, g, r, lm, fidx, solver, options: NewtonOptions,
               full_first: bool = False):
    """The damped Newton direction: solve K dx = -g over the free DOFs with
    K = H + tau diag|H| + eps mean|diag H| I. ``hessians``: every term's Hessian at xs, as summed
    into H (the fallback re-assembles only the terms that ask for projection). Returns (dx or
    None if every attempt failed, slope g.dx, tau used, whether the fallback terms were
    projected in the accepted K, a direction of the full K's negative curvature that the
    conjugate gradients met, or None). ``full_first`` ("krylov_detect" only; the last iteration
    took the full K's step): the full K at ``lm`` is factorised first, and its solution taken
    where it is definite; otherwise the projected K's step follows without the conjugate
    gradients, which would only find again that the full K is not definite. Either way the
    direction is the one "krylov_detect" takes without it.

    Damping changes the step, never the equilibrium.
    - eps (``regularisation``), in every factorisation: a floating body's rigid modes are an
      exact null space, in which a singular solve returns an arbitrary drift that no residual
      check can see. An undamped step (tau = 0) is solved on H without eps where a few
      preconditioned conjugate gradients get there (:func:`_unshifted`): eps would otherwise
      damp every mode softer than it (a slender strip's bending) and Newton would converge
      there only linearly.
    - tau: starts at the Marquardt term ``lm`` and grows only while the step does not descend;
      with ``definite`` (the inertia correction) also while K has a negative eigenvalue.
      Projecting element Hessians instead discards the curvature of every gel element (each is
      non-convex alone while the assembly is stable: docs/solver.md, "Choices").
    """
    fallback = any(t.fallback_projection for t in terms)
    krylov = options.fallback_start == "krylov_detect" and options.definite and fallback
    reach = _reach(terms, xs, fidx)
    eps = options.regularisation * hdiag.mean()
    full_indefinite = False
    if krylov and full_first:
        # the projected K is the full one plus a positive semi-definite part: where the full K at
        # lm is definite, the projected one is too and the conjugate gradients meet no negative
        # curvature, so "krylov_detect" would take this solution
        K = Hff + sp.diags(lm * hdiag + eps, format="csr")
        cand, full_indefinite = _definite_solution(K, g, r, reach, solver, options, Hff if lm == 0 else None)
        if cand is not None:
            return cand, float(g @ cand), lm, False, None
    tau, dx, slope, Hfull, negative, projected = lm, None, 0.0, Hff, None, False
    for attempt in range(DAMPING_ATTEMPTS):
        if (attempt == 1 or krylov) and fallback and not projected:
            # the barrier's own negative curvature (b'(d) times the curvature of the distance)
            # is what makes a contact Hessian indefinite: project it per contact, as IPC does,
            # before damping the whole system (docs/solver.md, "Choices")
            Hff = free_sum([t.hessian(xs, True) if t.fallback_projection else h for t, h in zip(terms, hessians)], fidx)
            tau, projected = lm, True
        K = Hff + sp.diags(tau * hdiag + eps, format="csr")
        cand, indefinite = _accurate_solution(K, g, r, reach, solver, options, Hff if tau == 0 else None)
        if cand is not None:
            slope = float(g @ cand)
            indefinite = options.definite and bool(solver.negative_eigenvalues)
            if slope < 0 and not indefinite:
                dx = cand
                break
        tau = max(DAMPING_GROWTH * tau, DEFINITE_FLOOR if indefinite else DAMPING_FLOOR)
    if krylov and not full_indefinite and dx is not None and solver.negative_eigenvalues is not None and tau == lm:
        # "krylov_detect" follows "full": its full K is tried at the Marquardt damping only (the
        # full K is the projected one less the contacts' negative curvature, so where the
        # projected K needed more damping, the full one at lm is indefinite too)
        K = Hfull + sp.diags(tau * hdiag + eps, format="csr")
        _, negative = _conjugate_gradients(K, g, r, solver, options.detect_iterations, options)
        full = None if negative is not None else _definite_solution(K, g, r, reach, solver, options,
                                                                    Hfull if tau == 0 else None)[0]
        if full is not None:
            dx, slope, projected = full, float(g @ full), False
    return dx, slope, tau, projected, negative


def _accurate_solution(K, g, r, reach, solver, options: NewtonOptions, unshifted=None):
    """(dx, indefinite): the solution of K dx = -g by a factorisation where the solve succeeds and
    ||K dx + g|| <= linear_residual x r, None otherwise; indefinite where the inertia correction
    (``options.definite``) asked the solver for a positive definite K and it found it is not one
    (a failed Cholesky factorisation: the solution is not needed then). ``unshifted``: K without
    the regularisation (an undamped step), whose solution :func:`_unshifted` then takes where
    it gets there."""
    try:
        dx = solver.solve(K, -g, reach, definite=options.definite)
    except NotPositiveDefinite:
        return None, True
    except LinearSolveError:
        return None, False
    if np.linalg.norm(K @ dx + g) > options.linear_residual * r:
        return None, False
    if unshifted is not None and not (options.definite and solver.negative_eigenvalues):
        dx = _unshifted(unshifted, dx, g, r, solver, options)
    return dx, False


def _definite_solution(K, g, r, reach, solver, options: NewtonOptions, unshifted=None):
    """(dx, indefinite): :func:`_accurate_solution`'s dx where K is positive definite by its
    inertia and dx descends, None otherwise; indefinite where the factorisation showed K is not
    positive definite (a Cholesky's refusal, an LDL^T's negative eigenvalue)."""
    dx, refused = _accurate_solution(K, g, r, reach, solver, options, unshifted)
    if dx is None:
        return None, refused
    if solver.negative_eigenvalues:
        return None, True
    return (dx if g @ dx < 0 else None), False


def _unshifted(H, dx, g, r, solver, options: NewtonOptions):
    """The solution of H dx = -g (H without the regularisation eps) by at most
    :data:`UNSHIFTED_STEPS` conjugate gradients from ``dx`` (the regularised solution),
    preconditioned with the solver's last factorisation (H + eps mean|diag H| I): taken where
    ||H dx + g|| <= linear_residual x r and it descends, the given dx otherwise (H not positive
    definite along a search direction, or a floating body's null space, where the residual
    cannot fall and eps must hold the rigid modes).

    In the regularised solution a mode of H with eigenvalue lambda is short by eps/(lambda + eps):
    where eps exceeds a slender structure's bending stiffness, Newton converged there only
    linearly (docs/solver.md, "Choices"). Preconditioned, H has its spectrum at 1 but for the
    few modes about as soft as eps, which the conjugate gradients resolve in about as many
    steps."""
    target = options.linear_residual * r
    x, _ = _conjugate_gradients(H, g, r, solver, UNSHIFTED_STEPS, options, x0=dx)
    return x if x is not None and np.linalg.norm(H @ x + g) <= target and g @ x < 0 else dx


def _conjugate_gradients(K, g, r, solver, steps: int, options: NewtonOptions, x0=None):
    """K dx = -g by at most ``steps`` conjugate-gradient iterations preconditioned with the
    solver's last factorisation (a positive definite K nearby), from ``x0`` (default 0): (dx, p).
    dx once ||K dx + g|| <= linear_residual x r (``x0`` itself where it meets that already), else
    None; p the first search direction with curvature p.K.p <= 0 (K is not positive definite
    there; dx is None then), else None. Every iterate from dx = 0 descends (g.dx < 0)."""
    if x0 is None:
        x, res = np.zeros_like(g), -g
    else:
        x, res = x0, -g - K @ x0
        if np.linalg.norm(res) <= options.linear_residual * r:
            return x0, None
    z = solver.resolve(res, approximate=True)
    p, rz = z, float(res @ z)
    for _ in range(steps):
        Kp = K @ p
        curvature = float(p @ Kp)
        if curvature <= 0:
            return None, p
        a = rz / curvature
        x = x + a * p
        res = res - a * Kp
        if np.linalg.norm(res) <= options.linear_residual * r:
            return x, None
        z = solver.resolve(res, approximate=True)
        rz, rz_old = float(res @ z), rz
        p = z + (rz / rz_old) * p
    return None, None


def _line_search(terms, x, E, step, slope, shape, alpha, options: NewtonOptions, residual=None):
    """Backtracking Armijo from ``alpha`` (the step cap): (alpha, x_new, E_new, trials) of the
    first admissible trial with sufficient decrease, and the energy evaluations it took; alpha <
    min_alpha when none was found.
    ``residual(x_new) -> bool`` (:attr:`NewtonOptions.residual_search`): a trial whose energy
    change lies within the round-off slack of what Armijo asks must also pass it."""
    slack = ENERGY_SLACK * abs(E)  # energy round-off: lets full Newton steps through near convergence
    xn, En, trials = x, E, 0
    while alpha >= options.min_alpha:
        xn = x + alpha * step
        En = sum_energy(terms, xn.reshape(shape))
        trials += 1
        if np.isfinite(En) and En <= E + options.armijo * alpha * slope + slack:
            if residual is None or not _blind(En, E + options.armijo * alpha * slope, slack) or residual(xn):
                break
        alpha *= BACKTRACK
    return alpha, xn, En, trials


def _blind(En: float, demanded: float, slack: float) -> bool:
    """Whether an energy En [mJ] that meets Armijo's ``demanded`` energy within the round-off
    ``slack`` (En <= demanded + slack) lies inside that slack, where the energy cannot judge the
    step (:attr:`NewtonOptions.residual_search`)."""
    return En >= demanded - slack


def _lowers_residual(terms, shape, fidx, r: float):
    """The test :func:`_line_search` applies where the energy cannot judge a trial
    (:attr:`NewtonOptions.residual_search`): whether the residual at the trial x (flat [mm]) is
    below r [N]."""

    def lowers(xn: np.ndarray) -> bool:
        return residual_norm(terms, xn.reshape(shape), fidx) < r

    return lowers


def _full_step_by_residual(terms, x, E, step, slope, shape, cap, r, tol, fidx, options: NewtonOptions):
    """Near the tolerance (r <= stall_factor x tol), the full uncapped step judged by the residual
    where the energy cannot judge it: (1, x_new, E_new) when it is admissible and passes the
    energy test (what the line search would accept first) or cuts the residual to
    ``residual_acceptance`` x r; (None, x, E) otherwise, and the line search decides."""
    if cap < 1.0 or r > options.stall_factor * tol:
        return None, x, E
    xn = x + step
    En = sum_energy(terms, xn.reshape(shape))
    if not np.isfinite(En):
        return None, x, E
    slack = ENERGY_SLACK * abs(E)
    if En <= E + options.armijo * slope + slack and (not options.residual_search
                                                     or not _blind(En, E + options.armijo * slope, slack)):
        return 1.0, xn, En
    rn = residual_norm(terms, xn.reshape(shape), fidx)
    return (1.0, xn, En) if rn <= RESIDUAL_ACCEPTANCE * r else (None, x, E)


def largest_move(dx: np.ndarray, shape) -> float:
    """The largest nodal move [mm] of a flat displacement ``dx`` over nodes of ``shape`` (n, d)."""
    return float(np.linalg.norm(dx.reshape(shape), axis=1).max())


def _curvature_step(terms, x, E, p, g, fidx, accepted, shape, options: NewtonOptions):
    """(x, E) moved from the accepted state x along the free direction ``p`` of the full K's
    negative curvature (:attr:`NewtonOptions.curvature_step`): the sign with g.p <= 0 (g the
    free gradient at the iterate), a first largest nodal move of ``curvature_step`` times that of
    the accepted step (all DOFs), doubled while the energy falls, within the terms' cap over the
    longest trial (every trial segment lies on it, so every state kept is admissible and
    collision-free). The cap is computed only once the first trial has lowered the energy (most
    do not). The given (x, E) where no trial within the cap lowers the energy."""
    d = np.zeros_like(x)
    d[fidx] = p if float(g @ p) <= 0 else -p
    size = largest_move(d, shape)
    length = options.curvature_step * largest_move(accepted, shape)
    if size == 0 or length <= 0:
        return x, E
    d *= length / size
    first = sum_energy(terms, (x + d).reshape(shape))
    if not first < E:  # inf and nan included: most trials end here, before any CCD
        return x, E
    longest = 2.0**options.curvature_doublings
    cap = longest * min([1.0] + [t.max_step(x.reshape(shape), (longest * d).reshape(shape)) for t in terms])
    if cap < 1.0:
        return x, E
    best, t = (x + d, first), 2.0
    while t <= cap:
        xn = x + t * d
        En = sum_energy(terms, xn.reshape(shape))
        if not En < best[1]:
            break
        best, t = (xn, En), 2 * t
    return best


def _marquardt_update(lm: float, alpha: float) -> float:
    """The Marquardt damping for the next iteration after a step of length ``alpha``: grown while
    CCD or the line search cut steps hard (a particle held only by barely-active barriers has
    almost no stiffness, so plain Newton predicts a huge rigid motion that CCD reduces to a few
    percent, iteration after iteration), decayed after long steps (:data:`MARQUARDT_LONG_STEP`)."""
    if alpha < MARQUARDT_SHORT_STEP:
        return min(max(MARQUARDT_GROWTH * lm, MARQUARDT_MIN), MARQUARDT_MAX)
    if alpha >= MARQUARDT_LONG_STEP:
        return lm / MARQUARDT_DECAY if lm > MARQUARDT_CUTOFF else 0.0
    return lm


@blas_limited
def minimize(
    terms: Sequence[EnergyTerm],
    x0: np.ndarray,
    free: np.ndarray,
    force_scale: float,
    options: NewtonOptions = NewtonOptions(),
    solver: LinearSolver | None = None,
    observers: Sequence[Observer] = (),
) -> NewtonResult:
    """Minimise the sum of ``terms`` over the free DOFs from x0 by damped, projected Newton with
    a backtracking line search within the terms' step cap (contact CCD): every iterate has finite
    energy and is collision-free.

    Parameters
    ----------
    terms : sequence of EnergyTerm
        The energy [mJ; mJ/mm per unit thickness in 2D], summed in order.
    x0 : ndarray, shape (n, d)
        Start positions [mm]; the fixed DOFs keep their values.
    free : ndarray of bool, shape (n*d,)
        The free DOFs.
    force_scale : float
        The problem's force scale [N; N/mm in 2D]: the residual tolerance is never below
        ``options.residual_floor`` times it.
    options : NewtonOptions, optional
        Tolerance, iteration budget and the direction's choices.
    solver : LinearSolver, optional
        The linear solver (reused across minimisations, it keeps its analyses); a new one of
        ``options.linear_solver`` where None.
    observers : sequence of Observer, optional
        Told every direction, line search and accepted iteration
        (:mod:`hydrojam.fem.solver.events`), and, where this call makes the solver, every linear
        solve; none by default, at no cost.

    Returns
    -------
    NewtonResult
        The last iterate x (n, d) [mm] (the minimiser where converged), how it ended (``status``,
        ``converged``, ``message``), the Newton iterations, the residual [N] and energy [mJ] there,
        every iteration's residual and the time by phase. A minimisation that does not converge
        returns its last admissible iterate; it never returns non-finite positions.

    Raises
    ------
    ValueError
        For an invalid linear solver setting (``options.linear_solver`` or the environment's
        ``HYDROJAM_SOLVER_THREADS``).
    """
    solver = solver or LinearSolver(options.linear_solver, observers)
    shape = x0.shape
    x = np.array(x0, dtype=float).ravel()
    fidx = np.flatnonzero(free)
    tm = Timings()
    residuals: list[float] = []

    def result(status, it, r, message=None):
        return NewtonResult(x.reshape(shape).copy(), status, it, r, E, message or status.value, residuals, tm)

    E = sum_energy(terms, x.reshape(shape))
    if not np.isfinite(E):
        return result(NewtonStatus.INADMISSIBLE_START, 0, np.inf)
    lm, projected = 0.0, False
    for it in range(options.max_iter + 1):
        t0 = time.perf_counter()
        xs = x.reshape(shape)
        grads = [t.gradient(xs) for t in terms]
        g = sum(grads)[fidx]
        tm.assembly += time.perf_counter() - t0
        r = float(np.linalg.norm(g))
        tol = tolerance(terms, xs, grads, fidx, force_scale, options.rtol, options.residual_floor)
        residuals.append(r)
        if not np.isfinite(r):
            return result(NewtonStatus.NOT_FINITE, it, r)
        if r <= tol:
            return result(NewtonStatus.CONVERGED, it, r)
        if it == options.max_iter:
            break
        t_it = t0 = time.perf_counter()
        full_first = it > 0 and not projected  # the last iteration took the full K's step
        hessians = [t.hessian(xs, False) for t in terms]
        t_sum = time.perf_counter() if observers else 0.0
        Hff = free_sum(hessians, fidx)
        tm.assembly += time.perf_counter() - t0
        t0 = time.perf_counter()
        if observers:
            sum_seconds, solver.log = t0 - t_sum, []
        hdiag = abs(Hff.diagonal())
        dx, slope, tau, projected, negative = _direction(terms, xs, hessians, Hff, hdiag, g, r, lm, fidx, solver,
                                                         options, full_first)
        tm.linear_solve += time.perf_counter() - t0
        if observers:
            solves, solver.log = tuple(solver.log), None
            notify(observers, "on_direction", Direction(terms, xs, it, r, tol, tau, projected,
                                                         time.perf_counter() - t0, sum_seconds, solves))
        if dx is None:
            return result(NewtonStatus.SINGULAR, it, r)
        lm = tau
        if tau == 0 and -slope <= DECREMENT_ROUNDOFF * abs(E) and r <= options.stall_factor * tol:
            return result(NewtonStatus.CONVERGED_DECREMENT, it, r)
        step = np.zeros_like(x)
        step[fidx] = dx
        t0 = time.perf_counter()
        cap = min([1.0] + [t.max_step(xs, step.reshape(shape)) for t in terms])
        cap_seconds = time.perf_counter() - t0
        tm.step_cap += cap_seconds
        t0 = time.perf_counter()
        residual = _lowers_residual(terms, shape, fidx, r) if options.residual_search else None
        alpha, xn, En = _full_step_by_residual(terms, x, E, step, slope, shape, cap, r, tol, fidx, options)
        searched, trials = alpha is None, 0
        if searched:
            alpha, xn, En, trials = _line_search(terms, x, E, step, slope, shape, cap, options, residual)
        tm.line_search += time.perf_counter() - t0
        tm.iterations += 1
        if observers:
            notify(observers, "on_line_search", LineSearch(terms, xs, step.reshape(shape), cap, alpha, trials, En - E,
                                                           searched, time.perf_counter() - t0, cap_seconds))
        if alpha < options.min_alpha:
            if r <= options.stall_factor * tol:
                # within stall_factor of the tolerance and no representable descent along the
                # Newton direction: the energy is at its round-off floor, not stuck
                return result(NewtonStatus.CONVERGED_NO_DESCENT, it, r)
            return result(NewtonStatus.LINE_SEARCH_FAILED, it, r)
        moved, curvature_seconds = xn, 0.0
        if negative is not None and options.curvature_step > 0:
            t0 = time.perf_counter()
            xn, En = _curvature_step(terms, xn, En, negative, g, fidx, alpha * step, shape, options)
            curvature_seconds = time.perf_counter() - t0
            tm.line_search += curvature_seconds
        if observers:
            curved = largest_move(xn - moved, shape) if xn is not moved else 0.0
            notify(observers, "on_iteration", Iteration(it, alpha, curved, En, time.perf_counter() - t_it,
                                                        curvature_seconds))
        x, E = xn, En
        lm = _marquardt_update(lm, alpha)
    return result(NewtonStatus.MAX_ITERATIONS, options.max_iter, residuals[-1],
                  f"no convergence in {options.max_iter} iterations")
