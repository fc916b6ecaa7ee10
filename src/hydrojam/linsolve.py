"""Sparse direct solves for the Newton step: MKL PARDISO (pypardiso) by default, SciPy as fallback.

The Newton matrices are symmetric, so PARDISO runs as a real symmetric indefinite solver
(``mtype = -2``) on the upper triangle: half the fill and work of the general LU.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class LinearSolveError(RuntimeError):
    """The linear system could not be solved (singular or not finite)."""


def _pardiso_available() -> bool:
    try:
        import pypardiso  # noqa: F401
    except Exception:  # pragma: no cover - missing MKL on exotic platforms
        return False
    return True


class LinearSolver:
    """Solve K u = b for symmetric sparse K.

    ``method``: "pardiso", "scipy" or "auto" (PARDISO where it loads, else SciPy's SuperLU).
    ``seconds`` accumulates the wall time spent in solves [s] (for benchmarks).
    """

    def __init__(self, method: str = "auto"):
        if method not in ("auto", "pardiso", "scipy"):
            raise ValueError(f"linear solver must be 'auto', 'pardiso' or 'scipy' (got {method!r})")
        if method == "auto":
            method = "pardiso" if _pardiso_available() else "scipy"
        self.method = method
        self.seconds = 0.0
        self.calls = 0
        self._pardiso = None

    def _solve_pardiso(self, K: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        import pypardiso

        if self._pardiso is None:
            self._pardiso = pypardiso.PyPardisoSolver(mtype=-2)
            self._pardiso.set_statistical_info_off()
        upper = sp.triu(K, format="csr")
        upper.sort_indices()
        try:
            x = self._pardiso.solve(upper, b)
        finally:
            self._pardiso.free_memory(everything=False)
        return x

    def solve(self, K: sp.spmatrix, b: np.ndarray) -> np.ndarray:
        """Solution u of K u = b; raises LinearSolveError if it is not finite."""
        t0 = time.perf_counter()
        K = sp.csr_matrix(K, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        try:
            if self.method == "pardiso":
                x = self._solve_pardiso(K, b)
            else:
                x = spla.spsolve(K.tocsc(), b)
        except Exception as exc:  # PARDISO / SuperLU report singularity as exceptions
            raise LinearSolveError(f"{self.method}: {exc}") from exc
        finally:
            self.seconds += time.perf_counter() - t0
            self.calls += 1
        if not np.all(np.isfinite(x)):
            raise LinearSolveError(f"{self.method}: solution is not finite (singular matrix?)")
        return x
