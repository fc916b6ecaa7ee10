"""Stability of an equilibrium: the negative eigenvalues of the physics' unprojected Hessian
(:func:`negative_curvature`), its lowest mode (:func:`lowest_mode`), and settling an unstable
equilibrium (a saddle: Newton converges to any stationary point) off its saddle to a stable one
(:func:`settle`)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from hydrojam.fem.solver.events import Observer
from hydrojam.fem.solver.linsolve import LinearSolver, LinearSolveError
from hydrojam.fem.solver.newton import NewtonOptions, Timings, minimize
from hydrojam.fem.solver.total import TINY, free_sum, physical_residual, sum_energy
from hydrojam.fem.terms import EnergyTerm

_MODE_SHIFT = 1e-3  # x mean|diag H|: lowest_mode's preconditioner shift; much smaller, its inverse
# overweights the projected Hessian's soft modes and LOBPCG settles on them (docs/solver.md)
_MODE_TOLERANCE = 1e-5  # x mean|diag H|: lowest_mode's LOBPCG residual norm (a direction, not a spectrum)


def negative_curvature(
    terms: Sequence[EnergyTerm],
    x: np.ndarray,
    free: np.ndarray,
    solver: LinearSolver,
    options: NewtonOptions = NewtonOptions(),
) -> int | None:
    """Number of negative eigenvalues of the unprojected Hessian of ``terms`` over the free DOFs
    at x: 0 where x is a stable equilibrium of these terms, > 0 where it is unstable (a saddle,
    or a state held by terms left out).

    One factorisation of H_ff + eps mean|diag H_ff| I, eps = ``options.regularisation`` (the
    shift the Newton solve adds), whose inertia the solver reports: eigenvalues above
    -eps mean|diag H_ff| count as non-negative, so the exact null space of a floating body and
    round-off around it never count.

    Parameters
    ----------
    terms : sequence of EnergyTerm
        The energy whose stability is tested (the physics: leave a stabilisation out).
    x : ndarray, shape (n, d)
        Positions [mm].
    free : ndarray of bool, shape (n*d,)
        The free DOFs.
    solver : LinearSolver
        Factorises H_ff (its last factorisation is replaced: give the check its own solver where
        the Newton solver's round-off must not change).
    options : NewtonOptions, optional
        Its ``regularisation`` sets the shift.

    Returns
    -------
    int or None
        The number of negative eigenvalues (0 where no DOF is free); None where the solver does
        not report the inertia (SciPy) or the factorisation fails.
    """
    xs = np.asarray(x, dtype=float)
    fidx = np.flatnonzero(free)
    if fidx.size == 0:
        return 0
    Hff = free_sum([t.hessian(xs, False) for t in terms], fidx)
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
    H = free_sum([t.hessian(xs, False) for t in terms], fidx)
    hdiag = abs(H.diagonal())
    H = H + sp.diags(np.full(len(fidx), options.regularisation * hdiag.mean()), format="csr")
    block = 3
    if len(fidx) <= 5 * block:  # LOBPCG itself falls back to a dense solver there
        w, V = np.linalg.eigh(H.toarray())
        value, vec = float(w[0]), V[:, 0]
    else:
        P = free_sum([t.hessian(xs, True) for t in terms], fidx)
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
    return value, mode / max(float(np.linalg.norm(mode, axis=1).max()), TINY)


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


def settle(terms, x: np.ndarray, free: np.ndarray, force_scale: float, newton: NewtonOptions,
           solver: LinearSolver, checker: LinearSolver, perturbation: float = 1e-5, tries: int = 3,
           observers: Sequence[Observer] = ()) -> Settled:
    """Move an unstable equilibrium x (n, d) [mm] of ``terms`` (the physics) off its saddle, along
    its unstable mode: the Hessian's lowest eigenpair (:func:`lowest_mode`), followed downhill
    from a largest nodal move of ``perturbation`` x the bounding box diagonal, doubled while the
    energy falls (:func:`_down_the_mode`), then the full Newton
    from the lowest state on it. Below the saddle's energy the monotone descent cannot come back
    to it. Up to ``tries`` times, from each unstable equilibrium reached; the result is the first
    stable state, or x itself with its count where none was reached."""
    xs = np.asarray(x, dtype=float)
    size = float(np.linalg.norm(xs.max(axis=0) - xs.min(axis=0)))
    spent, its = Timings(), 0
    negative, current = None, xs
    for _ in range(tries):
        value, mode = lowest_mode(terms, current, free, checker, newton)
        if not value < 0:
            break
        start = _down_the_mode(terms, current, mode, perturbation * size, size)
        if start is None:
            break
        res = minimize(terms, start, free, force_scale, newton, solver, observers)
        spent.add(res.timings)
        its += res.iterations
        if not res.converged:
            break
        negative = negative_curvature(terms, res.x, free, checker, newton)
        if negative == 0:
            r, tol = physical_residual(terms, res.x, free, force_scale, newton.rtol, (), newton.residual_floor)
            return Settled(res.x, 0, its, r, tol, spent)
        current = res.x
    r, tol = physical_residual(terms, xs, free, force_scale, newton.rtol, (), newton.residual_floor)
    return Settled(xs, negative, its, r, tol, spent)
