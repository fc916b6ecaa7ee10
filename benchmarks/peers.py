"""hydrojam beside its peers: the same hyperelastic problem in FElupe and CalculiX.

Run:  .venv/bin/pip install -e ".[bench]"      # FElupe 11.3.0, only for this benchmark
      .venv/bin/python benchmarks/peers.py [--quick] [--repeats N] [--no-ccx]

The problem
-----------
A compressible neo-Hookean block (hydrojam's ``NeoHookean``, Ecoflex defaults: G = 0.023 MPa,
Poisson's ratio 0.45; W = G/2 (I1bar - 3) + K/2 (J - 1)^2) stretched in one load step: the face
x = 0 clamped, the face x = L moved by (STRETCH - 1) L in x and held in the other directions.
Meshes from ``hydrojam.fem.meshing``: a 40 x 10 mm rectangle of tri6 in plane strain (~6.6k
DOFs) and a 20 x 10 x 10 mm box of tet10 (~25k DOFs); both codes get the same nodes, cells and
quadrature (3 points per triangle, 4 per tetrahedron: FElupe gets hydrojam's points as a
``quadrature.Scheme``, since its own 4-point tetrahedron rule has 8-digit constants, 0.13819660,
which alone makes the two tangents differ by 1e-8).

FElupe ``NeoHooke(mu=G, bulk=K)`` has the same strain energy; the script checks it (W, P and A
at random F, plane strain included) and that both codes assemble the same tangent matrix at a
perturbed state before timing anything. FElupe 11.3.0's ``QuadraticTriangle.gradient`` has a
wrong derivative (d h5 / d s is 4 (t1 - r), it must be 4 (t1 - s), t1 = 1 - r - s): the script
patches it, checks the patch against finite differences of the shape functions, and without the
patch the two tangents differ.

What is timed (best of ``--repeats`` after a warm-up, at the perturbed state)
----------------------------------------------------------------------------
  residual   the internal-force vector: hydrojam ``Solid.gradient``; FElupe
             ``SolidBody.assemble.vector`` (stress evaluation + assembly)
  tangent    the stiffness matrix: hydrojam ``Solid.hessian`` (unprojected); FElupe
             ``SolidBody.assemble.matrix`` (elasticity tensor + assembly)
  solve      partition K into the free block + one PARDISO solve, each code as it runs in its
             Newton loop: hydrojam ``K[free][:, free]`` and ``fem.solver.linsolve.LinearSolver`` (real
             symmetric indefinite, upper triangle, the analysis reused while the pattern stays);
             FElupe ``fem.solve.partition`` + ``fem.solve.solve(solver=pypardiso.spsolve)`` (the
             general LU, analysis every call: the stored factorisation is dropped before each
             call, as a new Newton matrix would). "solve, fresh analysis" is hydrojam's solve
             with the analysis redone every call (``HYDROJAM_REUSE_ANALYSIS=0``).
Both use MKL PARDISO through pypardiso with the same MKL thread count (hydrojam's
``HYDROJAM_SOLVER_THREADS``, default 1; the script sets the same for FElupe's calls).

The Newton solve
----------------
FElupe: ``fem.newtonraphson(items=[solid], dof1, dof0, ext0, solver=pypardiso.spsolve, tol)``.
hydrojam: the same algorithm on hydrojam's operators in this script (full Newton steps, the
prescribed move entering the first solve through K10, FElupe's convergence test
sum ||r_free|| / (1e-3 + sum ||r_prescribed||) < TOL), so both take the same steps to the same
tolerance; hydrojam's own ``minimize`` (line search, damping) is not what is compared here. The
displacements must agree within a bound derived from the tolerance: 10 x the sum of the two
solutions' distances to the exact discrete solution (each estimated by one more Newton
correction from the residual it converged with) plus round-off. "per iteration" is the Newton
wall time over the iterations (residual + tangent + partition + solve + update + convergence
test), the fastest of ``--repeats // 2`` solves after a warm-up solve; also in CPU time
(``time.process_time``, all threads of the process), which another process disturbs less.

CalculiX (3D only, if ``ccx`` is on the PATH; Debian package ``calculix-ccx``): the same mesh as
C3D10 (4 integration points, node order as meshio's), ``*HYPERELASTIC, NEO HOOKE`` with
C10 = G/2 and D1 = 2/K (the same W), ``*STATIC, DIRECT`` NLGEOM, the same boundary conditions.
Its time per Newton iteration comes from two runs, the move in one increment and in
CCX_INCREMENTS: the difference of the wall times over the difference of the iteration counts,
which removes the input, set-up and output. Its linear solver is the one the Debian build uses
(SPOOLES), not PARDISO; its threads are set to the same count. Its tolerance cannot be made the
same: it declares convergence after 3 iterations (hydrojam and FElupe take 4) whatever
``*CONTROLS, PARAMETERS=FIELD`` asks (R_n from 5e-3 down to 1e-14, C_n down to 1e-12 were
tried), so its displacements differ from theirs by about the size of their fourth Newton
correction (printed). The 2D problem is not run in CalculiX: it expands CPE6 plane-strain
elements into 3D quadratic wedges (C3D15) with another integration rule, so the discrete problem
would not be the same.

Reading the numbers: the machine may be shared; the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import fmt, print_environment, print_load, section, table  # noqa: E402

from hydrojam.fem import meshing as _gmsh  # noqa: E402
from hydrojam.fem.assembly import Block, Solid  # noqa: E402
from hydrojam.fem.elements import element_for_meshio_type  # noqa: E402
from hydrojam.fem.solver.linsolve import LinearSolver  # noqa: E402
from hydrojam.fem.mesh import Mesh  # noqa: E402
from hydrojam.materials.energies import NeoHookean  # noqa: E402

try:
    import felupe as fem
    import pypardiso
except ImportError as exc:  # pragma: no cover - the optional extra is missing
    sys.exit(f"peers.py needs FElupe: pip install -e '.[bench]' ({exc})")

MATERIAL = NeoHookean()  # Ecoflex 00-30: G = 0.023 MPa, nu = 0.45
STRETCH = 1.2  # prescribed stretch of the block along x [-]
CCX_INCREMENTS = 4  # the second CalculiX run: the move in this many increments
TOL = 1e-8  # FElupe's default: residual of the free DOFs over the reaction forces [-]
REPEATS = 5
SEED = 0
PERTURBATION_MM = 1e-2

# (dim, gmsh element size [mm]): ~6.6k and ~25k DOFs with gmsh 4.15 (the tables print the counts)
CASES = {2: 0.77, 3: 1.25}
QUICK_CASES = {2: 1.6, 3: 3.0}


# --------------------------------------------------------------------------------------------
# FElupe 11.3.0's quadratic triangle, patched


def _quadratic_triangle_gradient(self, rs):
    """d h / d(r, s) (6, 2) of FElupe's QuadraticTriangle, with d h5 / d s = 4 (t1 - s)."""
    r, s = rs
    t1 = 1 - r - s
    dhdr_a = np.array([[-1, -1], [1, 0], [0, 1]], dtype=float)
    dhdr_b = np.array([[4 * (t1 - r), -4 * r], [4 * s, 4 * r], [-4 * s, 4 * (t1 - s)]])
    dhdr = np.vstack((dhdr_a, dhdr_b))
    dhdr[0] += -dhdr[3] / 2 - dhdr[5] / 2
    dhdr[1] += -dhdr[3] / 2 - dhdr[4] / 2
    dhdr[2] += -dhdr[4] / 2 - dhdr[5] / 2
    return dhdr


