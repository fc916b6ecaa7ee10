"""A per-iteration trace of Newton (``benchmarks/path.py --trace``): an observer of the solver
(:mod:`hydrojam.fem.solver.events`) that records for every iteration

- ``step``: the accepted load steps before it (the iteration belongs to the next one; a
  step's release rounds and its rejected attempts are counted in it too; the release of a
  stabilisation at the end of a path in the last step),
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

from hydrojam.fem import Observer

FIELDS = ("step", "residual", "tolerance", "tau", "cap", "alpha", "trials", "dE", "step_max", "stabilisation", "pairs",
          "analysis", "solves", "negative", "substitutions", "projected", "curvature")


class IterationTrace(Observer):
    """Records every Newton iteration of the minimisations it observes (see the module docstring)."""

    def __init__(self):
        self.rows: list[dict] = []
        self._row: dict = {}
        self._steps = 0

    def on_step_accepted(self, event) -> None:
        """An accepted state (s = 0 included): later iterations belong to the next step."""
        self._steps += 1 if event.s > 0 else 0

    def on_direction(self, event) -> None:
        row = self._row
        row.clear()
        solves = [e for e in event.solves if e.call == "solve"]
        first = solves[0] if solves else None
        row.update(step=self._steps, residual=event.residual, tolerance=event.tolerance, tau=event.damping,
                   projected=int(event.projected), trials=0, analysis=sum(e.analysed for e in event.solves),
                   solves=len(solves), substitutions=len(event.solves) - len(solves),
                   negative="" if first is None else (1 if first.refused else (
                       "" if first.negative_eigenvalues is None else first.negative_eigenvalues)))
        stab = next((t for t in event.terms if t.name == "stabilisation"), None)
        row["stabilisation"] = 0.0 if stab is None else float(getattr(stab, "scale", 0.0))
        contact = next((t for t in event.terms if t.name == "contact"), None)
        inner = getattr(contact, "_term", contact)  # inside a TimedTerm (simulate's clocks)
        if inner is not None and hasattr(inner, "_collisions"):
            row["pairs"] = len(inner._collisions(event.x)[1])

    def on_line_search(self, event) -> None:
        row = self._row
        row["cap"], row["trials"], row["dE"] = event.cap, event.trials, event.energy_change
        row["step_max"] = float(np.abs(event.alpha * event.step).max())

    def on_iteration(self, event) -> None:
        row = self._row
        row["alpha"], row["curvature"] = event.alpha, event.curvature_move
        self.rows.append({k: row.get(k, "") for k in FIELDS})

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
