"""Energy minimisation by damped Newton (docs/solver.md, "Newton").

The solver knows only energy terms (:mod:`hydrojam.fem.terms`) and which DOFs are free. Every
accepted state has finite energy (admissible) and respects every term's step cap (contact CCD).
One iteration is: the forces and the convergence test, the Hessian, a *direction* (the damped,
regularised linear solve, :func:`_direction`), a *line search* (:func:`_line_search`) and the
*damping update* (:func:`_marquardt_update`). Every constant is a named field of
:class:`NewtonOptions`; the outcome is a :class:`NewtonStatus`.

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
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from hydrojam.fem._env import blas_limited
from hydrojam.fem.linsolve import LinearSolver, LinearSolveError, NotPositiveDefinite
from hydrojam.fem.terms import EnergyTerm

_TINY = 1e-300  # keeps the scaled gradient step finite when the Hessian's diagonal is all zero
_MODE_SHIFT = 1e-3  # x mean|diag H|: lowest_mode's preconditioner shift; much smaller, its inverse
# overweights the projected Hessian's soft modes and LOBPCG settles on them (docs/solver.md)
_MODE_TOLERANCE = 1e-5  # x mean|diag H|: lowest_mode's LOBPCG residual norm (a direction, not a spectrum)


@dataclass(frozen=True)
class NewtonOptions:
    """Newton settings. ``projection``: "adaptive" (the full Hessian, shifted by tau diag|H| only
    while its step does not descend), "always" (element Hessians projected to PSD throughout, as
    in IPC) or "never" (the full Hessian; a scaled gradient step where it does not descend).

    Adaptive is the default because projecting a stable but locally non-convex gel (every gel
    element under lateral constraint) discards real curvature: on a swelling layer always-projected
    Newton converges linearly where the full Hessian converges quadratically (docs/solver.md,
    "Choices").
    """

    rtol: float = 1e-6
    """Residual tolerance relative to the forces in play [-]."""
    max_iter: int = 40
    """Newton iterations before giving up (status MAX_ITERATIONS)."""
    projection: str = "adaptive"
    """"adaptive", "always" or "never" (see the class docstring)."""
    armijo: float = 1e-4
    """Sufficient-decrease constant of the line search [-]."""
    min_alpha: float = 1e-8
    """Smallest step length the line search tries [-]."""
    stall_factor: float = 1e3
    """A residual within this factor of the tolerance may converge at energy round-off [-]."""
    linear_solver: str = "auto"
    """"auto", "pardiso" or "scipy" (:class:`hydrojam.fem.linsolve.LinearSolver`)."""
    residual_floor: float = 1e-10
    """Floor of the residual tolerance, times the problem's force scale: round-off of the residual."""
    regularisation: float = 1e-9
    """eps, times mean|diag H|, added to the diagonal always: pins the rigid modes of a floating
    body, in which a singular solve returns an arbitrary drift that no residual check sees."""
    linear_residual: float = 1e-6
    """A linear solve is accepted when ||K dx + g|| <= this x ||g||."""
    damping_attempts: int = 16
    """Damped solves tried per iteration before the status SINGULAR."""
    damping_growth: float = 10.0
    """Factor on tau after a direction that fails (no solution, or no descent)."""
    damping_floor: float = 1e-8
    """tau's first non-zero value, relative to diag|H|."""
    decrement_roundoff: float = 1e-14
    """A Newton decrement below this x |E| is energy round-off: converged (undamped steps only)."""
    energy_slack: float = 1e-12
    """The line search accepts an energy rise of this x |E| (round-off): full steps near convergence."""
    backtrack: float = 0.5
    """Factor on the step length after a rejected trial."""
    residual_acceptance: float = 0.5
    """Within stall_factor of the tolerance, a full step (no CCD cap) that fails the energy test
    is still taken when it cuts the residual to this x ||g|| or less: there the energy change is
    below the energy's round-off (a freely swelling gel's energy is a sum of cancelling terms),
    and the residual is the reliable measure of progress."""
    residual_search: bool = False
    """Where a step's energy change lies within the round-off slack (``energy_slack`` x |E|) of
    the decrease Armijo asks, the energy cannot judge the step: it is then taken only where it
    also lowers the residual (a full step near the tolerance: by ``residual_acceptance``).
    Energy changes at round-off cannot tell a step from its way back: without this, Newton
    cycled between states just above the tolerance until it ran out of iterations
    (docs/solver.md, "Newton")."""
    marquardt_short_step: float = 0.1
    """An accepted step length below this grows the Marquardt damping."""
    marquardt_growth: float = 10.0
    """Factor on the Marquardt damping after a short step."""
    marquardt_min: float = 1e-4
    """Smallest Marquardt damping once grown (relative to diag|H|)."""
    marquardt_max: float = 1e4
    """Largest Marquardt damping (relative to diag|H|)."""
    marquardt_decay: float = 10.0
    """Divisor of the Marquardt damping after a long step (``marquardt_long_step``)."""
    marquardt_long_step: float = 1.0
    """An accepted step length at or above this decays the Marquardt damping (1: full steps only)."""
    marquardt_cutoff: float = 1e-6
    """A Marquardt damping at or below this drops to 0 after a long step."""
    definite: bool = False
    """Inertia correction: a damped system K with a negative eigenvalue (the linear solver's
    inertia, where it reports one) counts as a failed direction, so tau grows until K is positive
    definite and the step heads for a minimum, not for a saddle."""
    definite_floor: float = 1e-4
    """tau's first non-zero value after an indefinite K (``definite``), relative to diag|H|."""
    fallback_start: str = "full"
    """Where the terms with ``fallback_projection`` (contact) start each iteration: "full" (their
    full Hessian first, projected only after a failed direction), "projected" (projected from the
    first attempt, as IPC does), "remembered" (full in a minimisation's first iteration, projected
    from the first attempt once an iteration of it needed the projection) or "krylov" (with
    ``definite``: the projected K is factorised first, then preconditions conjugate gradients on the
    full K, whose solution is the direction unless they meet negative curvature) or
    "krylov_detect" (the same conjugate gradients only detect the full K's negative curvature:
    where they meet none, the full K is factorised and its solution taken if its factorisation
    shows it definite; after an iteration that took the full K's step, the full K is factorised
    first: the directions of "full" with fewer factorisations; the actuator's path). Each failed
    attempt costs a factorisation."""
    krylov_iterations: int = 20
    """Conjugate-gradient iterations at most on the full K (``fallback_start`` "krylov")."""
    detect_iterations: int = 5
    """Conjugate-gradient iterations at most that look for the full K's negative curvature
    (``fallback_start`` "krylov_detect"): where they meet none, the full K is factorised, and its
    factorisation (a Cholesky's refusal, an LDL^T's inertia) decides whether it is definite.
    Negative curvature shows within a few iterations or not at all, while converging on a
    definite K takes several more."""
    curvature_step: float = 0.0
    """With ``fallback_start`` "krylov" or "krylov_detect": where the conjugate gradients met a
    direction p of negative curvature of the full K (p.K.p <= 0), the state after the line search
    is moved further along p, the sign that descends at the iterate, from a largest nodal move of
    ``curvature_step`` times the accepted step's, doubled while the energy falls, at most
    ``curvature_doublings`` times and within the terms' step cap (one CCD over the longest): the
    lowest state is kept. The projected K's step cannot see that curvature; along it the energy
    falls further than any model the projection leaves. 0: off (the actuator's path: 1, with one
    doubling)."""
    curvature_doublings: int = 3
    """Doublings at most of the negative-curvature step (``curvature_step``): up to 2**n times its
    first length."""


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


