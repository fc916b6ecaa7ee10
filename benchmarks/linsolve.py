"""What the linear solve of a Newton iteration costs: PARDISO's own time against the bookkeeping
around it (the upper triangle, the union pattern), and PARDISO's settings, on the linear systems
an actuator simulation really solves.

Run:  .venv/bin/python benchmarks/linsolve.py [--design one_layer|default] [--solves N]

The problem
-----------
The design (``one_layer``: ``Design(particle_layers=1)``, 2238 DOFs; ``default``:
``default_design()``, 6678 DOFs) is simulated once with every matrix and right-hand side passed
to ``LinearSolver.solve`` recorded (the first ``--solves``, default 500; about 0.6 MB a system
for one layer, 1.8 MB for the default design). The recorded sequence is then replayed through a
fresh ``LinearSolver`` twice per variant, the faster pass kept:

Table 1 splits the replay's wall time per solve into PARDISO's own call (``_Pardiso.solve``) and
the rest (the upper-triangle gather, the union pattern, MKL's release before a new analysis),
for solves with a new symbolic analysis (phase 13) and for those reusing it (phase 23).

Table 2 replays the sequence under PARDISO settings (iparm, 1-based): MKL's defaults for mtype
-2 (METIS ordering iparm(2) = 3, two refinement steps always iparm(8) = 2) and the variants.
"max rel. residual" is max ||K x - b|| / ||b|| over the sequence; "dev. from MKL defaults" is
max ||x - x_default|| / ||x_default||: the settings change round-off, not the mathematics.

Reading the numbers: the header prints the load average; other processes on the machine inflate
the times (compare rows of one run, not runs). The solves and analyses are exact counts.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import fmt, print_environment, section, table  # noqa: E402
from hydrojam import Design, build_model, default_design, simulate  # noqa: E402
from hydrojam.fem import linsolve  # noqa: E402

VARIANTS = {
    "MKL defaults": {},
    "min. degree": {2: 0},
    "no forced refinement": {8: 0},
    "min. degree, no forced refinement": {2: 0, 8: 0},
    "min. degree + CNR (hydrojam)": {2: 0, 34: 1},
}


def record(design_name: str, limit: int) -> list:
    """The first ``limit`` (K, b) the simulation of the design solves."""
    systems = []
    original = linsolve.LinearSolver.solve

    def solve(self, K, b):
        if len(systems) < limit:
            systems.append((K.tocsr().copy(), np.array(b, dtype=float)))
        return original(self, K, b)

    design = default_design() if design_name == "default" else Design(particle_layers=1)
    linsolve.LinearSolver.solve = solve
    try:
        simulate(build_model(design))
    finally:
        linsolve.LinearSolver.solve = original
    return systems


def replay(systems, settings: dict[int, int]):
    """Replay through a fresh solver with PARDISO ``settings``: (solutions, seconds in PARDISO's
    call and in total, split by analysed / reused, the count of analyses)."""
    saved = linsolve._Pardiso.settings
    linsolve._Pardiso.settings = settings
    try:
        solver = linsolve.LinearSolver("pardiso")
        solver.solve(*systems[0])  # the handle and MKL's first-call set-up, untimed
        solver = linsolve.LinearSolver("pardiso")
        solver._pardiso = linsolve._Pardiso(solver.threads)
    finally:
        linsolve._Pardiso.settings = saved
    inner = {"t": 0.0}
    call = solver._pardiso.solve

    def timed(*args):
        t0 = time.perf_counter()
        try:
            return call(*args)
        finally:
            inner["t"] = time.perf_counter() - t0

    solver._pardiso.solve = timed
    xs = []
    split = {True: [0.0, 0.0, 0], False: [0.0, 0.0, 0]}  # analysed -> [pardiso s, total s, count]
    for K, b in systems:
        before = solver.analyses
        t0 = time.perf_counter()
        xs.append(solver.solve(K, b))
        total = time.perf_counter() - t0
        row = split[solver.analyses > before]
        row[0] += inner["t"]
        row[1] += total
        row[2] += 1
    return xs, split, solver.analyses


def best_of_two(systems, settings):
    runs = [replay(systems, settings) for _ in range(2)]
    return min(runs, key=lambda r: sum(v[1] for v in r[1].values()))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--design", choices=["one_layer", "default"], default="one_layer")
    p.add_argument("--solves", type=int, default=500)
    args = p.parse_args(argv)
    print_environment(["numpy", "scipy", "pypardiso", "mkl"])
    systems = record(args.design, args.solves)
    n = systems[0][0].shape[0]
    print(f"design {args.design}: {len(systems)} recorded systems of {n} unknowns")

    section("1. Time per solve: PARDISO against the bookkeeping around it [ms]")
    xs, split, analyses = best_of_two(systems, linsolve._Pardiso.settings)
    rows = []
    for analysed, label in ((True, "new analysis (phase 13)"), (False, "analysis reused (phase 23)")):
        t_p, t_all, count = split[analysed]
        if count:
            rows.append([label, str(count), fmt(t_p / count, 1e3), fmt((t_all - t_p) / count, 1e3)])
    print(table(["solves", "count", "PARDISO", "bookkeeping"], rows))

    section("2. PARDISO settings (iparm, 1-based) on the same systems")
    reference = None
    rows = []
    for name, settings in VARIANTS.items():
        xs, split, analyses = best_of_two(systems, settings)
        if reference is None:
            reference = xs
        res = max(np.linalg.norm(K @ x - b) / np.linalg.norm(b) for (K, b), x in zip(systems, xs))
        dev = max(np.linalg.norm(x - y) / np.linalg.norm(y) for x, y in zip(xs, reference))
        a, r = split[True], split[False]
        rows.append([name, str(settings or "-"), str(analyses),
                     fmt(a[0] / max(a[2], 1), 1e3), fmt(r[0] / max(r[2], 1), 1e3), f"{res:.1e}", f"{dev:.1e}"])
    print(table(["settings", "iparm", "analyses", "analysis+solve [ms]", "factor+solve [ms]",
                 "max rel. residual", "dev. from MKL defaults"], rows))


if __name__ == "__main__":
    main()