def _shape_gradient_error(element) -> float:
    """Largest |gradient - central difference of the shape functions| at a few points."""
    err, h = 0.0, 1e-6
    for rs in np.random.default_rng(SEED).uniform(0.05, 0.45, (5, 2)):
        fd = np.stack([(element.function(rs + h * e) - element.function(rs - h * e)) / (2 * h)
                       for e in np.eye(2)], axis=1)
        err = max(err, float(np.abs(element.gradient(rs) - fd).max()))
    return err


def patch_felupe() -> tuple[float, float]:
    """Replace QuadraticTriangle.gradient; the finite-difference error before and after."""
    before = _shape_gradient_error(fem.QuadraticTriangle())
    fem.QuadraticTriangle.gradient = _quadratic_triangle_gradient
    after = _shape_gradient_error(fem.QuadraticTriangle())
    if after > 1e-6:
        raise RuntimeError(f"patched QuadraticTriangle gradient is still wrong ({after:.1e})")
    return before, after


# --------------------------------------------------------------------------------------------
# The same material


def felupe_material():
    return fem.NeoHooke(mu=MATERIAL.shear_modulus, bulk=MATERIAL.bulk_modulus)


def material_difference() -> dict[str, float]:
    """Relative differences of W, P and A between hydrojam and FElupe at random F, for 3D and
    plane strain (FElupe's F there is diag(F, 1), hydrojam's the 2x2 block)."""
    rng = np.random.default_rng(SEED)
    F3 = np.eye(3) + 0.3 * rng.uniform(-1, 1, (20, 3, 3))
    F2 = np.repeat(np.eye(3)[None], 20, axis=0)
    F2[:, :2, :2] += 0.3 * rng.uniform(-1, 1, (20, 2, 2))
    umat = felupe_material()
    out = {}
    for name, F, d in (("3D", F3, 3), ("plane strain", F2, 2)):
        Ff = np.moveaxis(F, 0, -1)[..., None]  # (3, 3, n, 1): FElupe's layout
        Wf = umat.function([Ff, None])[0][:, 0]
        Pf = np.moveaxis(umat.gradient([Ff, None])[0][..., 0], -1, 0)[:, :d, :d]
        Af = np.moveaxis(umat.hessian([Ff, None])[0][..., 0], -1, 0)[:, :d, :d, :d, :d]
        r = MATERIAL.evaluate(F[:, :d, :d])
        out[name] = max(float(np.abs(r.energy - Wf).max() / np.abs(Wf).max()),
                        float(np.abs(r.stress - Pf).max() / np.abs(Pf).max()),
                        float(np.abs(r.tangent - Af).max() / np.abs(Af).max()))
    return out