def sum_energy(terms: Sequence[EnergyTerm], x: np.ndarray) -> float:
    """Total energy of ``terms`` at x (n, d) [mm]; inf as soon as a partial sum is not finite."""
    e = 0.0
    for t in terms:
        e += t.energy(x)
        if not np.isfinite(e):
            return np.inf
    return e


def _tolerance(terms, xs, grads, fidx, force_scale, options: NewtonOptions) -> float:
    """Residual tolerance [N]: rtol x the largest term's forces in play, floored at round-off."""
    in_play = max(float(np.linalg.norm(t.force_flux(xs, gt)[fidx])) for t, gt in zip(terms, grads))
    return max(options.rtol * in_play, options.residual_floor * force_scale)


def _sum_hessians(matrices) -> sp.csr_matrix:
    """The terms' Hessians summed in order, with the values and stored entries of Python's
    ``sum`` (0 + H1 + H2 + ...), without its passes that change nothing: the copy that 0 + H1
    makes, and the addition of a matrix with only zero values after the first addition (a
    stabilisation at scale 0; x + 0.0 == x, and SciPy's addition drops the entries that sum to
    zero, which the first addition has dropped already)."""
    matrices = list(matrices)
    if len(matrices) == 1:
        return sp.csr_matrix(matrices[0]).copy()
    total = matrices[0] + matrices[1]
    for m in matrices[2:]:
        if m.nnz and np.any(m.data):
            total = total + m
    return total


