"""The benchmarks' instruments, run on a small problem: they wrap hydrojam's internals, so a
change of an internal signature breaks them without any benchmark being run."""

import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.linsolve import LinearSolver
from hydrojam.fem.newton import minimize
from hydrojam.fem.terms import EnergyTerm

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _trace import FIELDS, IterationTrace  # noqa: E402


class _Quartic(EnergyTerm):
    """sum (x - 1)^4 / 4 + (x - 1)^2 / 2 [mJ]: one minimum at x = 1, a few Newton iterations."""

    name = "quartic"

    def energy(self, x):
        u = x.ravel() - 1.0
        return float(np.sum(u**4 / 4 + u**2 / 2))

    def gradient(self, x):
        u = x.ravel() - 1.0
        return u**3 + u

    def hessian(self, x, project=False):
        u = x.ravel() - 1.0
        return sp.diags(3 * u**2 + 1.0, format="csr")


def test_the_iteration_trace_records_every_newton_iteration_and_restores_the_solver():
    """Installed, the trace sees every iteration of a minimisation (with the linear solver's reach
    hint passed through) and writes its columns; uninstalled, Newton's helpers are back."""
    import hydrojam.fem.newton as newton

    saved = newton._direction, newton._line_search, newton._marquardt_update, LinearSolver.solve
    trace = IterationTrace()
    trace.install()
    try:
        res = minimize([_Quartic()], np.full((4, 1), 3.0), np.ones(4, dtype=bool), 1.0)
    finally:
        trace.uninstall()
    assert res.converged and res.iterations == len(trace.rows) > 0
    assert all(set(row) == set(FIELDS) for row in trace.rows)
    assert (newton._direction, newton._line_search, newton._marquardt_update, LinearSolver.solve) == saved
    assert "iterations over 1 steps" in trace.summary("quartic")