# --------------------------------------------------------------------------------------------
# The problem in both codes


@dataclass
class Setup:
    mesh: Mesh
    solid: Solid
    fsolid: object  # felupe SolidBody
    field: object  # felupe FieldContainer
    dof0: np.ndarray  # prescribed DOFs (node * d + component)
    dof1: np.ndarray  # free DOFs
    ext0: np.ndarray  # prescribed displacements [mm] of dof0

    @property
    def dim(self) -> int:
        return self.mesh.dim


def make_mesh(dim: int, size: float) -> Mesh:
    if dim == 2:
        return _gmsh.rectangle(40.0, 10.0, size, order=2)
    return _gmsh.box(20.0, 10.0, 10.0, size, order=2)


def setup(dim: int, size: float) -> Setup:
    mesh = make_mesh(dim, size)
    solid = Solid(mesh.points, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), MATERIAL, "block")])
    fmesh = fem.Mesh(mesh.points.copy(), mesh.cells.copy(), mesh.cell_type)
    element = solid.blocks[0].element
    scheme = fem.quadrature.Scheme(np.array(element.quad_points), np.array(element.quad_weights))
    if dim == 2:
        region = fem.RegionQuadraticTriangle(fmesh, quadrature=scheme)
        field = fem.FieldContainer([fem.FieldPlaneStrain(region, dim=2)])
    else:
        region = fem.RegionQuadraticTetra(fmesh, quadrature=scheme)
        field = fem.FieldContainer([fem.Field(region, dim=3)])
    fsolid = fem.SolidBody(felupe_material(), field)
    x = mesh.points[:, 0]
    length = float(np.ptp(x))
    left = np.flatnonzero(np.isclose(x, x.min()))
    right = np.flatnonzero(np.isclose(x, x.max()))
    dof_left = (left[:, None] * dim + np.arange(dim)).ravel()
    dof_right = (right[:, None] * dim + np.arange(dim)).ravel()
    move = np.zeros((len(right), dim))
    move[:, 0] = (STRETCH - 1.0) * length
    dof0 = np.concatenate([dof_left, dof_right])
    order = np.argsort(dof0)
    dof0 = dof0[order]
    ext0 = np.concatenate([np.zeros(len(dof_left)), move.ravel()])[order]
    dof1 = np.setdiff1d(np.arange(mesh.points.size), dof0)
    return Setup(mesh, solid, fsolid, field, dof0, dof1, ext0)