def _positions(n: int, fidx: np.ndarray) -> np.ndarray:
    """Each of n DOFs' index among the free DOFs ``fidx`` (ascending), -1 where it is fixed."""
    position = np.full(n, -1, dtype=np.int64)
    position[fidx] = np.arange(len(fidx))
    return position


def _free_block(H, fidx: np.ndarray) -> sp.csr_matrix:
    """H's block on the free DOFs ``fidx`` (ascending): SciPy's ``H[fidx][:, fidx]`` (the same
    entries in the same order, so the same bits downstream) in one compiled pass instead of two
    fancy-indexing passes."""
    H = sp.csr_matrix(H)
    if not H.has_sorted_indices:
        return H[fidx][:, fidx]
    from hydrojam.fem import _kernels

    ptr, ind, val = _kernels.free_block(H.indptr, H.indices, H.data, fidx.astype(np.int64),
                                        _positions(H.shape[1], fidx))
    return sp.csr_matrix((val, ind, ptr), shape=(len(fidx), len(fidx)))


def _free_sum(matrices, fidx: np.ndarray) -> sp.csr_matrix:
    """``_free_block(_sum_hessians(matrices), fidx)``, the same entries to the bit, with the first
    two matrices added and cut to the free block in one compiled pass where both are canonical
    (sorted rows, no duplicates), as the elastic and contact Hessians are: the sum of the whole
    matrices and its block were two passes over every entry of the elastic Hessian."""
    matrices = [sp.csr_matrix(m) for m in matrices]
    if len(matrices) == 1 or not all(m.has_canonical_format for m in matrices[:2]):
        return _free_block(_sum_hessians(matrices), fidx)
    from hydrojam.fem import _kernels

    a, b = matrices[:2]
    ptr, ind, val = _kernels.free_sum(a.indptr, a.indices, a.data, b.indptr, b.indices, b.data,
                                      fidx.astype(np.int64), _positions(a.shape[1], fidx))
    total = sp.csr_matrix((val, ind, ptr), shape=(len(fidx), len(fidx)))
    for m in matrices[2:]:
        if m.nnz and np.any(m.data):
            total = total + _free_block(m, fidx)
    return total


def _reach(terms, xs, fidx):
    """The linear solver's hint (:meth:`LinearSolver.solve`'s ``reach``): a callable giving the
    free block of the terms' Hessian patterns near xs, made only when asked (None where no term
    gives one)."""

    def reach():
        patterns = [p for t in terms if (p := t.hessian_pattern(xs)) is not None]
        return _free_block(sum(patterns), fidx) if patterns else None

    return reach


