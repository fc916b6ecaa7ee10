"""Where a run's wall time goes, piece by piece (``benchmarks/path.py --pieces``): an observer of
the solver (:mod:`hydrojam.fem.solver.events`) that adds up the seconds the solver reports for
the pieces of a Newton iteration (the Hessians' free sum, the direction, the step cap (CCD), the
line search and the curvature step) and of the linear solver (its calls, the pattern
bookkeeping, the refinement, and PARDISO's calls split by phase (analysis, factorisation,
substitution) and by matrix type (the LDL^T, the Cholesky), the factorisations it refused
apart), and, from a simulation's result, the energy terms' own methods (the elastic and contact
terms' energy, gradient, Hessian, step cap, reach pattern). Nested pieces overlap (PARDISO's
calls lie within the direction, the contact's step cap within the step cap), so the shares do
not add up to 100 %. Unlike cProfile, the clocks add next to nothing to the Python-heavy
pieces, so their shares are those of a run without them.
"""

from __future__ import annotations

import collections

from hydrojam.fem import Observer

#: PARDISO's phases as the timer names them
PHASES = {11: "analysis", 12: "analysis + factorisation", 13: "analysis + factorisation + substitution",
          22: "factorisation", 23: "factorisation + substitution", 33: "substitution"}


def pardiso_label(phase: int, kind: str, failed: bool = False) -> str:
    """The name of one of PARDISO's calls: its phase and matrix type ("Cholesky", mtype 2; "LDL^T",
    -2), " refused" where it failed."""
    return f"PARDISO {PHASES.get(phase, f'phase {phase}')} ({kind})" + (" refused" if failed else "")


class PieceTimer(Observer):
    """Wall-clock seconds and calls of each piece the solver reports while it observes."""

    def __init__(self):
        self.seconds: dict[str, float] = collections.defaultdict(float)
        self.calls: collections.Counter = collections.Counter()

    def _add(self, name: str, seconds: float, calls: int = 1) -> None:
        self.seconds[name] += seconds
        self.calls[name] += calls

    def on_direction(self, event) -> None:
        self._add("Newton direction", event.seconds)
        self._add("Hessians summed (free block)", event.sum_seconds)

    def on_line_search(self, event) -> None:
        self._add("step cap (CCD)", event.cap_seconds)
        if event.searched:
            self._add("line search", event.seconds)

    def on_iteration(self, event) -> None:
        if event.curvature_seconds > 0:
            self._add("curvature step", event.curvature_seconds)

    def on_linear_solve(self, event) -> None:
        self._add(f"linear solver ({event.call})", event.seconds)
        if event.pattern_seconds:
            self._add("union pattern", event.pattern_seconds)
        if event.refine_seconds:
            self._add("refinement in double", event.refine_seconds)
        for phase, kind, seconds, failed in event.pardiso:
            self._add("PARDISO calls", seconds)
            self._add(pardiso_label(phase, kind, failed), seconds)

    def add_terms(self, clocks: dict[str, tuple[float, int]]) -> None:
        """The energy terms' methods, timed by a simulation (its ``timings["terms"]``:
        "term.method" -> (seconds, calls))."""
        for name, (seconds, calls) in clocks.items():
            self._add(name, seconds, calls)

    def summary(self, label: str, wall: float) -> str:
        """The pieces, costliest first: calls, seconds, ms a call and share of ``wall`` [s]."""
        lines = [f"  {label}: where the wall time went (nested pieces overlap)"]
        width = max(map(len, self.seconds), default=0)
        for name in sorted(self.seconds, key=self.seconds.get, reverse=True):
            s, n = self.seconds[name], self.calls[name]
            lines.append(f"    {name:{width}s} {n:7d} calls {s:8.1f} s {1e3 * s / max(n, 1):8.2f} ms a call "
                         f"{s / wall:6.1%}")
        return "\n".join(lines)