def perturbed_displacement(s: Setup) -> np.ndarray:
    rng = np.random.default_rng(SEED)
    return PERTURBATION_MM * rng.uniform(-1.0, 1.0, s.mesh.points.shape)


def set_felupe(s: Setup, u: np.ndarray) -> None:
    s.field[0].values[:] = u


def tangent_difference(s: Setup, u: np.ndarray) -> tuple[float, float]:
    """max|K_hydrojam - K_felupe| / max|K| and the same for the residuals, at displacement u."""
    set_felupe(s, u)
    Kf = sp.csr_matrix(s.fsolid.assemble.matrix(s.field))
    rf = np.asarray(s.fsolid.assemble.vector(s.field).todense()).ravel()
    x = s.mesh.points + u
    Kh = s.solid.hessian(x)
    rh = s.solid.gradient(x)
    dK = abs(Kh - Kf).max() / abs(Kh).max()
    return float(dK), float(np.abs(rh - rf).max() / np.abs(rh).max())


# --------------------------------------------------------------------------------------------
# Timings


def best_time(fn, repeats: int, before=None) -> tuple[float, object]:
    """Least wall time [s] of ``repeats`` calls after one warm-up, and the last result;
    ``before()`` runs untimed ahead of every call."""
    result, times = None, []
    for k in range(repeats + 1):
        if before is not None:
            before()
        t0 = time.perf_counter()
        result = fn()
        if k:
            times.append(time.perf_counter() - t0)
    return min(times), result


def set_mkl_threads(n: int) -> None:
    setter = getattr(pypardiso.scipy_aliases.pypardiso_solver.libmkl, "MKL_Set_Num_Threads", None)
    if setter is not None:
        setter(ctypes.c_int(n))


def _hydrojam_solver(reuse: bool) -> LinearSolver:
    old = os.environ.get("HYDROJAM_REUSE_ANALYSIS")
    os.environ["HYDROJAM_REUSE_ANALYSIS"] = "1" if reuse else "0"
    try:
        return LinearSolver("pardiso")
    finally:
        if old is None:
            del os.environ["HYDROJAM_REUSE_ANALYSIS"]
        else:
            os.environ["HYDROJAM_REUSE_ANALYSIS"] = old


def time_components(s: Setup, u: np.ndarray, repeats: int) -> dict[str, float]:
    """Best wall time [s] of residual, tangent and solve in both codes at displacement u."""
    t = {}
    x = s.mesh.points + u
    t["h_residual"], g = best_time(lambda: s.solid.gradient(x), repeats)
    t["h_tangent"], K = best_time(lambda: s.solid.hessian(x), repeats)
    b = -g[s.dof1]
    solver = _hydrojam_solver(reuse=True)
    t["h_solve"], _ = best_time(lambda: solver.solve(sp.csr_matrix(K)[s.dof1][:, s.dof1], b), repeats)
    fresh = _hydrojam_solver(reuse=False)
    t["h_solve_fresh"], _ = best_time(lambda: fresh.solve(sp.csr_matrix(K)[s.dof1][:, s.dof1], b), repeats)
    set_mkl_threads(solver.threads)

    set_felupe(s, u)
    t["f_residual"], r = best_time(lambda: s.fsolid.assemble.vector(s.field), repeats)
    t["f_tangent"], Kf = best_time(lambda: s.fsolid.assemble.matrix(s.field), repeats)
    r = np.asarray(r.todense()).ravel()
    ext0 = s.ext0

    def felupe_solve():
        system = fem.solve.partition(s.field, Kf, s.dof1, s.dof0, -r)
        return fem.solve.solve(*system, ext0, solver=pypardiso.spsolve)

    t["f_solve"], _ = best_time(felupe_solve, repeats,
                                before=pypardiso.scipy_aliases.pypardiso_solver.remove_stored_factorization)
    return t


