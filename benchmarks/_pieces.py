"""Where a run's wall time goes, piece by piece (``benchmarks/path.py --pieces``): wall-clock
timers wrapped around the pieces of a Newton iteration (the Hessians, their sum and free block,
the linear solver's pattern bookkeeping and PARDISO's calls, the contact's CCD, reach pattern,
energies and collision sets, the line search and the curvature step), read from outside like
the trace. Nested pieces overlap (PARDISO's calls lie within the direction, the reach within the
union pattern), so the shares do not add up to 100 %. Unlike cProfile, the timers add next to
nothing to the Python-heavy pieces, so their shares are those of a run without them.
"""

from __future__ import annotations

import collections
import functools
import time

import hydrojam.fem.assembly as assembly
import hydrojam.fem.contact as contact
import hydrojam.fem.linsolve as linsolve
import hydrojam.fem.newton as newton

#: (owner, attribute) of every timed piece
PIECES = [
    (newton, "_direction"), (newton, "_free_sum"), (newton, "_line_search"), (newton, "_curvature_step"),
    (linsolve._Pardiso, "_call"), (linsolve.LinearSolver, "_on_union_pattern"), (linsolve.LinearSolver, "_refine"),
    (contact.Contact, "hessian"), (contact.Contact, "hessian_pattern"), (contact.Contact, "max_step"),
    (contact.Contact, "energy"), (contact.Contact, "gradient"), (contact.Contact, "_collisions"),
    (assembly.Solid, "hessian"), (assembly.Solid, "energy"), (assembly.Solid, "gradient"),
]


class PieceTimer:
    """Wall-clock seconds and calls of each piece in :data:`PIECES` while installed."""

    def __init__(self):
        self.seconds: dict[str, float] = collections.defaultdict(float)
        self.calls: collections.Counter = collections.Counter()
        self._saved: list | None = None

    def install(self) -> None:
        self._saved = []
        for owner, name in PIECES:
            original = getattr(owner, name)
            self._saved.append((owner, name, original))
            setattr(owner, name, self._timed(original, f"{owner.__name__.split('.')[-1]}.{name}"))

    def _timed(self, f, label: str):
        @functools.wraps(f)
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return f(*args, **kwargs)
            finally:
                self.seconds[label] += time.perf_counter() - t0
                self.calls[label] += 1
        return timed

    def uninstall(self) -> None:
        for owner, name, original in self._saved or []:
            setattr(owner, name, original)
        self._saved = None

    def summary(self, label: str, wall: float) -> str:
        """The pieces, costliest first: calls, seconds, ms a call and share of ``wall`` [s]."""
        lines = [f"  {label}: where the wall time went (nested pieces overlap)"]
        for name in sorted(self.seconds, key=self.seconds.get, reverse=True):
            s, n = self.seconds[name], self.calls[name]
            lines.append(f"    {name:34s} {n:7d} calls {s:8.1f} s {1e3 * s / n:8.2f} ms a call {s / wall:6.1%}")
        return "\n".join(lines)
