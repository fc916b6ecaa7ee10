"""Energy-minimising solver (DESIGN.md section 8): projected Newton and an adaptive load path.

The solver knows only energy terms (value, gradient, Hessian, step cap; see ``terms.py``) and
Dirichlet conditions, which eliminate DOFs. Every accepted state has finite energy (admissible)
and respects every term's step cap (contact CCD).

Convergence: the residual norm over free DOFs ||g_f|| <= ``rtol`` * force scale, or, once the
residual is within ``stall_factor`` of that, a Newton decrement g.dx below round-off of the energy.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .linsolve import LinearSolver, LinearSolveError
from .terms import EnergyTerm


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
    """Newton settings. ``projection``: "adaptive" (the full Hessian, and the element-wise PSD
    projection only in an iteration where the full one gives no descent direction), "always"
    (projected Newton throughout, as in IPC) or "never".

    Adaptive is the default because projecting a stable but locally non-convex gel (every gel
    element under lateral constraint) discards real curvature: measured on a swelling layer,
    always-projected Newton needed 725 iterations where adaptive needed 20, quadratically.
    """

    rtol: float = 1e-8
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
    force_project = False
    tol = options.rtol * force_scale
    for it in range(options.max_iter + 1):
        t0 = time.perf_counter()
        xs = x.reshape(shape)
        g = sum(t.gradient(xs) for t in terms)[fidx]
        tm.assembly += time.perf_counter() - t0
        r = float(np.linalg.norm(g))
        residuals.append(r)
        if not np.isfinite(r):
            return NewtonResult(xs.copy(), False, it, r, E, "residual is not finite", residuals, tm)
        if r <= tol:
            return NewtonResult(xs.copy(), True, it, r, E, "converged", residuals, tm)
        if it == options.max_iter:
            break
        project = options.projection == "always" or force_project
        t0 = time.perf_counter()
        H = sum(t.hessian(xs, project) for t in terms)
        Hff = sp.csr_matrix(H)[fidx][:, fidx]
        tm.assembly += time.perf_counter() - t0
        t0 = time.perf_counter()
        dx = None
        # a singular Hessian (a body floating free before it touches anything) is regularised by
        # a shift that only changes the step, never the equilibrium (Levenberg-Marquardt)
        diag = abs(Hff.diagonal()).mean()
        for shift in (0.0, 1e-10, 1e-8, 1e-6, 1e-4):
            try:
                K = Hff if shift == 0 else Hff + shift * diag * sp.eye(len(fidx), format="csr")
                cand = solver.solve(K, -g)
            except LinearSolveError:
                continue
            if np.linalg.norm(K @ cand + g) <= 1e-6 * r:
                dx = cand
                break
        tm.linear_solve += time.perf_counter() - t0
        if dx is None:
            return NewtonResult(xs.copy(), False, it, r, E, "linear solve failed (singular Hessian)", residuals, tm)
        slope = float(g @ dx)
        if slope >= 0:
            if not project and options.projection != "never":
                force_project = True  # indefinite Hessian: fall back to the projected one
                continue
            dx = -g * (options.rtol + r) / (r * max(abs(Hff.diagonal()).max(), 1e-300))
            slope = float(g @ dx)
        # a decrement at round-off of the energy: nothing left to gain
        if -slope <= 1e-14 * abs(E) and r <= options.stall_factor * tol:
            return NewtonResult(xs.copy(), True, it, r, E, "converged (decrement at round-off)", residuals, tm)
        step = np.zeros_like(x)
        step[fidx] = dx
        t0 = time.perf_counter()
        alpha = min([1.0] + [t.max_step(xs, step.reshape(shape)) for t in terms])
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
        if alpha < options.min_alpha:
            return NewtonResult(xs.copy(), False, it, r, E, "line search failed (no admissible descent)", residuals, tm)
        x, E = xn, En
        force_project = False
    xs = x.reshape(shape)
    return NewtonResult(xs.copy(), False, options.max_iter, residuals[-1], E, f"no convergence in {options.max_iter} iterations", residuals, tm)


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
) -> PathResult:
    """Follow s from 0 to 1 in adaptive increments, each an energy minimisation.

    On failure below the minimum increment, returns (or raises, on request) with the last
    converged state and a message saying where and why.
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
            res = minimize(terms, x_start.reshape(problem.X.shape), free, problem.force_scale, options.newton, solver)
        tm.add(res.timings)
        if res.converged:
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
            if ds < options.ds_min:
                message = (
                    f"load step failed at s = {s_try:.6g} (increment {2 * ds:.3g} < minimum {options.ds_min:g}): "
                    f"{res.message}; last converged state kept at s = {s:.6g}"
                )
                if raise_on_failure:
                    raise ConvergenceError(message)
                return PathResult(x.reshape(problem.X.shape), s, False, message, history, states, tm, rejected)
    return PathResult(x.reshape(problem.X.shape), s, True, message, history, states, tm, rejected)