# --------------------------------------------------------------------------------------------
# Newton solves


def felupe_newton(s: Setup) -> dict:
    s.field[0].values[:] = 0.0
    c0 = time.process_time()
    t0 = time.perf_counter()
    res = fem.newtonraphson(items=[s.fsolid], x0=s.field, dof1=s.dof1, dof0=s.dof0, ext0=s.ext0,
                            solver=pypardiso.spsolve, tol=TOL, verbose=0)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    u = res.x[0].values.copy()
    return {"wall": wall, "cpu": cpu, "iterations": res.iterations, "u": u}


def hydrojam_newton(s: Setup, solver: LinearSolver, maxiter: int = 16) -> dict:
    """FElupe's Newton-Raphson on hydrojam's operators: the same steps, the same test."""
    X = s.mesh.points.ravel()
    u = np.zeros(X.size)
    free, fixed = s.dof1, s.dof0
    corrections = []
    c0 = time.process_time()
    t0 = time.perf_counter()
    f = s.solid.gradient((X + u).reshape(s.mesh.points.shape))
    for it in range(maxiter):
        K = sp.csr_matrix(s.solid.hessian((X + u).reshape(s.mesh.points.shape)))
        K1 = K[free]
        du = np.empty_like(u)
        du[fixed] = s.ext0 - u[fixed]
        du[free] = solver.solve(K1[:, free], -f[free] - K1[:, fixed] @ du[fixed])
        u = u + du
        corrections.append(np.abs(du[free]).max())
        f = s.solid.gradient((X + u).reshape(s.mesh.points.shape))
        fnorm = np.linalg.norm(f[free]) / (1e-3 + np.linalg.norm(f[fixed]))
        if fnorm < TOL:
            break
    else:
        raise RuntimeError(f"hydrojam Newton: no convergence in {maxiter} iterations")
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    return {"wall": wall, "cpu": cpu, "iterations": it + 1, "u": u.reshape(s.mesh.points.shape), "corrections": corrections}


def newton_error(s: Setup, u: np.ndarray) -> float:
    """max |u* - u| [mm] estimated by one more Newton correction at u (hydrojam's operators):
    the distance to the exact discrete solution that the remaining residual leaves."""
    x = s.mesh.points + u
    K = sp.csr_matrix(s.solid.hessian(x))[s.dof1][:, s.dof1]
    r = s.solid.gradient(x)[s.dof1]
    return float(np.abs(LinearSolver("pardiso").solve(K, -r)).max())


def best_newton(fn, repeats: int) -> dict:
    """The fastest of ``repeats`` Newton solves after an untimed warm-up solve."""
    runs = [fn() for _ in range(repeats + 1)][1:]
    best = min(runs, key=lambda r: r["wall"])
    if len({r["iterations"] for r in runs}) != 1:
        raise RuntimeError("Newton iteration counts differ between repeats")
    return best


# --------------------------------------------------------------------------------------------
# CalculiX


