"""A per-iteration trace of Newton (``benchmarks/path.py --trace``), read from outside: it wraps
the helpers of :func:`hydrojam.fem.newton.minimize` (the direction, the line search, the
Marquardt update) and the linear solver, and records for every iteration

- ``step``: the accepted load steps before it (the iteration belongs to the next one; a
  step's release rounds and its rejected attempts are counted in it too),
- ``residual`` [N] at the iterate, ``tolerance`` [N] (that of the minimisation it is in),
  ``tau`` (the Marquardt damping used, relative to diag|H|),
- ``cap``: the step cap of the terms (contact CCD; 1 = none), ``alpha``: the accepted step length,
- ``trials``: energy evaluations of the line search, ``dE`` [mJ]: the energy change,
- ``step_max`` [mm]: the largest nodal move, ``stabilisation``: the damped term's scale (0 without),
- ``pairs``: active contact collisions at the iterate, ``analysis``: whether the linear solve
  analysed a new sparsity pattern, ``solves``: the factorisations the direction took,
  ``negative``: the negative eigenvalues of its first K (1 where a Cholesky factorisation refused
  it: at least one), ``substitutions``: solves on a factorisation already made, ``projected``:
  whether the contact Hessian was projected in the accepted K, ``curvature`` [mm]: the largest
  nodal move of the step along the full K's negative curvature after the line search
  (``NewtonOptions.curvature_step``; 0 where none was taken).

The summary says where the iterations went: capped steps (TOI locking), line-search cuts, and
the tail (iterations within 100x of the tolerance's residual, chasing near-neutral modes).
"""

from __future__ import annotations

import csv

import numpy as np

import hydrojam.fem.newton as newton
from hydrojam.fem.linsolve import LinearSolver, NotPositiveDefinite

FIELDS = ("step", "residual", "tolerance", "tau", "cap", "alpha", "trials", "dE", "step_max", "stabilisation", "pairs",
          "analysis", "solves", "negative", "substitutions", "projected", "curvature")