def _direction(terms, xs, hessians, Hff, hdiag, g, r, lm, fidx, solver, options: NewtonOptions,
               projected: bool = False, full_first: bool = False):
    """The damped Newton direction: solve K dx = -g over the free DOFs with
    K = H + tau diag|H| + eps mean|diag H| I. ``hessians``: every term's Hessian at xs, as summed
    into H (the fallback re-assembles only the terms that ask for projection; ``projected``: they
    already are). Returns (dx or None if every attempt failed, slope g.dx, tau used, whether the
    fallback terms were projected in the accepted K, a direction of the full K's negative
    curvature that the conjugate gradients met, or None). ``full_first`` ("krylov_detect" only; the
    last iteration took the full K's step): the full K at ``lm`` is factorised first, and its
    solution taken where it is definite; otherwise the projected K's step follows without the
    conjugate gradients, which would only find again that the full K is not definite. Either way
    the direction is the one "krylov_detect" takes without it.

    Damping changes the step, never the equilibrium.
    - eps (``regularisation``), always: a floating body's rigid modes are an exact null space,
      in which a singular solve returns an arbitrary drift that no residual check can see.
    - tau ("adaptive"): starts at the Marquardt term ``lm`` and grows only while the step does
      not descend; with ``definite`` (the inertia correction) also while K has a negative
      eigenvalue. Projecting element Hessians instead discards the curvature of every gel
      element (each is non-convex alone while the assembly is stable: docs/solver.md, "Choices").
    """
    adaptive = options.projection == "adaptive"
    fallback = any(t.fallback_projection for t in terms)
    krylov = (options.fallback_start in ("krylov", "krylov_detect") and options.definite and adaptive and fallback
              and not projected)
    reach = _reach(terms, xs, fidx)
    eps = options.regularisation * hdiag.mean()
    detect, full_indefinite = options.fallback_start == "krylov_detect", False
    if krylov and detect and full_first:
        # the projected K is the full one plus a positive semi-definite part: where the full K at
        # lm is definite, the projected one is too and the conjugate gradients meet no negative
        # curvature, so "krylov_detect" would take this solution
        K = Hff + sp.diags(lm * hdiag + eps, format="csr")
        cand, full_indefinite = _definite_solution(K, g, r, reach, solver, options)
        if cand is not None:
            return cand, float(g @ cand), lm, False, None
    tau, dx, slope, Hfull, negative = lm, None, 0.0, Hff, None
    for attempt in range(options.damping_attempts):
        if (attempt == 1 or krylov) and adaptive and fallback and not projected:
            # the barrier's own negative curvature (b'(d) times the curvature of the distance)
            # is what makes a contact Hessian indefinite: project it per contact, as IPC does,
            # before damping the whole system (docs/solver.md, "Choices")
            Hff = _free_sum([t.hessian(xs, True) if t.fallback_projection else h for t, h in zip(terms, hessians)], fidx)
            tau, projected = lm, True
        K = Hff + sp.diags(tau * hdiag + eps, format="csr")
        cand, indefinite = _accurate_solution(K, g, r, reach, solver, options)
        if cand is not None:
            slope = float(g @ cand)
            indefinite = options.definite and bool(solver.negative_eigenvalues)
            if (not adaptive or slope < 0) and not indefinite:
                dx = cand
                break
        tau = max(options.damping_growth * tau, options.definite_floor if indefinite else options.damping_floor)
    if (krylov and not full_indefinite and dx is not None and solver.negative_eigenvalues is not None
            and (tau == lm or not detect)):
        # "krylov_detect" follows "full": its full K is tried at the Marquardt damping only (the
        # full K is the projected one less the contacts' negative curvature, so where the
        # projected K needed more damping, the full one at lm is indefinite too)
        K = Hfull + sp.diags(tau * hdiag + eps, format="csr")
        if detect:
            _, negative = _conjugate_gradients(K, g, r, solver, options.detect_iterations, options)
            full = None if negative is not None else _definite_solution(K, g, r, reach, solver, options)[0]
        else:
            full, negative = _conjugate_gradients(K, g, r, solver, options.krylov_iterations, options)
        if full is not None:
            dx, slope, projected = full, float(g @ full), False
    return dx, slope, tau, projected, negative


def _accurate_solution(K, g, r, reach, solver, options: NewtonOptions):
    """(dx, indefinite): the solution of K dx = -g by a factorisation where the solve succeeds and
    ||K dx + g|| <= linear_residual x r, None otherwise; indefinite where the inertia correction
    (``options.definite``) asked the solver for a positive definite K and it found it is not one
    (a failed Cholesky factorisation: the solution is not needed then)."""
    try:
        dx = solver.solve(K, -g, reach, definite=options.definite)
    except NotPositiveDefinite:
        return None, True
    except LinearSolveError:
        return None, False
    return (dx if np.linalg.norm(K @ dx + g) <= options.linear_residual * r else None), False


def _definite_solution(K, g, r, reach, solver, options: NewtonOptions):
    """(dx, indefinite): :func:`_accurate_solution`'s dx where K is positive definite by its
    inertia and dx descends, None otherwise; indefinite where the factorisation showed K is not
    positive definite (a Cholesky's refusal, an LDL^T's negative eigenvalue)."""
    dx, refused = _accurate_solution(K, g, r, reach, solver, options)
    if dx is None:
        return None, refused
    if solver.negative_eigenvalues:
        return None, True
    return (dx if g @ dx < 0 else None), False


