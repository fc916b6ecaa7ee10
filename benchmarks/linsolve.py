"""What the linear solve of a Newton iteration costs: PARDISO's own time against the bookkeeping
around it (the upper triangle, the union pattern), PARDISO's settings, and the reuse of orderings
across changing contact patterns, on the linear systems an actuator simulation really solves.

Run:  .venv/bin/python benchmarks/linsolve.py [--design NAME] [--solves N] [--save DIR | --load DIR]
      [--no-settings]

The problem
-----------
The design (``one_layer``: ``Design(particle_layers=1)``, 2238 DOFs; ``default``:
``default_design()``, 6678 DOFs; ``one_layer_3d``: the one-layer design in 3D at the 4 mm mesh,
8.9k DOFs; ``default_3d``: the default design in 3D at the 4 mm mesh, 24k DOFs) is simulated
with every matrix and right-hand side passed to ``LinearSolver.solve`` recorded, and stopped
after the first ``--solves`` (default 500; about 0.6 MB a system for one layer, 1.8 MB for the 2D
default design, 6 MB and 18-36 MB in 3D). ``--save DIR`` writes them to DIR (one .npz a
system), ``--load DIR`` replays a saved sequence without simulating, streaming one system at a
time from disk (reading is not timed). The sequence is replayed through fresh ``LinearSolver``s:

Table 1 splits the replay's wall time per solve into PARDISO's own call (``_Pardiso.solve``) and
the rest (the upper-triangle gather, the union pattern, MKL's release before a new analysis),
for solves with a new symbolic analysis (phase 13) and for those reusing it (phase 23).

Table 2 replays the sequence under PARDISO settings (iparm, 1-based): MKL's defaults for mtype
-2 (METIS ordering iparm(2) = 3, two refinement steps always iparm(8) = 2) and the variants
(``--no-settings`` leaves it out: in 3D it takes minutes).
"max rel. residual" is max ||K x - b|| / ||b|| over the sequence; "dev. from MKL defaults" is
max ||x - x_default|| / ||x_default||: the settings change round-off, not the mathematics.

Table 3 replays it with each new pattern ordered afresh and with the last ordering reused
(``LinearSolver.reuse_ordering``, iparm(5) = 1), each without and with the contact term's
pattern within reach (``Contact.hessian_pattern``, recorded with every system and handed to
the solve as it was in the simulation; ``LinearSolver.use_reach``), then with PARDISO's Cholesky
where the simulation asked for a definite K, in double and in single precision refined in double
(``LinearSolver.mixed_precision``; "refinement steps" counts the refining substitutions),
interleaved (every variant solves system i before any solves i + 1) and the faster of two passes
kept: analyses, orderings computed, factorisations, the mean factor size and ms per solve. The
kept ordering and the Cholesky are used for dense (3D) patterns only, so on a 2D design the
rows with the reach solve alike, as do those without it.

Reading the numbers: the header prints the load average; other processes on the machine inflate
the times (compare rows of one run, not runs). The solves, analyses, orderings and
factorisations are exact counts.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import fmt, print_environment, print_load, section, table  # noqa: E402
from hydrojam import build_model, default_design, simulate  # noqa: E402
from hydrojam.actuator.design import apply_overrides  # noqa: E402
from hydrojam.fem.solver import linsolve  # noqa: E402

VARIANTS = {
    "MKL defaults": {},
    "min. degree": {2: 0},
    "no forced refinement": {8: 0},
    "min. degree, no forced refinement": {2: 0, 8: 0},
    "min. degree + CNR (hydrojam)": {2: 0, 34: 1},
}


DESIGNS = {
    "one_layer": ["particle_layers=1"],
    "default": [],
    "one_layer_3d": ["dimension=3", "particle_layers=1", "mesh.size=4"],
    "default_3d": ["dimension=3", "mesh.size=4"],
}


class _Enough(Exception):
    """Stops the simulation once the systems wanted are recorded."""


def record(design_name: str, limit: int, save: str | None = None) -> list:
    """The first ``limit`` (K, b) the simulation of the design solves (the simulation stopped
    there); with ``save``, written to that folder instead and returned as their file paths."""
    systems = []
    original = linsolve.LinearSolver.solve
    if save:
        Path(save).mkdir(parents=True, exist_ok=True)

    def solve(self, K, b, reach=None, definite=False):
        if len(systems) >= limit:
            raise _Enough
        K = sp.csr_matrix(K)
        R = None if reach is None else reach()
        R = None if R is None else sp.csr_matrix(R)
        if save:
            path = Path(save) / f"{len(systems):05d}.npz"
            extra = {} if R is None else {"reach_indptr": R.indptr.astype(np.int64), "reach_indices": R.indices.astype(np.int32)}
            np.savez(path, data=K.data, indices=K.indices.astype(np.int32), indptr=K.indptr.astype(np.int64),
                     b=np.asarray(b, dtype=float), shape=np.array(K.shape), definite=np.array(definite), **extra)
            systems.append(path)
        else:
            systems.append((K.copy(), np.array(b, dtype=float), R, definite))
        return original(self, K, b, None if R is None else (lambda: R), definite)

    design = apply_overrides(default_design(), DESIGNS[design_name])
    linsolve.LinearSolver.solve = solve
    try:
        simulate(build_model(design))
    except _Enough:
        pass
    finally:
        linsolve.LinearSolver.solve = original
    return systems


def saved(folder: str) -> list[Path]:
    """The systems saved by ``record(..., save=folder)``, in order."""
    return sorted(Path(folder).glob("*.npz"))


def system(item) -> tuple:
    """(K, b) of a recorded system: in memory, or a saved file read from disk."""
    return recorded(item)[:2]


def recorded(item) -> tuple:
    """(K, b, reach, definite) of a recorded system: reach the contact's pattern within reach
    handed to the solve (``LinearSolver.solve``), None where there was none or it was recorded
    without; definite whether the solve asked for a positive definite K (False where recorded
    without)."""
    if isinstance(item, tuple):
        return item
    with np.load(item) as z:
        n = int(z["shape"][0])
        reach = None
        if "reach_indptr" in z.files:
            ind = z["reach_indices"]
            reach = sp.csr_matrix((np.ones(len(ind)), ind, z["reach_indptr"]), shape=(n, n))
        definite = bool(z["definite"]) if "definite" in z.files else False
        return sp.csr_matrix((z["data"], z["indices"], z["indptr"]), shape=(n, n)), z["b"], reach, definite


def replay(systems, settings: dict[int, int]):
    """Replay through a fresh solver with PARDISO ``settings``: (solutions, seconds in PARDISO's
    call and in total, split by analysed / reused, the count of analyses)."""
    saved = linsolve._Pardiso.settings
    linsolve._Pardiso.settings = settings
    try:
        solver = linsolve.LinearSolver("pardiso")
        solver.solve(*system(systems[0]))  # the handle and MKL's first-call set-up, untimed
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
    for item in systems:
        K, b, R, _ = recorded(item)
        before = solver.analyses
        t0 = time.perf_counter()
        xs.append(solver.solve(K, b, None if R is None else (lambda: R)))
        total = time.perf_counter() - t0
        row = split[solver.analyses > before]
        row[0] += inner["t"]
        row[1] += total
        row[2] += 1
    return xs, split, solver.analyses


def best_of_two(systems, settings):
    runs = [replay(systems, settings) for _ in range(2)]
    return min(runs, key=lambda r: sum(v[1] for v in r[1].values()))


ORDERINGS = {
    "each pattern ordered afresh, no reach": {"reuse_ordering": False, "use_reach": False, "use_cholesky": False},
    "last ordering reused, no reach": {"use_reach": False, "use_cholesky": False},
    "last ordering reused, the reach": {"use_cholesky": False},
    "the same, Cholesky in double where a definite K is asked": {"mixed_precision": False},
    "the same, Cholesky in single, refined in double (hydrojam)": {},
}


def orderings(systems, passes: int = 2) -> list[list[str]]:
    """Table 3's rows: each variant of ``ORDERINGS`` replayed interleaved with the others, the
    faster of ``passes`` passes kept per variant."""
    best = {}
    for _ in range(passes):
        solvers = {}
        for name, attrs in ORDERINGS.items():
            solver = linsolve.LinearSolver("pardiso")
            for key, value in attrs.items():
                setattr(solver, key, value)
            solvers[name] = solver
        seconds = dict.fromkeys(solvers, 0.0)
        fill = {name: [] for name in solvers}
        residual = dict.fromkeys(solvers, 0.0)
        refused = dict.fromkeys(solvers, 0)
        for item in systems:
            K, b, R, definite = recorded(item)
            reach = None if R is None else (lambda: R)
            for name, solver in solvers.items():
                before = solver.analyses
                t0 = time.perf_counter()
                try:
                    x = solver.solve(K, b, reach, definite)
                except linsolve.NotPositiveDefinite:
                    x = None
                    refused[name] += 1
                seconds[name] += time.perf_counter() - t0
                if solver.analyses > before and x is not None:
                    fill[name].append(solver._pardiso.factor_entries())
                if x is not None:
                    residual[name] = max(residual[name], np.linalg.norm(K @ x - b) / np.linalg.norm(b))
        for name, solver in solvers.items():
            row = [name, str(solver.calls), str(solver.analyses), str(solver.reorderings),
                   str(solver.calls), str(refused[name]), str(solver.refinements),
                   fmt(np.mean(fill[name]) if fill[name] else None, 1e-6),
                   fmt(seconds[name] / solver.calls, 1e3), f"{residual[name]:.1e}"]
            if name not in best or seconds[name] < best[name][0]:
                best[name] = (seconds[name], row)
    return [row for _, row in best.values()]


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--design", choices=list(DESIGNS), default="one_layer")
    p.add_argument("--solves", type=int, default=500)
    p.add_argument("--save", help="record to this folder (one .npz a system)")
    p.add_argument("--load", help="replay the systems saved in this folder instead of simulating")
    p.add_argument("--no-settings", action="store_true", help="leave out table 2 (PARDISO's settings)")
    args = p.parse_args(argv)
    print_environment(["numpy", "scipy", "pypardiso", "mkl"])
    if args.load:
        systems = saved(args.load)[: args.solves]
        source = args.load
    else:
        systems = record(args.design, args.solves, args.save)
        source = f"design {args.design}"
    n = system(systems[0])[0].shape[0]
    print(f"{source}: {len(systems)} recorded systems of {n} unknowns")

    section("1. Time per solve: PARDISO against the bookkeeping around it [ms]")
    xs, split, analyses = best_of_two(systems, linsolve._Pardiso.settings)
    rows = []
    for analysed, label in ((True, "new analysis (phase 13)"), (False, "analysis reused (phase 23)")):
        t_p, t_all, count = split[analysed]
        if count:
            rows.append([label, str(count), fmt(t_p / count, 1e3), fmt((t_all - t_p) / count, 1e3)])
    print(table(["solves", "count", "PARDISO", "bookkeeping"], rows))
    print_load()

    if not args.no_settings:
        section("2. PARDISO settings (iparm, 1-based) on the same systems")
        reference = None
        rows = []
        for name, settings in VARIANTS.items():
            xs, split, analyses = best_of_two(systems, settings)
            if reference is None:
                reference = xs
            res = max(np.linalg.norm(K @ x - b) / np.linalg.norm(b) for (K, b), x in zip(map(system, systems), xs))
            dev = max(np.linalg.norm(x - y) / np.linalg.norm(y) for x, y in zip(xs, reference))
            a, r = split[True], split[False]
            rows.append([name, str(settings or "-"), str(analyses),
                         fmt(a[0] / max(a[2], 1), 1e3), fmt(r[0] / max(r[2], 1), 1e3), f"{res:.1e}", f"{dev:.1e}"])
        print(table(["settings", "iparm", "analyses", "analysis+solve [ms]", "factor+solve [ms]",
                     "max rel. residual", "dev. from MKL defaults"], rows))
        print_load()

    section("3. Orderings of changing patterns (interleaved, the faster of two passes)")
    print(table(["variant", "solves", "analyses", "orderings", "factorisations", "not definite (Cholesky)",
                 "refinement steps", "mean factor [M entries]",
                 "ms per solve", "max rel. residual"], orderings(systems)))
    print_load()


if __name__ == "__main__":
    main()