def _ccx_input(s: Setup, increments: int) -> str:
    """The 3D problem as a CalculiX deck: C3D10 (node order as meshio's tetra10: corners, then
    the edge nodes (1,2), (2,3), (3,1), (1,4), (2,4), (3,4)), the move in ``increments`` fixed
    increments, displacements written once at the end."""
    pts, cells = s.mesh.points, s.mesh.cells
    G, K = MATERIAL.shear_modulus, MATERIAL.bulk_modulus
    lines = ["*NODE, NSET=NALL"]
    lines += [f"{i + 1}, {p[0]:.17g}, {p[1]:.17g}, {p[2]:.17g}" for i, p in enumerate(pts)]
    lines.append("*ELEMENT, TYPE=C3D10, ELSET=EALL")
    for e, c in enumerate(cells + 1):
        lines.append(f"{e + 1}, " + ", ".join(map(str, c[:8])) + ",")
        lines.append(", ".join(map(str, c[8:])))
    lines += ["*MATERIAL, NAME=NH", "*HYPERELASTIC, NEO HOOKE", f"{G / 2:.17g}, {2.0 / K:.17g}",
              "*SOLID SECTION, ELSET=EALL, MATERIAL=NH",
              f"*STEP, NLGEOM, INC={increments + 10}", "*STATIC, DIRECT", f"{1.0 / increments:.17g}, 1.",
              "*BOUNDARY"]
    lines += [f"{d // 3 + 1}, {d % 3 + 1}, {d % 3 + 1}, {v:.17g}" for d, v in zip(s.dof0, s.ext0)]
    lines += [f"*NODE PRINT, NSET=NALL, FREQUENCY={increments}", "U", "*END STEP", ""]
    return "\n".join(lines)


def _read_dat_displacements(path: Path, n: int) -> np.ndarray:
    """The last displacement table of a CalculiX .dat file, (n, 3) [mm]."""
    u = np.full((n, 3), np.nan)
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) == 4 and parts[0].isdigit():
                u[int(parts[0]) - 1] = [float(v) for v in parts[1:]]
    return u