def _conjugate_gradients(K, g, r, solver, steps: int, options: NewtonOptions):
    """K dx = -g by at most ``steps`` conjugate-gradient iterations preconditioned with the
    solver's last factorisation (a positive definite K nearby): (dx, p). dx once
    ||K dx + g|| <= linear_residual x r, else None; p the first search direction with curvature
    p.K.p <= 0 (K is not positive definite there; dx is None then), else None. Every iterate
    from dx = 0 descends (g.dx < 0)."""
    x = np.zeros_like(g)
    res = -g
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
    """Backtracking Armijo from ``alpha`` (the step cap): (alpha, x_new, E_new) of the first
    admissible trial with sufficient decrease; alpha < min_alpha when none was found.
    ``residual(x_new) -> bool`` (:attr:`NewtonOptions.residual_search`): a trial whose energy
    change lies within the round-off slack of what Armijo asks must also pass it."""
    slack = options.energy_slack * abs(E)  # energy round-off: lets full Newton steps through near convergence
    xn, En = x, E
    while alpha >= options.min_alpha:
        xn = x + alpha * step
        En = sum_energy(terms, xn.reshape(shape))
        if np.isfinite(En) and En <= E + options.armijo * alpha * slope + slack:
            if residual is None or not _blind(En, E + options.armijo * alpha * slope, slack) or residual(xn):
                break
        alpha *= options.backtrack
    return alpha, xn, En


def _blind(En: float, demanded: float, slack: float) -> bool:
    """Whether an energy En [mJ] that meets Armijo's ``demanded`` energy within the round-off
    ``slack`` (En <= demanded + slack) lies inside that slack, where the energy cannot judge the
    step (:attr:`NewtonOptions.residual_search`)."""
    return En >= demanded - slack


def _residual_norm(terms, xs: np.ndarray, fidx: np.ndarray) -> float:
    """||g_free|| [N] of ``terms`` at positions xs (n, d) [mm]."""
    return float(np.linalg.norm(sum(t.gradient(xs) for t in terms)[fidx]))


def _lowers_residual(terms, shape, fidx, r: float):
    """The test :func:`_line_search` applies where the energy cannot judge a trial
    (:attr:`NewtonOptions.residual_search`): whether the residual at the trial x (flat [mm]) is
    below r [N]."""

    def lowers(xn: np.ndarray) -> bool:
        return _residual_norm(terms, xn.reshape(shape), fidx) < r

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
    slack = options.energy_slack * abs(E)
    if En <= E + options.armijo * slope + slack and (not options.residual_search
                                                     or not _blind(En, E + options.armijo * slope, slack)):
        return 1.0, xn, En
    rn = _residual_norm(terms, xn.reshape(shape), fidx)
    return (1.0, xn, En) if rn <= options.residual_acceptance * r else (None, x, E)


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


def _marquardt_update(lm: float, alpha: float, options: NewtonOptions) -> float:
    """The Marquardt damping for the next iteration after a step of length ``alpha``: grown while
    CCD or the line search cut steps hard (a particle held only by barely-active barriers has
    almost no stiffness, so plain Newton predicts a huge rigid motion that CCD reduces to a few
    percent, iteration after iteration), decayed after long steps (``marquardt_long_step``)."""
    if alpha < options.marquardt_short_step:
        return min(max(options.marquardt_growth * lm, options.marquardt_min), options.marquardt_max)
    if alpha >= options.marquardt_long_step:
        return lm / options.marquardt_decay if lm > options.marquardt_cutoff else 0.0
    return lm


