"""Energy-minimising solver (DESIGN.md section 8): projected Newton and an adaptive load path.

The solver knows only energy terms (value, gradient, Hessian, step cap; see ``terms.py``) and
Dirichlet conditions, which eliminate DOFs. Every accepted state has finite energy (admissible)
and respects every term's step cap (contact CCD).

Convergence: the residual norm over free DOFs ||g_f|| <= ``rtol`` x the forces in play (the
largest term's force magnitude: a solid's internal-force flux |f_e| summed without the
cancellation of assembly, a load's or the contact's own force), but never below 1e-10 x the
problem's force scale (round-off of the residual: a stress-free mesh of 100 mm already shows
1e-13 N), or,
once the residual is within ``stall_factor`` of that, a Newton decrement below round-off of the
energy or a line search that finds no representable decrease. rtol = 1e-6 by default: six
orders of magnitude below the acting forces (ABAQUS's
default is 5e-3); frictionless round particles have near-zero-stiffness rotation modes that a
tighter tolerance chases for hundreds of iterations without changing any result.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.linsolve import LinearSolver, LinearSolveError
from hydrojam.fem.terms import EnergyTerm


class ConvergenceError(RuntimeError):
    """The load path could not be followed: raised only on request (``raise_on_failure``)."""


# --------------------------------------------------------------------------------------------
# Dirichlet conditions


@dataclass(frozen=True)
class Dirichlet:
    """Prescribed DOFs: x[dof] = X[dof] + ramp(s) * displacement [mm] (ramp(s) = s by default).

    ``dofs`` index the flat position vector (dof = node*d + component).
    """

    dofs: np.ndarray
    displacement: np.ndarray
    ramp: Callable[[float], float] | None = None

    def values(self, X_flat: np.ndarray, s: float) -> np.ndarray:
        r = s if self.ramp is None else self.ramp(s)
        return X_flat[self.dofs] + r * self.displacement


def fixed(nodes, dim: int, components: Sequence[int] | None = None) -> Dirichlet:
    """Hold ``nodes`` at their reference positions (all components, or the given ones)."""
    comps = range(dim) if components is None else components
    nodes = np.asarray(nodes, dtype=np.int64)
    dofs = (nodes[:, None] * dim + np.asarray(list(comps))[None, :]).ravel()
    return Dirichlet(dofs, np.zeros(len(dofs)))


def prescribed(nodes, dim: int, component: int, displacement: float, ramp=None) -> Dirichlet:
    """Move component ``component`` of ``nodes`` by ``displacement`` [mm] at s = 1 (linear ramp)."""
    nodes = np.asarray(nodes, dtype=np.int64)
    return Dirichlet(nodes * dim + component, np.full(len(nodes), float(displacement)), ramp)


# --------------------------------------------------------------------------------------------
# Problem and options


@dataclass(frozen=True)
class Problem:
    """What the load-path driver solves.

    ``terms(s)`` returns the energy terms at load parameter s in [0, 1] (materials at the stimulus
    of s, loads scaled by s, ...). ``force_scale`` [N] sets the residual tolerance;
    ``length_scale`` [mm] a typical element size.
    """

    X: np.ndarray
    terms: Callable[[float], list[EnergyTerm]]
    dirichlet: list[Dirichlet] = field(default_factory=list)
    force_scale: float = 1.0
    length_scale: float = 1.0

    @property
    def ndof(self) -> int:
        return self.X.size

    def free_mask(self) -> np.ndarray:
        free = np.ones(self.ndof, dtype=bool)
        for bc in self.dirichlet:
            free[bc.dofs] = False
        return free

    def apply_dirichlet(self, x_flat: np.ndarray, s: float) -> None:
        X = self.X.ravel()
        for bc in self.dirichlet:
            x_flat[bc.dofs] = bc.values(X, s)


@dataclass(frozen=True)
class NewtonOptions:
    """Newton settings. ``projection``: "adaptive" (the full Hessian, shifted by tau diag|H| only
    while its step does not descend), "always" (element Hessians projected to PSD throughout, as
    in IPC) or "never" (the full Hessian; a scaled gradient step where it does not descend).

    Adaptive is the default because projecting a stable but locally non-convex gel (every gel
    element under lateral constraint) discards real curvature: measured on a swelling layer,
    always-projected Newton needed 725 iterations where the full Hessian needed 20, quadratically.
    """

    rtol: float = 1e-6
    max_iter: int = 40
    projection: str = "adaptive"
    armijo: float = 1e-4
    min_alpha: float = 1e-8
    stall_factor: float = 1e3
    linear_solver: str = "auto"


@dataclass
class Timings:
    """Wall time [s] by phase, accumulated over Newton iterations."""

    assembly: float = 0.0
    linear_solve: float = 0.0
    line_search: float = 0.0
    step_cap: float = 0.0
    iterations: int = 0

    def add(self, other: "Timings") -> None:
        for k in ("assembly", "linear_solve", "line_search", "step_cap", "iterations"):
            setattr(self, k, getattr(self, k) + getattr(other, k))


@dataclass(frozen=True)
class NewtonResult:
    """Outcome of one minimisation: positions x (n, d) [mm] and diagnostics."""

    x: np.ndarray
    converged: bool
    iterations: int
    residual: float
    energy: float
    message: str
    residuals: list[float]
    timings: Timings
    trace: list[tuple[float, float, float, bool, float]] = field(default_factory=list)
    """Per iteration: (residual [N], accepted step length alpha, step cap from the terms, projected,
    damping tau relative to diag|H|)."""


def _sum_energy(terms, x):
    e = 0.0
    for t in terms:
        e += t.energy(x)
        if not np.isfinite(e):
            return np.inf
    return e


def minimize(
    terms: Sequence[EnergyTerm],
    x0: np.ndarray,
    free: np.ndarray,
    force_scale: float,
    options: NewtonOptions = NewtonOptions(),
    solver: LinearSolver | None = None,
) -> NewtonResult:
    """Minimise the sum of ``terms`` over the free DOFs from x0 (n, d) [mm] (fixed DOFs stay)."""
    solver = solver or LinearSolver(options.linear_solver)
    shape = x0.shape
    x = np.array(x0, dtype=float).ravel()
    fidx = np.flatnonzero(free)
    tm = Timings()
    E = _sum_energy(terms, x.reshape(shape))
    if not np.isfinite(E):
        return NewtonResult(x.reshape(shape), False, 0, np.inf, E, "initial state is inadmissible (infinite energy)", [], tm)
    residuals: list[float] = []
    trace: list[tuple[float, float, float, bool, float]] = []
    lm = 0.0
    for it in range(options.max_iter + 1):
        t0 = time.perf_counter()
        xs = x.reshape(shape)
        grads = [t.gradient(xs) for t in terms]
        g = sum(grads)[fidx]
        tm.assembly += time.perf_counter() - t0
        r = float(np.linalg.norm(g))
        # relative to the forces in play: the largest term's force magnitude (a solid's internal
        # force flux without cancellation; a load's or contact's own force), with the problem's
        # force scale only as a floor far below any real force
        in_play = max(
            float(np.linalg.norm((t.force_flux(xs) if hasattr(t, "force_flux") else gt)[fidx]))
            for t, gt in zip(terms, grads)
        )
        tol = max(options.rtol * in_play, 1e-10 * force_scale)  # floor: round-off of the residual
        residuals.append(r)
        if not np.isfinite(r):
            return NewtonResult(xs.copy(), False, it, r, E, "residual is not finite", residuals, tm, trace)
        if r <= tol:
            return NewtonResult(xs.copy(), True, it, r, E, "converged", residuals, tm, trace)
        if it == options.max_iter:
            break
        project = options.projection == "always"
        t0 = time.perf_counter()
        H = sum(t.hessian(xs, project) for t in terms)
        Hff = sp.csr_matrix(H)[fidx][:, fidx]
        tm.assembly += time.perf_counter() - t0
        t0 = time.perf_counter()
        # Damping changes the step, never the equilibrium: K = H + tau diag|H| + eps mean|diag H| I.
        # - eps = 1e-9, always: a floating body's rigid modes are an exact null space, in which a
        #   singular solve returns an arbitrary drift that no residual check can see.
        # - tau ("adaptive"): grown only while the step does not descend. An indefinite Hessian
        #   whose Newton step still descends is kept: it converged a swelling layer in 4
        #   iterations per step, where requiring definiteness damped it into stagnation.
        #   Projecting element Hessians instead discards the curvature of every gel element
        #   (each is non-convex alone while the assembly is stable): 2204 iterations on a jammed
        #   packing against 1587 with tau.
        # - lm: a Marquardt term grown while CCD or the line search cut steps hard (a particle
        #   held only by barely-active barriers has almost no stiffness, so plain Newton predicts
        #   a huge rigid motion that CCD reduces to a few percent, iteration after iteration).
        fallback = any(getattr(t, "fallback_projection", False) for t in terms)
        hdiag = abs(Hff.diagonal())
        eps = 1e-9 * hdiag.mean()
        tau, dx, slope = lm, None, 0.0
        for attempt in range(16):
            if attempt == 1 and options.projection == "adaptive" and fallback:
                # the barrier's own negative curvature (b'(d) times the curvature of the distance)
                # is what makes a contact Hessian indefinite: project it per contact, as IPC does,
                # before damping the whole system (about 15% fewer iterations on a one-particle actuator)
                Hff = sp.csr_matrix(sum(t.hessian(xs, getattr(t, "fallback_projection", False))
                                        for t in terms))[fidx][:, fidx]
                tau = lm
            K = Hff + sp.diags(tau * hdiag + eps, format="csr")
            try:
                cand = solver.solve(K, -g)
            except LinearSolveError:
                cand = None

            if cand is not None and np.linalg.norm(K @ cand + g) <= 1e-6 * r:
                slope = float(g @ cand)
                if options.projection != "adaptive" or slope < 0:
                    dx = cand
                    break
            tau = max(10.0 * tau, 1e-8)
        tm.linear_solve += time.perf_counter() - t0
        if dx is None:
            return NewtonResult(xs.copy(), False, it, r, E, "linear solve failed (singular Hessian)", residuals, tm, trace)
        lm = tau
        if slope >= 0:  # "never"/"always" with a non-descent direction: a scaled gradient step
            dx = -g / max(hdiag.max(), 1e-300)
            slope = float(g @ dx)
        # a decrement at round-off of the energy: nothing left to gain
        if tau == 0 and -slope <= 1e-14 * abs(E) and r <= options.stall_factor * tol:
            return NewtonResult(xs.copy(), True, it, r, E, "converged (decrement at round-off)", residuals, tm, trace)
        step = np.zeros_like(x)
        step[fidx] = dx
        t0 = time.perf_counter()
        alpha = cap = min([1.0] + [t.max_step(xs, step.reshape(shape)) for t in terms])
        tm.step_cap += time.perf_counter() - t0
        t0 = time.perf_counter()
        slack = 1e-12 * abs(E)  # energy round-off: lets full Newton steps through near convergence
        while alpha >= options.min_alpha:
            xn = x + alpha * step
            En = _sum_energy(terms, xn.reshape(shape))
            if np.isfinite(En) and En <= E + options.armijo * alpha * slope + slack:
                break
            alpha *= 0.5
        tm.line_search += time.perf_counter() - t0
        tm.iterations += 1
        trace.append((r, alpha, cap, project, tau))
        if alpha < options.min_alpha:
            if r <= options.stall_factor * tol:
                # within stall_factor of the tolerance and no representable descent along the
                # Newton direction: the energy is at its round-off floor, not stuck
                return NewtonResult(xs.copy(), True, it, r, E, "converged (no descent left above round-off)",
                                    residuals, tm, trace)
            return NewtonResult(xs.copy(), False, it, r, E, "line search failed (no admissible descent)", residuals, tm, trace)
        x, E = xn, En
        if alpha < 0.1:
            lm = min(max(10.0 * lm, 1e-4), 1e4)
        elif alpha == 1.0:
            lm = lm / 10.0 if lm > 1e-6 else 0.0
    xs = x.reshape(shape)
    return NewtonResult(xs.copy(), False, options.max_iter, residuals[-1], E, f"no convergence in {options.max_iter} iterations", residuals, tm, trace)


# --------------------------------------------------------------------------------------------
# Load path


@dataclass(frozen=True)
class PathOptions:
    """Adaptive load stepping in s: grow ``grow``x after easy steps (<= ``easy_iterations``),
    halve on failure, give up below ``ds_min``."""

    ds0: float = 0.25
    ds_min: float = 1e-4
    ds_max: float = 1.0
    grow: float = 1.5
    easy_iterations: int = 6
    newton: NewtonOptions = NewtonOptions()


@dataclass(frozen=True)
class StepRecord:
    """One accepted load step."""

    s: float
    ds: float
    iterations: int
    residual: float
    energy: float
    seconds: float


@dataclass(frozen=True)
class PathResult:
    """Outcome of a load path: the last converged state and the step history."""

    x: np.ndarray  # last converged positions (n, d) [mm]
    s: float  # load parameter reached
    converged: bool  # reached s = 1
    message: str
    history: list[StepRecord]
    states: list[tuple[float, np.ndarray]]  # (s, x) of every accepted step, when kept
    timings: Timings
    rejected_steps: int

    @property
    def newton_iterations(self) -> int:
        return sum(h.iterations for h in self.history)


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
        step = (trial - x).reshape(shape)
        if min([1.0] + [t.max_step(xs, step) for t in terms]) < 1.0:
            continue
        if np.isfinite(_sum_energy(terms, trial.reshape(shape))):
            return trial
    return None


def solve_path(
    problem: Problem,
    options: PathOptions = PathOptions(),
    x0: np.ndarray | None = None,
    keep_states: bool = False,
    callback: Callable[[float, np.ndarray, StepRecord], None] | None = None,
    raise_on_failure: bool = False,
    on_attempt: Callable[[float, float, NewtonResult], None] | None = None,
) -> PathResult:
    """Follow s from 0 to 1 in adaptive increments, each an energy minimisation.

    On failure below the minimum increment, returns (or raises, on request) with the last
    converged state and a message saying where and why. ``callback(s, x, record)`` runs after
    every accepted step, ``on_attempt(s_try, ds, newton_result)`` after every attempt (progress).
    """
    solver = LinearSolver(options.newton.linear_solver)
    free = problem.free_mask()
    x = (problem.X if x0 is None else np.asarray(x0, dtype=float)).ravel().copy()
    problem.apply_dirichlet(x, 0.0)
    tm = Timings()
    history: list[StepRecord] = []
    states: list[tuple[float, np.ndarray]] = []
    # equilibrate at s = 0 first (a no-op for a stress-free reference)
    s, ds, rejected = 0.0, options.ds0, 0
    res0 = minimize(problem.terms(0.0), x.reshape(problem.X.shape), free, problem.force_scale, options.newton, solver)
    tm.add(res0.timings)
    if not res0.converged:
        msg = f"could not equilibrate the initial state (s = 0): {res0.message}"
        if raise_on_failure:
            raise ConvergenceError(msg)
        return PathResult(x.reshape(problem.X.shape), 0.0, False, msg, history, states, tm, 0)
    x = res0.x.ravel().copy()
    if keep_states:
        states.append((0.0, res0.x.copy()))
    message = "converged"
    newton, last_resort = options.newton, False
    while s < 1.0 - 1e-12:
        ds = min(ds, 1.0 - s)
        s_try = s + ds
        t0 = time.perf_counter()
        terms = problem.terms(s_try)
        x_bc = x.copy()
        problem.apply_dirichlet(x_bc, s_try)
        for t in terms:  # lagged quantities (friction) freeze at the start of the step
            if hasattr(t, "begin_step"):
                t.begin_step(x.reshape(problem.X.shape))
        x_start = _predictor(problem, terms, x, x_bc, free, solver)
        if x_start is None:
            res = NewtonResult(x.reshape(problem.X.shape), False, 0, np.inf, np.inf,
                               "the prescribed displacement increment is not admissible", [], Timings())
        else:
            res = minimize(terms, x_start.reshape(problem.X.shape), free, problem.force_scale, newton, solver)
        tm.add(res.timings)
        if on_attempt is not None:
            on_attempt(s_try, ds, res)
        if res.converged:
            newton, last_resort = options.newton, False
            s = s_try
            x = res.x.ravel().copy()
            rec = StepRecord(s, ds, res.iterations, res.residual, res.energy, time.perf_counter() - t0)
            history.append(rec)
            if keep_states:
                states.append((s, res.x.copy()))
            if callback is not None:
                callback(s, res.x, rec)
            if res.iterations <= options.easy_iterations:
                ds = min(ds * options.grow, options.ds_max)
        else:
            rejected += 1
            ds *= 0.5
            if ds < options.ds_min and not last_resort and "no convergence" in res.message:
                # A snap (jammed particles rearranging) has no nearby equilibrium: the state must
                # travel, which takes many iterations, not a smaller increment. One long attempt.
                last_resort, ds = True, 2.0 * ds
                newton = dataclasses.replace(options.newton, max_iter=10 * options.newton.max_iter)
                continue
            if ds < options.ds_min:
                message = (
                    f"load step failed at s = {s_try:.6g} (increment {2 * ds:.3g} < minimum {options.ds_min:g}): "
                    f"{res.message}; last converged state kept at s = {s:.6g}"
                )
                if raise_on_failure:
                    raise ConvergenceError(message)
                return PathResult(x.reshape(problem.X.shape), s, False, message, history, states, tm, rejected)
    return PathResult(x.reshape(problem.X.shape), s, True, message, history, states, tm, rejected)