def run_ccx(s: Setup, increments: int, workdir: Path, threads: int) -> dict:
    name = f"peers_{increments}"
    (workdir / f"{name}.inp").write_text(_ccx_input(s, increments))
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), CCX_NPROC_STIFFNESS=str(threads),
               CCX_NPROC_EQUATION_SOLVER=str(threads), NUMBER_OF_CPUS=str(threads))
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(["ccx", name], cwd=workdir, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    if out.returncode != 0 or "Job finished" not in out.stdout:
        raise RuntimeError(f"ccx failed:\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}")
    iterations = len(re.findall(r"^\s*iteration \d+", out.stdout, flags=re.M))
    solver = re.search(r"Factoring the system of equations using the (.*?) solver", out.stdout)
    u = _read_dat_displacements(workdir / f"{name}.dat", len(s.mesh.points))
    return {"wall": wall, "cpu": cpu, "iterations": iterations, "u": u, "increments": increments,
            "solver": solver.group(1) if solver else "?"}


def ccx_figures(s: Setup, repeats: int, threads: int) -> dict:
    """Time per Newton iteration from a run in one increment and one in CCX_INCREMENTS (best of
    ``repeats`` each): the difference of the times over the difference of the iterations, from the
    wall time and from ccx's CPU time (user + sys; the same on an idle machine for one thread,
    less disturbed by other processes on a busy one)."""
    with tempfile.TemporaryDirectory(prefix="hydrojam_ccx_") as tmp:
        workdir = Path(tmp)
        runs = [min((run_ccx(s, n, workdir, threads) for _ in range(max(1, repeats))), key=lambda r: r["wall"])
                for n in (1, CCX_INCREMENTS)]
    one, many = runs
    dn = many["iterations"] - one["iterations"]
    per_it = (many["wall"] - one["wall"]) / dn if dn > 0 else None
    per_it_cpu = (many["cpu"] - one["cpu"]) / dn if dn > 0 else None
    return {"one": one, "many": many, "per_iteration": per_it, "per_iteration_cpu": per_it_cpu}


# --------------------------------------------------------------------------------------------


def run_case(dim: int, size: float, repeats: int, do_ccx: bool) -> dict:
    s = setup(dim, size)
    label = f"{dim}D {'tri6 plane strain' if dim == 2 else 'tet10'}"
    up = perturbed_displacement(s)
    dK, dr = tangent_difference(s, up)
    t = time_components(s, up, repeats)
    solver = _hydrojam_solver(reuse=True)
    set_mkl_threads(solver.threads)
    hn = best_newton(lambda: hydrojam_newton(s, solver), max(1, repeats // 2))
    fn = best_newton(lambda: felupe_newton(s), max(1, repeats // 2))
    du = float(np.abs(hn["u"] - fn["u"]).max())
    bound = 10.0 * (newton_error(s, hn["u"]) + newton_error(s, fn["u"])) + 1e-12 * float(np.abs(hn["u"]).max())
    out = {"label": label, "s": s, "dofs": s.mesh.points.size, "free": len(s.dof1), "cells": s.mesh.n_cells,
           "dK": dK, "dr": dr, "t": t, "hn": hn, "fn": fn, "du": du, "bound": bound, "ccx": None}
    if do_ccx and dim == 3:
        out["ccx"] = ccx_figures(s, max(1, repeats // 2), solver.threads)
    return out


def print_case(r: dict) -> None:
    t, hn, fn = r["t"], r["hn"], r["fn"]
    section(f"{r['label']}: {r['dofs']} DOFs ({r['free']} free), {r['cells']} cells")
    print(f"same problem: max|K_hj - K_fe| / max|K| = {r['dK']:.1e}, residuals {r['dr']:.1e} "
          f"(perturbed state, {PERTURBATION_MM} mm)")
    h_ts, f_ts = t["h_tangent"] + t["h_solve"], t["f_tangent"] + t["f_solve"]
    h_it, f_it = hn["wall"] / hn["iterations"], fn["wall"] / fn["iterations"]
    rows = [
        ["residual", fmt(t["h_residual"], 1e3), fmt(t["f_residual"], 1e3), f"{t['h_residual'] / t['f_residual']:.2f}"],
        ["tangent", fmt(t["h_tangent"], 1e3), fmt(t["f_tangent"], 1e3), f"{t['h_tangent'] / t['f_tangent']:.2f}"],
        ["solve (partition + PARDISO)", fmt(t["h_solve"], 1e3), fmt(t["f_solve"], 1e3),
         f"{t['h_solve'] / t['f_solve']:.2f}"],
        ["solve, fresh analysis", fmt(t["h_solve_fresh"], 1e3), fmt(t["f_solve"], 1e3),
         f"{t['h_solve_fresh'] / t['f_solve']:.2f}"],
        ["tangent + solve", fmt(h_ts, 1e3), fmt(f_ts, 1e3), f"{h_ts / f_ts:.2f}"],
        ["Newton iterations", str(hn["iterations"]), str(fn["iterations"]), ""],
        ["per Newton iteration", fmt(h_it, 1e3), fmt(f_it, 1e3), f"{h_it / f_it:.2f}"],
        ["per Newton iteration (CPU time)", fmt(hn["cpu"] / hn["iterations"], 1e3),
         fmt(fn["cpu"] / fn["iterations"], 1e3), f"{(hn['cpu'] / hn['iterations']) / (fn['cpu'] / fn['iterations']):.2f}"],
        ["Newton solve (wall)", fmt(hn["wall"], 1e3), fmt(fn["wall"], 1e3), f"{hn['wall'] / fn['wall']:.2f}"],
    ]
    print(table(["[ms]", "hydrojam", "FElupe", "hydrojam/FElupe"], rows))
    print("hydrojam's Newton corrections max|du_free| [mm]: " + ", ".join(f"{c:.1e}" for c in hn["corrections"]))
    print(f"solution: max|u_hj - u_fe| = {r['du']:.1e} mm (bound from the tolerance {r['bound']:.1e} mm); "
          f"max|u| = {np.abs(r['hn']['u']).max():.3g} mm")
    if r["du"] > r["bound"]:
        print("WARNING: the two solutions differ by more than the tolerance allows")
    if r["ccx"] is not None:
        c = r["ccx"]
        uc = c["one"]["u"]
        duc = float(np.nanmax(np.abs(uc - r["hn"]["u"])))
        print(f"CalculiX ({c['one']['solver']} solver): {c['one']['iterations']} iterations in one increment, "
              f"{c['one']['wall']:.2f} s; {c['many']['iterations']} in {c['many']['increments']} increments, "
              f"{c['many']['wall']:.2f} s -> {fmt(c['per_iteration'], 1e3)} ms per iteration (CPU time: "
              f"{c['one']['cpu']:.2f} s, {c['many']['cpu']:.2f} s -> {fmt(c['per_iteration_cpu'], 1e3)} ms); "
              f"max|u_ccx - u_hj| = {duc:.1e} mm (one increment; its .dat prints 7 digits)")
        if c["per_iteration"]:
            h_cpu = hn["cpu"] / hn["iterations"]
            print(f"hydrojam / CalculiX per Newton iteration: {h_it / c['per_iteration']:.2f} (wall), "
                  f"{h_cpu / c['per_iteration_cpu']:.2f} (CPU time)")


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="smoke run on coarse meshes")
    p.add_argument("--repeats", type=int, default=REPEATS, help=f"timed repeats (default {REPEATS})")
    p.add_argument("--no-ccx", action="store_true", help="skip CalculiX")
    p.add_argument("--dims", type=int, nargs="+", default=[2, 3], choices=[2, 3])
    return p.parse_args(argv)


def main(argv=None) -> None:
    args = parse_args(argv)
    t0 = time.perf_counter()
    print("hydrojam beside FElupe and CalculiX" + (" (--quick)" if args.quick else ""))
    print_environment(["hydrojam", "felupe", "numpy", "scipy", "pypardiso", "mkl", "gmsh"])
    do_ccx = not args.no_ccx and shutil.which("ccx") is not None
    print(f"ccx     : {shutil.which('ccx') or 'not found'}" + ("" if do_ccx else " (skipped)"))
    print(f"problem : {MATERIAL!r} (K = {MATERIAL.bulk_modulus:.4g} MPa), stretch {STRETCH} in one step, "
          f"tolerance {TOL:g}")
    before, after = patch_felupe()
    print(f"felupe  : QuadraticTriangle.gradient patched (d h5/ds); max error against finite differences "
          f"{before:.1e} before, {after:.1e} after")
    dm = material_difference()
    print("material: hydrojam NeoHookean vs felupe NeoHooke, max relative difference of W, P, A at 20 random F: "
          + ", ".join(f"{k} {v:.1e}" for k, v in dm.items()))
    cases = QUICK_CASES if args.quick else CASES
    results = []
    for dim in args.dims:
        results.append(run_case(dim, cases[dim], args.repeats, do_ccx))
        print_case(results[-1])
        print_load()
    section("Summary: hydrojam / peer, time per tangent + solve and per Newton iteration")
    rows = []
    for r in results:
        t = r["t"]
        ts = (t["h_tangent"] + t["h_solve"]) / (t["f_tangent"] + t["f_solve"])
        it = (r["hn"]["wall"] / r["hn"]["iterations"]) / (r["fn"]["wall"] / r["fn"]["iterations"])
        c = r["ccx"]
        cc = "-" if c is None or not c["per_iteration"] else \
            f"{(r['hn']['cpu'] / r['hn']['iterations']) / c['per_iteration_cpu']:.2f}"
        rows.append([r["label"], str(r["dofs"]), f"{ts:.2f}", f"{it:.2f}",
                     f"{t['h_tangent'] / t['f_tangent']:.2f}", cc])
    print(table(["case", "DOFs", "FElupe: tangent+solve", "FElupe: per iteration", "FElupe: tangent",
                 "CalculiX: per iteration (CPU)"], rows))
    print(f"\ntotal benchmark time: {time.perf_counter() - t0:.1f} s")
    print_load("end load")


if __name__ == "__main__":
    main()