def negative_curvature(
    terms: Sequence[EnergyTerm],
    x: np.ndarray,
    free: np.ndarray,
    solver: LinearSolver,
    options: NewtonOptions = NewtonOptions(),
) -> int | None:
    """Number of negative eigenvalues of the unprojected Hessian of ``terms`` over the free DOFs
    (bool mask over n*d) at positions x (n, d) [mm]: 0 where x is a stable equilibrium of these
    terms, > 0 where it is unstable (a saddle, or a state held by terms left out). One
    factorisation of H_ff + eps mean|diag H_ff| I, eps = ``options.regularisation`` (the shift
    the Newton solve adds): eigenvalues above -eps mean|diag H_ff| count as non-negative, so the
    exact null space of a floating body and round-off around it never count. None where the
    solver does not report the inertia (SciPy) or the factorisation fails."""
    xs = np.asarray(x, dtype=float)
    fidx = np.flatnonzero(free)
    if fidx.size == 0:
        return 0
    Hff = _free_sum([t.hessian(xs, False) for t in terms], fidx)
    hdiag = abs(Hff.diagonal())
    K = Hff + sp.diags(np.full(len(fidx), options.regularisation * hdiag.mean()), format="csr")
    try:
        solver.solve(K, np.ones(len(fidx)))
    except LinearSolveError:
        return None
    return solver.negative_eigenvalues


def lowest_mode(
    terms: Sequence[EnergyTerm],
    x: np.ndarray,
    free: np.ndarray,
    solver: LinearSolver,
    options: NewtonOptions = NewtonOptions(),
    max_iter: int = 200,
) -> tuple[float, np.ndarray]:
    """The lowest eigenvalue of the unprojected Hessian of ``terms`` over the free DOFs at x and
    its mode: an unstable equilibrium's direction of steepest fall.

    LOBPCG (SciPy) on H_ff, preconditioned by one factorisation of the PSD-projected Hessian
    (every element and contact Hessian projected, as in IPC) shifted by ``_MODE_SHIFT`` x
    mean|diag H_ff|: the projection keeps the stiff part of the spectrum that makes plain Lanczos
    slow, and each iteration costs one substitution. A block of three vectors from a seeded
    start; a dense eigensolver where the free DOFs are too few for LOBPCG.

    Parameters
    ----------
    terms : sequence of EnergyTerm
        The energy (physics only: leave a stabilisation out).
    x : ndarray, shape (n, d)
        Positions [mm].
    free : ndarray of bool, shape (n*d,)
        Free DOFs.
    solver : LinearSolver
        Factorises the preconditioner (its last factorisation is replaced).
    options : NewtonOptions, optional
        Its ``regularisation`` shifts H_ff as the Newton solve does.
    max_iter : int, optional
        LOBPCG iterations at most.

    Returns
    -------
    eigenvalue : float
        The lowest eigenvalue found [N/mm; N/mm^2 per unit thickness in 2D]: negative at an
        unstable state (an upper bound of the true lowest, as every Rayleigh quotient is).
    mode : ndarray, shape (n, d)
        Its eigenvector, zero on fixed DOFs, scaled so that the largest nodal move is 1 [mm].
    """
    xs = np.asarray(x, dtype=float)
    fidx = np.flatnonzero(free)
    H = _free_sum([t.hessian(xs, False) for t in terms], fidx)
    hdiag = abs(H.diagonal())
    H = H + sp.diags(np.full(len(fidx), options.regularisation * hdiag.mean()), format="csr")
    block = 3
    if len(fidx) <= 5 * block:  # LOBPCG itself falls back to a dense solver there
        w, V = np.linalg.eigh(H.toarray())
        value, vec = float(w[0]), V[:, 0]
    else:
        P = _free_sum([t.hessian(xs, True) for t in terms], fidx)
        P = P + sp.diags(np.full(len(fidx), _MODE_SHIFT * hdiag.mean()), format="csr")
        solver.solve(P, np.ones(len(fidx)))

        def precondition(R):
            R = np.asarray(R)
            return solver.resolve(R) if R.ndim == 1 else np.column_stack([solver.resolve(c) for c in R.T])

        M = spla.LinearOperator(H.shape, matvec=precondition, matmat=precondition, dtype=float)
        start = np.random.default_rng(0).standard_normal((len(fidx), block))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "not reaching the requested tolerance"
            w, V = spla.lobpcg(H, start, M=M, largest=False, tol=_MODE_TOLERANCE * hdiag.mean(),
                               maxiter=max_iter)
        k = int(np.argmin(w))
        value, vec = float(w[k]), V[:, k]
    mode = np.zeros(xs.size)
    mode[fidx] = vec
    mode = mode.reshape(xs.shape)
    return value, mode / max(float(np.linalg.norm(mode, axis=1).max()), _TINY)


