"""Where a run's wall time goes, piece by piece (``benchmarks/path.py --pieces``): wall-clock
timers wrapped around the pieces of a Newton iteration (the Hessians, their sum and free block,
the linear solver's pattern bookkeeping and PARDISO's calls, the contact's CCD, reach pattern,
energies and collision sets, the line search and the curvature step), read from outside like
the trace. PARDISO's calls are split by phase (analysis, factorisation, substitution) and by
matrix type (the LDL^T, the Cholesky), with the factorisations it refused apart. Nested pieces
overlap (PARDISO's calls lie within the direction, the reach within the union pattern), so the
shares do not add up to 100 %. Unlike cProfile, the timers add next to
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


#: PARDISO's phases as the timer names them (``_Pardiso._call``'s second argument)
PHASES = {11: "analysis", 12: "analysis + factorisation", 13: "analysis + factorisation + substitution",
          22: "factorisation", 23: "factorisation + substitution", 33: "substitution"}


def pardiso_label(handle, phase: int, *args, **kwargs) -> str:
    """The name of one of PARDISO's calls: its phase and matrix type (mtype 2, the Cholesky;
    -2, the LDL^T)."""
    kind = "Cholesky" if handle.mtype == 2 else "LDL^T"
    return f"PARDISO {PHASES.get(phase, f'phase {phase}')} ({kind})"


#: pieces whose calls are also timed under a name of their own: (owner, attribute) -> the
#: function that names a call from its arguments
SPLITS = {(linsolve._Pardiso, "_call"): pardiso_label}


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
            setattr(owner, name, self._timed(original, f"{owner.__name__.split('.')[-1]}.{name}",
                                             SPLITS.get((owner, name))))

    def _timed(self, f, label: str, split=None):
        """f timed under ``label``; with ``split(*args)``, also under the name it gives the call
        (a refused call, one that raised, with " refused")."""
        @functools.wraps(f)
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            failed = False
            try:
                return f(*args, **kwargs)
            except BaseException:
                failed = True
                raise
            finally:
                dt = time.perf_counter() - t0
                self.seconds[label] += dt
                self.calls[label] += 1
                if split is not None:
                    part = split(*args, **kwargs) + (" refused" if failed else "")
                    self.seconds[part] += dt
                    self.calls[part] += 1
        return timed

    def uninstall(self) -> None:
        for owner, name, original in self._saved or []:
            setattr(owner, name, original)
        self._saved = None

    def summary(self, label: str, wall: float) -> str:
        """The pieces, costliest first: calls, seconds, ms a call and share of ``wall`` [s]."""
        lines = [f"  {label}: where the wall time went (nested pieces overlap)"]
        width = max(map(len, self.seconds), default=0)
        for name in sorted(self.seconds, key=self.seconds.get, reverse=True):
            s, n = self.seconds[name], self.calls[name]
            lines.append(f"    {name:{width}s} {n:7d} calls {s:8.1f} s {1e3 * s / n:8.2f} ms a call {s / wall:6.1%}")
        return "\n".join(lines)
