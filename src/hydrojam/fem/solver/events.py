"""What the solver reports while it works: its events and the observers that receive them.

An observer is any object with one or more of the methods of :class:`Observer` (subclass it to
inherit no-ops for the rest). :func:`~hydrojam.fem.solver.newton.minimize`,
:func:`~hydrojam.fem.solver.path.solve_path`, :func:`~hydrojam.fem.solver.release.release`,
:func:`~hydrojam.fem.solver.stability.settle` and
:class:`~hydrojam.fem.solver.linsolve.LinearSolver` take a sequence of observers and call each
one's method for every event, in the order they were given. With none given no event is built:
observing costs nothing then, and it never changes what the solver computes.

Events, in the order one Newton iteration raises them:

- :class:`LinearSolve`: every factorisation (:meth:`LinearSolver.solve
  <hydrojam.fem.solver.linsolve.LinearSolver.solve>`) and every further substitution on it
  (``resolve``), with PARDISO's calls phase by phase and whether a new sparsity pattern was
  analysed;
- :class:`Direction`: the damped Newton direction, before its line search;
- :class:`LineSearch`: the step along it, with the terms' step cap (contact CCD) and the trials;
- :class:`Iteration`: the iteration accepted (the state moved).

And on the load path: :class:`ReleaseRound` after every round of a release, :class:`StepAccepted`
after every accepted load step (and once for the equilibrated start, s = 0).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np


@dataclass(frozen=True)
class LinearSolve:
    """One call of the linear solver."""

    call: Literal["solve", "resolve"]
    """"solve": a factorisation (with its substitution); "resolve": a substitution on the last one."""
    method: str
    """The backend, "pardiso" or "scipy"."""
    analysed: bool
    """Whether a new sparsity pattern was analysed (the pattern changed); False for "resolve"."""
    failed: bool
    """Whether the call raised (a singular matrix, or a Cholesky refused: not positive definite)."""
    refused: bool
    """Whether it was a Cholesky that refused the matrix as not positive definite."""
    negative_eigenvalues: int | None
    """The inertia of the matrix factorised (None where unknown, and after a failed call)."""
    seconds: float
    """Wall time of the call [s]."""
    pattern_seconds: float = 0.0
    """Of it, the pattern bookkeeping (the matrix laid on the union pattern) [s]."""
    refine_seconds: float = 0.0
    """Of it, the refinement of a single-precision solution in double [s]."""
    pardiso: tuple[tuple[int, str, float, bool], ...] = ()
    """PARDISO's calls within it: (phase, matrix type "Cholesky" or "LDL^T", seconds, failed)."""


@dataclass(frozen=True)
class Direction:
    """A Newton direction computed at an iterate (before its line search)."""

    terms: Sequence[Any]
    """The energy terms minimised."""
    x: np.ndarray
    """The iterate (n, d) [mm]."""
    iteration: int
    """The iteration's index in its minimisation (0 first)."""
    residual: float
    """||g|| over the free DOFs at the iterate [N]."""
    tolerance: float
    """The residual tolerance of the minimisation [N]."""
    damping: float
    """The damping tau of the accepted K, relative to diag|H|."""
    projected: bool
    """Whether the contact Hessian was projected in the accepted K."""
    seconds: float
    """Wall time of the direction, its linear solves included [s]."""
    sum_seconds: float = 0.0
    """Wall time of the terms' Hessians summed and cut to the free DOFs before it [s]."""
    solves: tuple[LinearSolve, ...] = ()
    """The linear solver's calls that made the direction, in order."""


@dataclass(frozen=True)
class LineSearch:
    """The step taken along a direction."""

    terms: Sequence[Any]
    """The energy terms minimised."""
    x: np.ndarray
    """The iterate the step starts from (n, d) [mm]."""
    step: np.ndarray
    """The direction on all DOFs (n, d) [mm], zero on the fixed ones: the full Newton step."""
    cap: float
    """The terms' step cap (contact CCD): the longest admissible fraction of ``step``, at most 1."""
    alpha: float
    """The accepted fraction of ``step`` (below the options' ``min_alpha``: none was found)."""
    trials: int
    """Energy evaluations of the backtracking search (0 where the full step was judged by its residual)."""
    energy_change: float
    """E(x + alpha step) - E(x) [mJ]."""
    searched: bool
    """Whether the backtracking search ran (False: the full step near the tolerance, judged by its residual)."""
    seconds: float
    """Wall time of the search [s]."""
    cap_seconds: float = 0.0
    """Wall time of the step cap [s]."""


@dataclass(frozen=True)
class Iteration:
    """A Newton iteration accepted: the state moved."""

    iteration: int
    """The iteration's index in its minimisation."""
    alpha: float
    """The accepted step length (fraction of the Newton step)."""
    curvature_move: float
    """Largest nodal move [mm] of the extra step along the full K's negative curvature (0: none)."""
    energy: float
    """The energy at the new state [mJ]."""
    seconds: float
    """Wall time of the iteration, from its Hessians [s]."""
    curvature_seconds: float = 0.0
    """Of it, the step along the negative curvature [s]."""


@dataclass(frozen=True)
class StepAccepted:
    """A load step accepted: the path reached ``s`` (after the release and any settling)."""

    s: float
    """The load parameter reached (0: the equilibrated start)."""
    x: np.ndarray
    """The accepted state (n, d) [mm]."""
    record: Any = None
    """Its :class:`~hydrojam.fem.solver.path.StepRecord` (None for the start)."""


@dataclass(frozen=True)
class ReleaseRound:
    """One proximal round of a release of a damped term."""

    scale: float
    """The damped term's scale in the round (its own, absolute)."""
    iterations: int
    """Newton iterations of the round."""
    converged: bool
    """Whether the round's minimisation converged."""


class Observer:
    """The observer protocol, with a no-op for every event: subclass it and override what you
    need (or give any object with some of these methods)."""

    def on_linear_solve(self, event: LinearSolve) -> None:
        """A factorisation or a substitution."""

    def on_direction(self, event: Direction) -> None:
        """A Newton direction computed."""

    def on_line_search(self, event: LineSearch) -> None:
        """A step taken along it."""

    def on_iteration(self, event: Iteration) -> None:
        """A Newton iteration accepted."""

    def on_step_accepted(self, event: StepAccepted) -> None:
        """A load step accepted."""

    def on_release_round(self, event: ReleaseRound) -> None:
        """A round of a release."""


def notify(observers: Sequence[Any], method: str, event: object) -> None:
    """Call ``method`` (an :class:`Observer` method's name) with ``event`` on each observer that
    has it, in order."""
    for o in observers:
        handler = getattr(o, method, None)
        if handler is not None:
            handler(event)
