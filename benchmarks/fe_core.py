"""Cost of the finite-element core and how it grows with the number of DOFs.

Run:  .venv/bin/python benchmarks/fe_core.py [--quick] [--max-dofs N] [--kernels]

What is measured
----------------
Meshes of growing size: a 2D rectangle 40 x 10 mm of tri6 (plane strain) and a 3D box
20 x 10 x 10 mm of tet10, from about 2e3 DOFs up to the cap (default 1.2e5; ``--quick`` stops
at about 1e4 for a smoke run). The material is the hydrogel at the swelling stimulus
``Hydrogel(HydrogelParams()).at(mu=0, T=275)``, evaluated at a mildly perturbed reference state
``x = X + 1e-3 * U(-1, 1)`` mm (fixed seed), so every quadrature point is admissible. Boundary
conditions are those of a layer bonded to a rigid substrate: bottom face clamped, side faces
held in their normal direction.

Tables 1 and 2 ("FE core", 2D and 3D): the median wall time of 3 calls (1 with ``--quick``, and
1 for a call whose warm-up took over 2 s) after one warm-up call of
  mesh          gmsh meshing of the shape (geometry, generation, order 2, extraction to Mesh)
  solid         Solid construction: shape-function gradients and the CSR sparsity pattern
  energy        one total energy evaluation
  gradient      one gradient assembly
  hessian       one Hessian assembly (element matrices + scatter to CSR), unprojected
  hessian psd   the same with the element-wise PSD projection (eigendecomposition per element)
  extract       the free-DOF submatrix ``H[free][:, free]`` as the Newton solver does it
  pardiso       one linear solve with the default LinearSolver ("auto" = MKL PARDISO)
  scipy         one linear solve with LinearSolver("scipy") (SuperLU; "-" above 3e4 DOFs)
  newton it     one Newton iteration-equivalent: gradient + Hessian + extract + PARDISO
                solve + one energy evaluation (the line search's first trial)
Times in ms. The last two columns are growth exponents p in time ~ DOFs^p: "fit" is the
least-squares slope of log(time) vs log(DOFs) over all meshes, "last" the slope between the two
largest meshes (closer to the asymptotic rate; small meshes are dominated by fixed overheads).
Linear work is p = 1; a sparse direct solve of a 2D problem grows like p ~ 1.5, of a 3D one
like p ~ 2. The "rel. residual" row is ||K u - b|| / ||b|| of the PARDISO solution (a check).

Table 3 ("realistic solve"): free swelling of the bonded layer (Hong, Liu & Suo 2009) on the 2D
meshes up to about 3e4 DOFs: the gel stimulus goes from the as-prepared (mu0, T0) to
(0 kT, 275 K) along s in [0, 1] with the default adaptive load path and Newton options. One run
each (not a median): wall time [s], accepted load steps (+ rejected), Newton iterations, time per
iteration, and the share of the wall time spent in assembly (gradient, Hessian, extraction),
linear solve and line search as recorded in ``PathResult.timings``; "other" is the remainder
(predictor, material construction, bookkeeping). The final thickness stretch is checked against
the material-point (laterally constrained) solution.

Table 0 ("kernels"): the compiled path (numba element loops, the materials' ``evaluate_compiled``;
the default) against the numpy path (``Solid(..., kernels="numpy")``) at two sizes: the default
2D actuator's size (tri6, about 6.7e3 DOFs) and a tet10 box of about 2.5e4 DOFs. Best of
KERNEL_REPEATS calls after a warm-up (the first call's compile time is printed apart), in ms, and
the ratio numpy / compiled. ``--kernels`` runs this table only.

Reading the numbers: the header prints the CPU count, the thread settings and the load average
(again at the end). Multi-threaded kernels (OpenBLAS behind ``np.linalg.eigh`` in the PSD
projection; MKL PARDISO, whose threads ``HYDROJAM_SOLVER_THREADS`` sets) slow down badly when the
cores are shared with other processes; compare a run under ``OPENBLAS_NUM_THREADS=1``.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (  # noqa: E402
    fmt, fmt_slope, growth_exponent, median_time, print_environment, print_load, section, table,
)

from hydrojam.fem import meshing as _gmsh  # noqa: E402
from hydrojam.fem.assembly import Block, Solid  # noqa: E402
from hydrojam.fem.elements import element_for_meshio_type  # noqa: E402
from hydrojam.fem.solver.linsolve import LinearSolver  # noqa: E402
from hydrojam.materials.energies import Hydrogel, HydrogelParams  # noqa: E402
from hydrojam.fem.mesh import Mesh  # noqa: E402
from hydrojam.fem import Dirichlet, PathOptions, Problem, fixed, solve_path  # noqa: E402
from hydrojam.materials.swelling import constrained_swelling  # noqa: E402

PARAMS = HydrogelParams()
GEL = Hydrogel(PARAMS)
MU_TARGET, T_TARGET = 0.0, 275.0  # the swelling stimulus [kT], [K]
SEED = 0
PERTURBATION_MM = 1e-3

# (DOFs aimed at, gmsh element size [mm]); sizes calibrated with gmsh 4.15, the tables print
# the actual DOF counts
SERIES = {
    2: ((2e3, 1.4), (8e3, 0.7), (3e4, 0.36), (1e5, 0.195)),
    3: ((2e3, 3.5), (8e3, 2.0), (3e4, 1.2), (8e4, 0.84)),
}
DEFAULT_MAX_DOFS = 1.2e5
QUICK_MAX_DOFS = 1e4
REPEATS = 3  # timed calls after one warm-up; the median is reported
QUICK_REPEATS = 1
SCIPY_MAX_DOFS = 3e4  # SuperLU (the slow fallback) is skipped above this many DOFs
SOLVE_MAX_DOFS = 3e4  # the realistic solve runs on the 2D meshes aiming up to this
# (label, dim, gmsh element size [mm]) of the kernel comparison: the default actuator's DOF count
# in 2D (~6.7e3) and ~2.5e4 DOFs in 3D
KERNEL_CASES = (("2D tri6", 2, 0.77), ("3D tet10", 3, 1.29))
KERNEL_REPEATS = 5


# --------------------------------------------------------------------------------------------
# Meshes, bodies, boundary conditions


@dataclass(frozen=True)
class Case:
    """One mesh of the series: dimension, the DOF count aimed at and the gmsh element size [mm]."""

    dim: int
    target: float
    size: float

    def label(self) -> str:
        return f"h={self.size:.3g}"

    def mesh(self) -> Mesh:
        if self.dim == 2:
            return _gmsh.rectangle(40.0, 10.0, self.size, order=2)
        return _gmsh.box(20.0, 10.0, 10.0, self.size, order=2)


def cases(dim: int, max_dofs: float) -> list[Case]:
    return [Case(dim, target, size) for target, size in SERIES[dim] if target <= max_dofs]


def make_solid(mesh: Mesh, kernels: str | None = None) -> Solid:
    return Solid(mesh.points, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), GEL, "gel")], kernels=kernels)


def bonded_layer_bcs(mesh: Mesh) -> list[Dirichlet]:
    """Bottom clamped, the side faces held in their normal direction (a layer on a substrate)."""
    g, d = mesh.group_nodes, mesh.dim
    if d == 2:
        return [fixed(g("bottom"), 2), fixed(g("left"), 2, [0]), fixed(g("right"), 2, [0])]
    return [fixed(g("zmin"), 3), fixed(g("xmin"), 3, [0]), fixed(g("xmax"), 3, [0]),
            fixed(g("ymin"), 3, [1]), fixed(g("ymax"), 3, [1])]


def free_dofs(mesh: Mesh) -> np.ndarray:
    return np.flatnonzero(Problem(mesh.points, lambda s: [], bonded_layer_bcs(mesh)).free_mask())


def perturbed_state(mesh: Mesh) -> np.ndarray:
    rng = np.random.default_rng(SEED)
    return mesh.points + PERTURBATION_MM * rng.uniform(-1.0, 1.0, mesh.points.shape)


# --------------------------------------------------------------------------------------------
# FE core timings


CORE_ROWS = [
    ("mesh", "mesh (gmsh)"),
    ("solid", "solid (geometry+pattern)"),
    ("energy", "energy"),
    ("gradient", "gradient"),
    ("hessian", "hessian"),
    ("hessian_psd", "hessian psd (projected)"),
    ("extract", "extract H[free][:, free]"),
    ("pardiso", "solve pardiso (auto)"),
    ("scipy", "solve scipy (SuperLU)"),
    ("newton", "newton it (g+H+ext+solve+E)"),
]


def _extract(H: sp.spmatrix, fidx: np.ndarray) -> sp.csr_matrix:
    return sp.csr_matrix(H)[fidx][:, fidx]


def _newton_iteration(solid: Solid, x: np.ndarray, fidx: np.ndarray, solver: LinearSolver) -> float:
    """The work of one Newton iteration of ``hydrojam.solver.minimize`` (full step accepted)."""
    g = solid.gradient(x)[fidx]
    Hff = _extract(solid.hessian(x), fidx)
    dx = solver.solve(Hff, -g)
    step = np.zeros(x.size)
    step[fidx] = dx
    return solid.energy(x + step.reshape(x.shape))


def _relative_residual(K: sp.spmatrix, u: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(K @ u - b) / np.linalg.norm(b))


def measure_core(case: Case, repeats: int) -> dict:
    """Info (DOFs, cells, nnz) and the median time [s] of every phase for one mesh."""

    def timed(fn):
        return median_time(fn, repeats=repeats)

    t_mesh, mesh = timed(case.mesh)
    t_solid, solid = timed(lambda: make_solid(mesh))
    x = perturbed_state(mesh)
    fidx = free_dofs(mesh)
    assert np.isfinite(solid.energy(x)), "the perturbed state must be admissible"
    t = {"mesh": t_mesh, "solid": t_solid}
    t["energy"], _ = timed(lambda: solid.energy(x))
    t["gradient"], g = timed(lambda: solid.gradient(x))
    t["hessian"], H = timed(lambda: solid.hessian(x))
    t["hessian_psd"], _ = timed(lambda: solid.hessian(x, project=True))
    t["extract"], Hff = timed(lambda: _extract(H, fidx))
    b = -g[fidx]
    pardiso = LinearSolver("auto")
    t["pardiso"], u = timed(lambda: pardiso.solve(Hff, b))
    t["scipy"] = None
    if mesh.points.size <= SCIPY_MAX_DOFS:
        scipy_solver = LinearSolver("scipy")
        t["scipy"], _ = timed(lambda: scipy_solver.solve(Hff, b))
    t["newton"], _ = timed(lambda: _newton_iteration(solid, x, fidx, pardiso))
    info = {
        "dofs": mesh.points.size,
        "free": len(fidx),
        "cells": mesh.n_cells,
        "nnz": H.nnz,
        "residual": _relative_residual(Hff, u, b),
        "method": pardiso.method,
    }
    return {"label": case.label(), "info": info, "t": t}


def _last_slope(dofs, times) -> float | None:
    pts = [(n, t) for n, t in zip(dofs, times) if t is not None]
    return growth_exponent(*zip(*pts[-2:])) if len(pts) >= 2 else None


def print_core_table(title: str, results: list[dict]) -> None:
    section(title)
    dofs = [r["info"]["dofs"] for r in results]
    header = ["", *[r["label"] for r in results], "fit p", "last p"]
    rows = [
        ["DOFs", *[str(r["info"]["dofs"]) for r in results], "", ""],
        ["free DOFs", *[str(r["info"]["free"]) for r in results], "", ""],
        ["cells", *[str(r["info"]["cells"]) for r in results], "", ""],
        ["nnz(H)", *[str(r["info"]["nnz"]) for r in results], "", ""],
    ]
    for key, name in CORE_ROWS:
        times = [r["t"][key] for r in results]
        rows.append([f"{name} [ms]", *[fmt(v, 1e3) for v in times],
                     fmt_slope(growth_exponent(dofs, times)), fmt_slope(_last_slope(dofs, times))])
    rows.append(["rel. residual (pardiso)", *[f"{r['info']['residual']:.1e}" for r in results], "", ""])
    print(table(header, rows))
    if results and results[0]["info"]["method"] != "pardiso":
        print(f"note: PARDISO is not available; 'auto' ran {results[0]['info']['method']}")


def run_core(dim: int, max_dofs: float, repeats: int) -> None:
    name = "2D tri6, plane strain, rectangle 40 x 10 mm" if dim == 2 else "3D tet10, box 20 x 10 x 10 mm"
    results = []
    for case in cases(dim, max_dofs):
        t0 = time.perf_counter()
        results.append(measure_core(case, repeats))
        print(f"  [{dim}D {case.label()}: {results[-1]['info']['dofs']} DOFs measured in "
              f"{time.perf_counter() - t0:.1f} s]", flush=True)
    print_core_table(f"FE core, {name}: median of {repeats} after a warm-up (1 if over 2 s)", results)


# --------------------------------------------------------------------------------------------
# Compiled vs numpy kernels


KERNEL_ROWS = [
    ("energy", lambda S, x: S.energy(x)),
    ("gradient", lambda S, x: S.gradient(x)),
    ("hessian", lambda S, x: S.hessian(x)),
    ("hessian psd (projected)", lambda S, x: S.hessian(x, project=True)),
]


def best_time(fn, repeats: int) -> tuple[float, float]:
    """(first call [s], best of ``repeats`` further calls [s])."""
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return first, min(times)


def run_kernels(repeats: int) -> None:
    gel = GEL.at(MU_TARGET, T_TARGET)
    for label, dim, size in KERNEL_CASES:
        mesh = Case(dim, 0.0, size).mesh()
        x = perturbed_state(mesh)
        solids = {k: make_solid(mesh, k).with_materials({"gel": gel}) for k in ("numpy", "compiled")}
        rows, diffs = [], []
        for name, fn in KERNEL_ROWS:
            (_, tn), (first, tc) = (best_time(lambda: fn(solids[k], x), repeats) for k in ("numpy", "compiled"))
            a, b = fn(solids["numpy"], x), fn(solids["compiled"], x)
            a, b = (v if sp.issparse(v) else np.atleast_1d(v) for v in (a, b))
            diffs.append(f"{name} {abs(a - b).max() / abs(a).max():.1e}")
            rows.append([f"{name} [ms]", fmt(tn, 1e3), fmt(tc, 1e3), f"{tn / tc:.1f}x", fmt(first, 1e3)])
        section(f"Kernels, {label}, {mesh.points.size} DOFs, {mesh.n_cells} cells: best of {repeats}")
        print(table(["", "numpy", "compiled", "numpy/compiled", "compiled 1st call"], rows))
        print("max |numpy - compiled| / max |numpy|: " + ", ".join(diffs))
        print_load("load")


# --------------------------------------------------------------------------------------------
# A realistic solve: free swelling of the bonded layer


def swelling_terms(solid: Solid):
    """terms(s): the gel along the straight stimulus path (mu0, T0) -> (MU_TARGET, T_TARGET)."""

    def terms(s: float):
        mu = PARAMS.mu0 * (1.0 - s) + s * MU_TARGET
        T = PARAMS.T0 + s * (T_TARGET - PARAMS.T0)
        return [solid.with_materials({"gel": GEL.at(mu, T)})]

    return terms


def measure_swelling(case: Case) -> dict:
    mesh = case.mesh()
    solid = make_solid(mesh)
    thickness = float(np.ptp(mesh.points[:, 1]))
    # force scale: the network shear modulus acting over the layer thickness [N/mm]
    problem = Problem(mesh.points, swelling_terms(solid), bonded_layer_bcs(mesh),
                      force_scale=GEL.shear_modulus_ref * thickness)
    t0 = time.perf_counter()
    res = solve_path(problem, PathOptions())
    wall = time.perf_counter() - t0
    top = mesh.group_nodes("top")
    stretch = constrained_swelling(PARAMS, MU_TARGET, T_TARGET, (PARAMS.lambda0, PARAMS.lambda0)).stretch
    error = np.abs(res.x[top, 1] / mesh.points[top, 1] - stretch / PARAMS.lambda0).max()
    return {"label": case.label(), "dofs": mesh.points.size, "wall": wall, "res": res, "error": error}


def print_swelling_table(results: list[dict]) -> None:
    section("Realistic solve: free swelling of the bonded layer, 2D, (mu0, T0) -> (0 kT, 275 K); one run")
    header = ["mesh", "DOFs", "wall [s]", "steps", "rejected", "Newton its", "s/iteration",
              "assembly", "lin. solve", "line search", "other", "converged", "max |err| thickness"]
    rows = []
    for r in results:
        res, wall = r["res"], r["wall"]
        tm = res.timings
        its = tm.iterations
        other = wall - tm.assembly - tm.linear_solve - tm.line_search - tm.step_cap
        rows.append([
            r["label"], str(r["dofs"]), fmt(wall), str(len(res.history)), str(res.rejected_steps), str(its),
            fmt(wall / its if its else None), *[f"{100 * v / wall:.0f}%" for v in
                                                (tm.assembly, tm.linear_solve, tm.line_search, other)],
            "yes" if res.converged else f"no: {res.message}", f"{r['error']:.1e}",
        ])
    dofs = [r["dofs"] for r in results]
    walls = [r["wall"] for r in results]
    per_it = [r["wall"] / max(r["res"].timings.iterations, 1) for r in results]
    rows.append(["growth p (fit)", "", fmt_slope(growth_exponent(dofs, walls)), "", "", "",
                 fmt_slope(growth_exponent(dofs, per_it)), "", "", "", "", "", ""])
    print(table(header, rows))
    print("steps: accepted load steps; Newton its: all iterations run (PathResult.timings.iterations,")
    print("rejected steps included); shares of the wall time from PathResult.timings, 'other' = the rest;")
    print("max |err| thickness: top-face stretch vs the laterally constrained material-point solution.")


def run_swelling(max_dofs: float) -> None:
    results = []
    for case in cases(2, min(max_dofs, SOLVE_MAX_DOFS)):
        results.append(measure_swelling(case))
        print(f"  [swelling {case.label()}: {results[-1]['dofs']} DOFs in {results[-1]['wall']:.1f} s]", flush=True)
    print_swelling_table(results)


# --------------------------------------------------------------------------------------------


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help=f"smoke run: meshes up to ~{QUICK_MAX_DOFS:.0e} DOFs")
    p.add_argument("--max-dofs", type=float, default=None,
                   help=f"skip meshes aiming above this many DOFs (default {DEFAULT_MAX_DOFS:.1e})")
    p.add_argument("--kernels", action="store_true", help="only the compiled vs numpy kernel table")
    args = p.parse_args(argv)
    if args.max_dofs is None:
        args.max_dofs = QUICK_MAX_DOFS if args.quick else DEFAULT_MAX_DOFS
    return args


def main(argv=None) -> None:
    args = parse_args(argv)
    t0 = time.perf_counter()
    print("hydrojam FE core benchmark" + (" (--quick)" if args.quick else ""))
    print_environment(["hydrojam", "numpy", "numba", "scipy", "pypardiso", "mkl", "gmsh"])
    print(f"cap     : meshes aiming at <= {args.max_dofs:.3g} DOFs; material {GEL.at(MU_TARGET, T_TARGET)!r}")
    run_kernels(KERNEL_REPEATS)
    if args.kernels:
        print_load("end load")
        return
    repeats = QUICK_REPEATS if args.quick else REPEATS
    run_core(2, args.max_dofs, repeats)
    run_core(3, args.max_dofs, repeats)
    run_swelling(args.max_dofs)
    print(f"\ntotal benchmark time: {time.perf_counter() - t0:.1f} s")
    print_load("end load")


if __name__ == "__main__":
    main()