@blas_limited
def minimize(
    terms: Sequence[EnergyTerm],
    x0: np.ndarray,
    free: np.ndarray,
    force_scale: float,
    options: NewtonOptions = NewtonOptions(),
    solver: LinearSolver | None = None,
) -> NewtonResult:
    """Minimise the sum of ``terms`` over the free DOFs (bool mask over n*d) from x0 (n, d) [mm]
    (fixed DOFs stay); ``force_scale`` [N] sets the floor of the residual tolerance."""
    solver = solver or LinearSolver(options.linear_solver)
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
    if options.fallback_start not in ("full", "projected", "remembered", "krylov", "krylov_detect"):
        raise ValueError(f"fallback_start must be full, projected, remembered, krylov or krylov_detect, "
                         f"not {options.fallback_start!r}")
    lm, projected = 0.0, options.fallback_start == "projected"
    for it in range(options.max_iter + 1):
        t0 = time.perf_counter()
        xs = x.reshape(shape)
        grads = [t.gradient(xs) for t in terms]
        g = sum(grads)[fidx]
        tm.assembly += time.perf_counter() - t0
        r = float(np.linalg.norm(g))
        tol = _tolerance(terms, xs, grads, fidx, force_scale, options)
        residuals.append(r)
        if not np.isfinite(r):
            return result(NewtonStatus.NOT_FINITE, it, r)
        if r <= tol:
            return result(NewtonStatus.CONVERGED, it, r)
        if it == options.max_iter:
            break
        t0 = time.perf_counter()
        full_first = it > 0 and not projected  # the last iteration took the full K's step
        projected = projected and options.fallback_start in ("projected", "remembered")
        hessians = [t.hessian(xs, options.projection == "always" or (projected and t.fallback_projection))
                    for t in terms]
        Hff = _free_sum(hessians, fidx)
        tm.assembly += time.perf_counter() - t0
        t0 = time.perf_counter()
        hdiag = abs(Hff.diagonal())
        dx, slope, tau, projected, negative = _direction(terms, xs, hessians, Hff, hdiag, g, r, lm, fidx, solver,
                                                         options, projected, full_first)
        tm.linear_solve += time.perf_counter() - t0
        if dx is None:
            return result(NewtonStatus.SINGULAR, it, r)
        lm = tau
        if slope >= 0:  # "never"/"always" with a non-descent direction: a scaled gradient step
            dx = -g / max(hdiag.max(), _TINY)
            slope = float(g @ dx)
        if tau == 0 and -slope <= options.decrement_roundoff * abs(E) and r <= options.stall_factor * tol:
            return result(NewtonStatus.CONVERGED_DECREMENT, it, r)
        step = np.zeros_like(x)
        step[fidx] = dx
        t0 = time.perf_counter()
        cap = min([1.0] + [t.max_step(xs, step.reshape(shape)) for t in terms])
        tm.step_cap += time.perf_counter() - t0
        t0 = time.perf_counter()
        residual = _lowers_residual(terms, shape, fidx, r) if options.residual_search else None
        alpha, xn, En = _full_step_by_residual(terms, x, E, step, slope, shape, cap, r, tol, fidx, options)
        if alpha is None:
            alpha, xn, En = _line_search(terms, x, E, step, slope, shape, cap, options, residual)
        tm.line_search += time.perf_counter() - t0
        tm.iterations += 1
        if alpha < options.min_alpha:
            if r <= options.stall_factor * tol:
                # within stall_factor of the tolerance and no representable descent along the
                # Newton direction: the energy is at its round-off floor, not stuck
                return result(NewtonStatus.CONVERGED_NO_DESCENT, it, r)
            return result(NewtonStatus.LINE_SEARCH_FAILED, it, r)
        if negative is not None and options.curvature_step > 0:
            t0 = time.perf_counter()
            xn, En = _curvature_step(terms, xn, En, negative, g, fidx, alpha * step, shape, options)
            tm.line_search += time.perf_counter() - t0
        x, E = xn, En
        lm = _marquardt_update(lm, alpha, options)
    return result(NewtonStatus.MAX_ITERATIONS, options.max_iter, residuals[-1],
                  f"no convergence in {options.max_iter} iterations")