class IterationTrace:
    """Records every Newton iteration while installed (see the module docstring)."""

    def __init__(self):
        self.rows: list[dict] = []
        self._row: dict = {}
        self._steps = 0
        self._saved = None

    def step(self, s: float) -> None:
        """An accepted state was reported (s = 0 included): later iterations belong to the next step."""
        self._steps += 1 if s > 0 else 0

    def install(self) -> None:
        """Wrap newton's helpers and the linear solver (undone by :meth:`uninstall`)."""
        direction, line_search, update, solve, resolve, tolerance, curvature = (
            newton._direction, newton._line_search, newton._marquardt_update, LinearSolver.solve,
            LinearSolver.resolve, newton._tolerance, newton._curvature_step)
        self._saved = direction, line_search, update, solve, resolve, tolerance, curvature
        row = self._row
        last_tolerance = [float("nan")]

        def traced_tolerance(*args, **kwargs):
            last_tolerance[0] = tolerance(*args, **kwargs)
            return last_tolerance[0]

        def traced_direction(terms, xs, hessians, Hff, hdiag, g, r, lm, *args, **kwargs):
            row.clear()
            row.update(step=self._steps, residual=r, tolerance=last_tolerance[0], analysis=0, trials=0, solves=0,
                       substitutions=0)
            stab = next((t for t in terms if t.name == "stabilisation"), None)
            row["stabilisation"] = 0.0 if stab is None else float(getattr(stab, "scale", 0.0))
            contact = next((t for t in terms if t.name == "contact"), None)
            inner = getattr(contact, "_term", contact)  # inside a TimedTerm (simulate's clocks)
            if inner is not None and hasattr(inner, "_collisions"):
                row["pairs"] = len(inner._collisions(xs)[1])
            out = direction(terms, xs, hessians, Hff, hdiag, g, r, lm, *args, **kwargs)
            row["tau"], row["projected"] = out[2], int(out[3])
            return out

        def traced_line_search(terms, x, E, step, slope, shape, alpha, options, *rest):
            row["cap"] = alpha
            energy, trials = newton.sum_energy, [0]

            def counted(*args):  # one trial of the line search: one energy evaluation
                trials[0] += 1
                return energy(*args)

            newton.sum_energy = counted
            try:
                out = line_search(terms, x, E, step, slope, shape, alpha, options, *rest)
            finally:
                newton.sum_energy = energy
            row["trials"] = trials[0]
            row["dE"] = out[2] - E
            row["step_max"] = float(np.abs(out[0] * step).max())
            return out

        def traced_curvature(terms, x, E, p, g, fidx, accepted, shape, options):
            out = curvature(terms, x, E, p, g, fidx, accepted, shape, options)
            row["curvature"] = newton.largest_move(out[0] - x, shape)
            return out

        def traced_update(lm, alpha, options):
            row.setdefault("curvature", 0.0)
            row.setdefault("cap", 1.0)
            row["alpha"] = alpha
            self.rows.append({k: row.get(k, "") for k in FIELDS})
            return update(lm, alpha, options)

        def traced_solve(solver, K, b, reach=None, definite=False):
            before = solver.analyses
            failed = False
            try:
                return solve(solver, K, b, reach, definite)
            except NotPositiveDefinite:
                failed = True
                raise
            finally:
                row["analysis"] = row.get("analysis", 0) + (solver.analyses - before)
                row["solves"] = row.get("solves", 0) + 1
                if row["solves"] == 1:  # a failed Cholesky: at least one
                    row["negative"] = 1 if failed else ("" if solver.negative_eigenvalues is None
                                                        else solver.negative_eigenvalues)

        def traced_resolve(solver, b, **kw):
            row["substitutions"] = row.get("substitutions", 0) + 1
            return resolve(solver, b, **kw)

        newton._direction, newton._line_search, newton._marquardt_update, newton._tolerance, newton._curvature_step = (
            traced_direction, traced_line_search, traced_update, traced_tolerance, traced_curvature)
        LinearSolver.solve, LinearSolver.resolve = traced_solve, traced_resolve

    def uninstall(self) -> None:
        """Put newton's helpers and the linear solver back."""
        if self._saved is not None:
            (newton._direction, newton._line_search, newton._marquardt_update, LinearSolver.solve,
             LinearSolver.resolve, newton._tolerance, newton._curvature_step) = self._saved
            self._saved = None

    def write(self, path: str) -> None:
        """The rows as CSV."""
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, FIELDS)
            w.writeheader()
            w.writerows(self.rows)

    def summary(self, label: str) -> str:
        """Where the iterations went, in a few lines."""
        if not self.rows:
            return f"  {label}: no iterations traced"
        cap = np.array([r["cap"] for r in self.rows], dtype=float)
        alpha = np.array([r["alpha"] for r in self.rows], dtype=float)
        res = np.array([r["residual"] for r in self.rows], dtype=float)
        step = np.array([r["step"] for r in self.rows])
        tail = 0
        for k in np.unique(step):  # within a step: iterations whose residual is within 100x of the step's last
            rk = res[step == k]
            tail += int(np.sum(rk <= 100 * rk.min()))
        n = len(self.rows)
        analyses = sum(int(r["analysis"] or 0) for r in self.rows)
        return (f"  {label}: {n} iterations over {len(np.unique(step))} steps; CCD-capped {np.mean(cap < 1):.0%} "
                f"(median cap {np.median(cap[cap < 1]) if np.any(cap < 1) else 1:.2f}); line search cut "
                f"{np.mean(alpha < cap):.0%}; full steps {np.mean(alpha == 1):.0%}; median step length "
                f"{np.median(alpha):.2f}; in the tail (residual within 100x of the step's lowest) {tail / n:.0%}; "
                f"damped {np.mean([float(r['stabilisation'] or 0) > 0 for r in self.rows]):.0%}; "
                f"new patterns {analyses / n:.0%} of iterations; factorisations per iteration "
                f"{sum(int(r['solves'] or 0) for r in self.rows) / n:.2f}, substitutions "
                f"{sum(int(r['substitutions'] or 0) for r in self.rows) / n:.2f}; contact projected in "
                f"{np.mean([r['projected'] == 1 for r in self.rows]):.0%} of the directions; a step along the "
                f"negative curvature taken in {np.mean([float(r['curvature'] or 0) > 0 for r in self.rows]):.0%}")
