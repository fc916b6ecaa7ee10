"""What contact costs: collision detection, barrier assembly and CCD against the elastic assembly
and the linear solve, per Newton iteration, as the number of particles grows.

Run:  .venv/bin/python benchmarks/contact.py [--quick] [--path-cap SECONDS] [--ipc-threads N]

The problem
-----------
The jamming setup of ``tests/test_contact.py``: gel disks (R = 1 mm, tri6, mesh size 0.5 mm,
plane strain) on an n_side x n_side grid of cells 2R + c wide, centres jittered by up to 0.3 c
in x and y (fixed seed), inside a square rigid box of side L = n_side (2R + c) + c made of four
fixed wall blocks (neo-Hookean, G = 100 MPa). The gel swells along s in [0, 1] from the
as-prepared (mu0, T0) to (0 kT, 275 K); its free-swollen plane-strain diameter is
2R x 2.586 = 5.17 mm. The clearance is chosen per size so that a row of free-swollen disks is 8%
longer than the box (n_side x 5.17 mm = 1.08 L: c = 1.86, 2.23, 2.48 mm for 2, 4, 8 disks per
side), so every packing ends equally over-confined, jammed against each other and the walls. (A
fixed c = 2.2 mm would leave the 2 x 2 box 2.5% *larger* than its free-swollen disks and
over-confine the 8 x 8 one by 16%.) Contact: IPC barrier, dhat = 0.01 mm, kappa = 10 x the gel's
reference shear modulus, frictionless. Sizes: 4, 16 and 64 disks (``--quick``: 4 and 16).

Table 1, "load path": ``solve_path`` with the default options from s = 0 to the jammed state,
one run per size, stopped at the first accepted step (or failed attempt) after a time cap (60,
40, 110 s for 4, 16, 64 disks, ``--quick`` 20 s, or ``--path-cap``): the full paths take ~8 s,
~2 min and far longer, as jammed packings need hundreds of small load steps near s = 1. A capped
size reports "s reached" < 1 and the micro-benchmarks use its last accepted state (contact pairs
in table 2 show how jammed it is). Wall time, accepted load steps, rejected attempts, Newton
iterations (of all attempts) and the shares of the wall time in the solver's own ``Timings``
phases (what ``PathResult.timings`` reports, summed here over the attempts): assembly
(gradients, Hessians, free-DOF extraction), linear solve, line search (energies), step cap (CCD).
Below, the same wall time split by *what* is computed, measured by wrapping the energy terms
during the path:
  collision detection  building ipctk's collision set (only cache misses: once per new state)
  barrier              contact energy + gradient + Hessian, minus the collision detection in them
  CCD                  ``Contact.max_step`` (continuous collision detection of each step)
  elastic              the Solid's energy + gradient + Hessian
  linear solve         ``PathResult.timings.linear_solve`` (all tries of the damping loop)
  other                the rest: summing and extracting H_ff, residual norms, materials, driver.
"per it." rows divide by the Newton iterations; "/ it." rows count collision-set builds (one per
new state: every line-search trial, and the start of every attempt), CCD calls and linear solves
(more than one where the damping loop retries with a larger shift) per iteration. "solves
re-analysed" is the share of solves whose matrix had another sparsity pattern than the previous
one (the active contacts changed), so PARDISO redid its symbolic analysis instead of reusing it.

Table 2, "micro-benchmarks at the jammed state": median wall time after a warm-up call, of 3
calls, or of as many as fill 0.2 s (at most 25) for fast calls, which a busy machine disturbs most:
  collision set       ``Contact._collisions`` with its cache invalidated (ipctk broad + narrow phase)
  barrier E / g / H   contact energy, gradient, Hessian on a built collision set
  CCD                 ``Contact.max_step`` for a random step of up to 1e-3 mm (0.1 dhat) per free DOF
  elastic E / g / H   the Solid's energy, gradient, Hessian (unprojected)
  sum + extract       H_solid + H_contact and H[free][:, free], as ``minimize`` does
  solve (same pattern) one LinearSolver solve of K = H_ff + 1e-9 mean|diag| I whose sparsity
                      the solver has seen before: factorisation + solve (PARDISO phase 23)
  solve (new pattern) the same after a change of sparsity, as when the active contacts change:
                      symbolic analysis + factorisation + solve (phase 13)
and the state: DOFs, cells (the fixed walls' elements are assembled too, as in the tests: all
their nodes are held, so that part of the elastic work is spent on DOFs that are then
dropped), collision-mesh vertices, active collisions, component pairs in contact.

Table 3, "per Newton iteration": the model of one iteration of ``minimize`` whose full step is
accepted at the first line-search trial, built from table 2: collision detection = 1 collision
set; barrier = E + g + H; CCD = 1 step cap; elastic = E + g + H; sum + extract; linear solve =
1 solve, new or same pattern in the proportion of re-analysed solves along the path (table 1). Times in ms and
shares of the sum. It is a lower bound: the path's own per-iteration numbers (table 1) add
line-search trials (~0.6 more energy + collision set per iteration) and damping retries, and
there every kernel starts with cold caches (after a factorisation), while a micro-benchmark repeats
a warm call: the 4-disk elastic kernels were measured 1.5-2.5x slower after a PARDISO solve than
repeated. Table 1's metered split is the one to read for where the path's time goes.

Growth exponents p in time ~ n_particles^p ("fit p": least-squares over all sizes). Linear work
is p = 1. DOFs grow roughly like the number of disks (plus the walls), so p ~ 1 is linear in DOFs.
The header prints the CPU count, thread settings and load average: timings on a shared 2-core
machine are noisy. Where the time cap stops a path (and so the state of tables 2 and 3) depends on
the speed of the machine. The path itself is not reproducible either with ipctk's default thread
count: its parallel reductions change the barrier's gradient and Hessian in the last bits from
call to call, which a jammed path amplifies (the 4-disk path took 359 to 553 Newton iterations in
repeated runs); ``--ipc-threads 1`` makes them bitwise reproducible at no measured cost here.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import ipctk
import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (  # noqa: E402
    fmt, fmt_slope, growth_exponent, median_time, print_environment, print_load, section, table,
)

from hydrojam.fem import meshing as _gmsh  # noqa: E402
from hydrojam.fem.assembly import Block, Solid  # noqa: E402
from hydrojam.fem.contact import Contact, ContactSettings  # noqa: E402
from hydrojam.fem.elements import element_for_meshio_type  # noqa: E402
from hydrojam.fem.solver.linsolve import LinearSolver  # noqa: E402
from hydrojam.materials.energies import Hydrogel, HydrogelParams, NeoHookean  # noqa: E402
from hydrojam.fem.mesh import Mesh, merge  # noqa: E402
from hydrojam.fem import Problem, Timings, fixed, solve_path  # noqa: E402
from hydrojam.fem.terms import TimedTerm, by_name  # noqa: E402
from hydrojam.materials.swelling import constrained_swelling  # noqa: E402

PARAMS = HydrogelParams()
GEL = Hydrogel(PARAMS)
WALL = NeoHookean(shear_modulus=100.0)  # the rigid box [MPa]
MU_TARGET, T_TARGET = 0.0, 275.0  # the swelling stimulus [kT], [K]

RADIUS = 1.0  # [mm]
MESH_SIZE = 0.5  # [mm]
JITTER = 0.3  # centres moved by up to JITTER x the clearance in x and y
WALL_THICKNESS = 0.5  # [mm]
SEED = 7
WALLS = ("bottom", "top", "left", "right")
WALL_COMPONENT = 1_000_000  # component id of the box (all four walls: one body)
DHAT = 0.01  # [mm]
CCD_STEP = 1e-3  # [mm]: random step per free DOF for the CCD micro-benchmark

GRIDS = (2, 4, 8)  # disks per side
QUICK_GRIDS = (2, 4)
OVER_CONFINEMENT = 0.08  # a row of free-swollen disks is this much longer than the box
PATH_CAP_S = {2: 60.0, 4: 40.0, 8: 110.0}  # seconds of load path, by disks per side
QUICK_PATH_CAP_S = 20.0
REPEATS = 3  # timed calls at least (median reported) ...
MIN_TOTAL_S, MAX_REPEATS = 0.2, 25  # ... or as many as fill MIN_TOTAL_S, at most MAX_REPEATS


# --------------------------------------------------------------------------------------------
# The jamming problem


def free_swollen_diameter() -> float:
    """Diameter [mm] of a disk swollen freely to the target stimulus in plane strain (the
    out-of-plane stretch held at its as-prepared value)."""
    res = constrained_swelling(PARAMS, MU_TARGET, T_TARGET, (PARAMS.lambda0,))
    return 2 * RADIUS * res.stretch / PARAMS.lambda0


def clearance(n_side: int) -> float:
    """Clearance c [mm] such that n_side free-swollen diameters are OVER_CONFINEMENT longer than
    the box side L = n_side (2R + c) + c."""
    L = n_side * free_swollen_diameter() / (1 + OVER_CONFINEMENT)
    return (L - 2 * RADIUS * n_side) / (n_side + 1)


@dataclass
class Case:
    """Gel disks in a rigid box: mesh, energy terms and Dirichlet conditions."""

    n_side: int
    clearance: float  # [mm]
    side: float  # box side L [mm]
    mesh: Mesh
    solid: Solid
    contact: Contact
    wall_nodes: np.ndarray

    @property
    def n_particles(self) -> int:
        return self.n_side**2

    def terms(self, s: float, meter: "Meter | None" = None) -> list:
        gel = GEL.at(PARAMS.mu0 * (1.0 - s) + s * MU_TARGET, PARAMS.T0 + s * (T_TARGET - PARAMS.T0))
        solid = self.solid.with_materials({"gel": gel})
        if meter is None:
            return [solid, self.contact]
        return [TimedTerm(solid, meter.recorder("elastic")), TimedTerm(self.contact, meter.recorder("contact"))]

    def problem(self, meter: "Meter | None" = None) -> Problem:
        return Problem(self.mesh.points, lambda s: self.terms(s, meter), [fixed(self.wall_nodes, 2)],
                       force_scale=GEL.shear_modulus_ref)

    def free(self) -> np.ndarray:
        return np.flatnonzero(self.problem().free_mask())


def build_case(n_side: int) -> Case:
    """The box of ``tests/test_contact.py::_gel_in_box_2d`` with n_side x n_side disks."""
    R, c, t = RADIUS, clearance(n_side), WALL_THICKNESS
    rng = np.random.default_rng(SEED)
    L = n_side * (2 * R + c) + c
    centres = [(c + R + i * (2 * R + c) + JITTER * c * rng.uniform(-1, 1),
                c + R + j * (2 * R + c) + JITTER * c * rng.uniform(-1, 1))
               for j in range(n_side) for i in range(n_side)]
    m = merge({
        "disks": _gmsh.disks(centres, R, MESH_SIZE),
        "bottom": _gmsh.rectangle(L + 2 * t, t, MESH_SIZE, origin=(-t, -t)),
        "top": _gmsh.rectangle(L + 2 * t, t, MESH_SIZE, origin=(-t, L)),
        "left": _gmsh.rectangle(t, L, MESH_SIZE, origin=(-t, 0.0)),
        "right": _gmsh.rectangle(t, L, MESH_SIZE, origin=(L, 0.0)),
    })
    el = element_for_meshio_type(m.cell_type)
    gel_cells = m.cell_groups["disks"]
    wall_cells = np.setdiff1d(np.arange(m.n_cells), gel_cells)
    solid = Solid(m.points, [Block(m.cells[gel_cells], el, GEL, "gel"), Block(m.cells[wall_cells], el, WALL, "walls")])
    comp = np.full(m.n_nodes, WALL_COMPONENT)
    for k in range(n_side**2):
        comp[m.group_nodes(f"disks/disk{k}")] = k
    contact = Contact(m.points, m.boundary_facets(), comp,
                      ContactSettings(dhat=DHAT, kappa=10 * GEL.shear_modulus_ref))
    wall_nodes = np.unique(np.concatenate([m.group_nodes(w) for w in WALLS]))
    return Case(n_side, c, L, m, solid, contact, wall_nodes)


# --------------------------------------------------------------------------------------------
# Metering the energy terms along the path


class Meter:
    """Accumulated wall time [s] and call counts by key."""

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)

    def add(self, key: str, seconds: float) -> None:
        self.seconds[key] += seconds
        self.calls[key] += 1

    def recorder(self, name: str):
        """A TimedTerm record that files each call under "<name> <method>"."""
        return lambda method, seconds: self.add(f"{name} {method}", seconds)


@contextmanager
def metered_collisions(contact: Contact, meter: Meter):
    """Time every collision-set build (a cache miss of ``Contact._collisions``) into
    meter["collisions"]; the instance's own method is restored on exit."""
    build = contact._collisions

    def collisions(x):
        key = contact._cache_key
        t0 = time.perf_counter()
        out = build(x)
        if contact._cache_key is not key:  # a new collision set was built
            meter.add("collisions", time.perf_counter() - t0)
        return out

    contact._collisions = collisions
    try:
        yield
    finally:
        del contact._collisions


@contextmanager
def metered_solves(meter: Meter):
    """Count LinearSolver solves (meter["solves"]) and those that redid PARDISO's symbolic
    analysis for a new sparsity pattern (meter["analyses"]); the class is restored on exit."""
    solve = LinearSolver.solve

    def counted(solver, K, b):
        before = solver._analysed
        try:
            return solve(solver, K, b)
        finally:
            meter.add("solves", 0.0)
            if solver.method == "pardiso" and (before is None or solver._analysed != before):
                meter.add("analyses", 0.0)

    LinearSolver.solve = counted
    try:
        yield
    finally:
        LinearSolver.solve = solve


# --------------------------------------------------------------------------------------------
# Table 1: the load path


class _TimeCap(Exception):
    pass


@dataclass
class PathRun:
    """What the path did: the last accepted state, step counts, PathResult-style timings and the
    metered split of the wall time."""

    x: np.ndarray
    s: float
    converged: bool
    capped: bool  # stopped by the time cap
    message: str
    wall: float
    steps: int
    rejected: int
    timings: Timings
    meter: Meter


def follow_path(case: Case, cap_s: float) -> PathRun:
    """solve_path from s = 0, stopped after ``cap_s`` seconds at the next accepted step or failed
    attempt; timings are accumulated from every attempt (the s = 0 equilibration, zero Newton
    iterations for the stress-free reference, is not counted)."""
    meter = Meter()
    rec = {"x": case.mesh.points.copy(), "s": 0.0, "steps": 0, "rejected": 0, "timings": Timings()}
    t0 = time.perf_counter()

    def check_cap():
        if time.perf_counter() - t0 > cap_s:
            raise _TimeCap

    def on_attempt(s, ds, res):
        rec["timings"].add(res.timings)
        if not res.converged:
            rec["rejected"] += 1
            check_cap()

    def on_step(s, x, step):
        rec["x"], rec["s"] = x.copy(), s
        rec["steps"] += 1
        check_cap()

    capped = False
    with metered_collisions(case.contact, meter), metered_solves(meter):
        try:
            res = solve_path(case.problem(meter), callback=on_step, on_attempt=on_attempt)
            converged, message = res.converged, res.message
            if not converged:
                rec["x"], rec["s"] = res.x, res.s
        except _TimeCap:
            capped, converged = True, False
            message = f"stopped by the time cap ({cap_s:g} s) at s = {rec['s']:.4g}"
    wall = time.perf_counter() - t0
    return PathRun(rec["x"], rec["s"], converged, capped, message, wall, rec["steps"], rec["rejected"],
                   rec["timings"], meter)


def path_split(run: PathRun) -> dict[str, float]:
    """Wall time [s] of the path by what is computed (see the module docstring)."""
    sec = run.meter.seconds
    contact = sum(sec[f"contact {m}"] for m in ("energy", "gradient", "hessian"))
    split = {
        "collisions": sec["collisions"],
        "barrier": contact - sec["collisions"],
        "ccd": sec["contact max_step"],
        "elastic": sum(sec[f"elastic {m}"] for m in ("energy", "gradient", "hessian")),
        "solve": run.timings.linear_solve,
    }
    split["other"] = run.wall - sum(split.values())
    return split


SPLIT_ROWS = [("collisions", "collision detection"), ("barrier", "barrier E+g+H"), ("ccd", "CCD"),
              ("elastic", "elastic E+g+H"), ("solve", "linear solve"), ("other", "other")]


def reanalysed_share(run: PathRun) -> float:
    """Share of the path's linear solves that redid the symbolic analysis (new pattern)."""
    calls = run.meter.calls
    return calls["analyses"] / max(calls["solves"], 1)


def print_path_table(results: list[dict]) -> None:
    section("1. Load path to the jammed state (solve_path, default options; one run)")
    n = [r["case"].n_particles for r in results]
    runs = [r["run"] for r in results]
    its = [max(run.timings.iterations, 1) for run in runs]

    def row(name, values, slope=None):
        return [name, *values, fmt_slope(slope) if slope is not None else ""]

    rows = [
        row("clearance c [mm]", [f"{r['case'].clearance:.3f}" for r in results]),
        row("box side L [mm]", [f"{r['case'].side:.2f}" for r in results]),
        row("DOFs", [str(r["case"].mesh.points.size) for r in results]),
        row("s reached", [f"{run.s:.4g}" for run in runs]),
        row("converged", ["yes" if run.converged else "no (capped)" if run.capped else "no" for run in runs]),
        row("wall [s]", [fmt(run.wall) for run in runs]),
        row("load steps (+rejected)", [f"{run.steps} (+{run.rejected})" for run in runs]),
        row("Newton iterations", [str(run.timings.iterations) for run in runs]),
        row("wall per iteration [ms]", [fmt(run.wall / k, 1e3) for run, k in zip(runs, its)],
            growth_exponent(n, [run.wall / k for run, k in zip(runs, its)])),
    ]
    phases = ("assembly", "linear_solve", "line_search", "step_cap")
    rows.append(row("solver Timings shares:", ["" for _ in runs]))
    for key in phases:
        rows.append(row(f"  {key}", [f"{100 * getattr(run.timings, key) / run.wall:.0f}%" for run in runs]))
    rest = [1 - sum(getattr(run.timings, k) for k in phases) / run.wall for run in runs]
    rows.append(row("  other", [f"{100 * v:.0f}%" for v in rest]))
    splits = [path_split(run) for run in runs]
    rows.append(row("metered split, per it. [ms] (share):", ["" for _ in runs]))
    for key, name in SPLIT_ROWS:
        per_it = [sp_[key] / k for sp_, k in zip(splits, its)]
        rows.append(row(f"  {name}", [f"{fmt(v, 1e3)} ({100 * sp_[key] / run.wall:.0f}%)"
                                      for v, sp_, run in zip(per_it, splits, runs)],
                        growth_exponent(n, per_it) if key != "other" else None))
    rows.append(row("contact total share", [f"{100 * (s_['collisions'] + s_['barrier'] + s_['ccd']) / run.wall:.0f}%"
                                            for s_, run in zip(splits, runs)]))
    for key, name in (("collisions", "collision builds / it."), ("contact max_step", "CCD calls / it."),
                      ("solves", "linear solves / it.")):
        rows.append(row(name, [f"{run.meter.calls[key] / k:.2f}" for run, k in zip(runs, its)]))
    rows.append(row("solves re-analysed (new pattern)", [f"{100 * reanalysed_share(run):.0f}%" for run in runs]))
    header = ["", *[f"{k} disks" for k in n], "fit p"]
    print(table(header, rows))
    for r in results:
        if not r["run"].converged:
            print(f"note ({r['case'].n_particles} disks): {r['run'].message}")


# --------------------------------------------------------------------------------------------
# Table 2: micro-benchmarks at the jammed state


MICRO_ROWS = [
    ("collisions", "collision set (cache miss)"),
    ("barrier_e", "barrier energy"),
    ("barrier_g", "barrier gradient"),
    ("barrier_h", "barrier Hessian"),
    ("ccd", "CCD max_step (random 1e-3 mm)"),
    ("elastic_e", "elastic energy"),
    ("elastic_g", "elastic gradient"),
    ("elastic_h", "elastic Hessian"),
    ("extract", "sum + extract H_ff"),
    ("solve_same", "solve (same pattern)"),
    ("solve_new", "solve (new pattern)"),
]


def _with_structural_zero(K: sp.csr_matrix) -> sp.csr_matrix:
    """K with an explicit zero coupling its first and last DOF: same values, another pattern."""
    c = K.tocoo()
    i, j = 0, K.shape[0] - 1
    K2 = sp.csr_matrix((np.r_[c.data, 0.0, 0.0], (np.r_[c.row, i, j], np.r_[c.col, j, i])), shape=K.shape)
    assert K2.nnz == K.nnz + 2, "the first and last free DOF are coupled already"
    return K2


def measure_micro(case: Case, x: np.ndarray, s: float) -> dict:
    """Median times [s] of the contact and elastic kernels at state x (load parameter s)."""
    C = case.contact
    solid = by_name(case.terms(s))["elastic"]
    fidx = case.free()
    t: dict[str, float] = {}

    def timed(fn):
        t0 = time.perf_counter()
        fn()  # the warm-up, which also sizes the number of timed calls
        repeats = int(np.clip(MIN_TOTAL_S / max(time.perf_counter() - t0, 1e-9), REPEATS, MAX_REPEATS))
        return median_time(fn, repeats=repeats, warmup=0)

    def build_collisions():
        C._cache_key = None  # the cache is keyed on the vertex bytes: invalidate it to rebuild
        return C._collisions(x)

    t["collisions"], (_, col) = timed(build_collisions)
    t["barrier_e"], _ = timed(lambda: C.energy(x))
    t["barrier_g"], _ = timed(lambda: C.gradient(x))
    t["barrier_h"], Hc = timed(lambda: C.hessian(x))
    rng = np.random.default_rng(SEED)
    step = np.zeros(x.size)
    step[fidx] = CCD_STEP * rng.uniform(-1.0, 1.0, len(fidx))
    t["ccd"], alpha = timed(lambda: C.max_step(x, step.reshape(x.shape)))
    t["elastic_e"], _ = timed(lambda: solid.energy(x))
    t["elastic_g"], g = timed(lambda: solid.gradient(x))
    t["elastic_h"], Hs = timed(lambda: solid.hessian(x))
    t["extract"], Hff = timed(lambda: sp.csr_matrix(Hs + Hc)[fidx][:, fidx])
    K = Hff + sp.identity(len(fidx), format="csr") * (1e-9 * abs(Hff.diagonal()).mean())
    b = -(g + C.gradient(x))[fidx]
    solver = LinearSolver()
    t["solve_same"], u = timed(lambda: solver.solve(K, b))
    # a pattern change as contact makes it: K and K with one more structural (zero) entry pair,
    # alternately, so that every solve re-analyses (one solver: not its ~0.1 s construction)
    mats = [K, _with_structural_zero(K)]

    def solve_new_pattern():
        mats.reverse()
        return solver.solve(mats[0], b)

    t["solve_new"], _ = timed(solve_new_pattern)
    pairs = C.contact_pairs(x)
    info = {
        "dofs": x.size,
        "free": len(fidx),
        "cells": " / ".join(str(len(b.cells)) for b in solid.blocks),
        "vertices": len(C.vertex_ids),
        "active": len(col),
        "pp": sum(1 for a, b_ in pairs if b_ != WALL_COMPONENT),
        "pw": sum(1 for a, b_ in pairs if b_ == WALL_COMPONENT),
        "alpha": alpha,
        "nnz_c": Hc.nnz,
        "nnz": K.nnz,
        "residual": float(np.linalg.norm(K @ u - b) / np.linalg.norm(b)),
        "method": solver.method,
    }
    return {"t": t, "info": info}


def print_micro_table(results: list[dict]) -> None:
    section(f"2. Micro-benchmarks at the jammed state: median of {REPEATS}-{MAX_REPEATS} calls after a warm-up, ms")
    n = [r["case"].n_particles for r in results]
    infos = [r["micro"]["info"] for r in results]
    rows = [[name, *[str(i[key]) for i in infos], ""] for key, name in (
        ("dofs", "DOFs"), ("free", "free DOFs"), ("cells", "cells gel / walls"),
        ("vertices", "collision-mesh vertices"),
        ("active", "active collisions"), ("pp", "particle-particle pairs"), ("pw", "particle-wall pairs"),
        ("nnz_c", "nnz(H contact)"), ("nnz", "nnz(H_ff)"))]
    rows.insert(1, ["s of the state", *[f"{r['run'].s:.4g}" for r in results], ""])
    for key, name in MICRO_ROWS:
        times = [r["micro"]["t"][key] for r in results]
        rows.append([f"{name} [ms]", *[fmt(v, 1e3) for v in times], fmt_slope(growth_exponent(n, times))])
    rows.append(["CCD step fraction allowed", *[f"{i['alpha']:.3g}" for i in infos], ""])
    rows.append(["rel. residual of the solve", *[f"{i['residual']:.1e}" for i in infos], ""])
    print(table(["", *[f"{k} disks" for k in n], "fit p"], rows))
    if infos and infos[0]["method"] != "pardiso":
        print(f"note: PARDISO is not available; 'auto' ran {infos[0]['method']}")


# --------------------------------------------------------------------------------------------
# Table 3: per Newton iteration


def iteration_model(t: dict[str, float], new_pattern: float) -> dict[str, float]:
    """One Newton iteration of ``minimize`` with its full step accepted at the first trial [s]."""
    return {
        "collisions": t["collisions"],
        "barrier": t["barrier_e"] + t["barrier_g"] + t["barrier_h"],
        "ccd": t["ccd"],
        "elastic": t["elastic_e"] + t["elastic_g"] + t["elastic_h"],
        "extract": t["extract"],
        "solve": new_pattern * t["solve_new"] + (1 - new_pattern) * t["solve_same"],
    }


MODEL_ROWS = [("collisions", "collision detection"), ("barrier", "barrier E+g+H"), ("ccd", "CCD"),
              ("elastic", "elastic E+g+H"), ("extract", "sum + extract H_ff"), ("solve", "linear solve")]


def print_iteration_table(results: list[dict]) -> None:
    section("3. Per Newton iteration (model from table 2): ms (share)")
    n = [r["case"].n_particles for r in results]
    models = [iteration_model(r["micro"]["t"], reanalysed_share(r["run"])) for r in results]
    totals = [sum(m.values()) for m in models]
    rows = []
    for key, name in MODEL_ROWS:
        vals = [m[key] for m in models]
        rows.append([name, *[f"{fmt(v, 1e3)} ({100 * v / tot:.0f}%)" for v, tot in zip(vals, totals)],
                     fmt_slope(growth_exponent(n, vals))])
    contact = [m["collisions"] + m["barrier"] + m["ccd"] for m in models]
    rows.append(["contact (first three)", *[f"{fmt(v, 1e3)} ({100 * v / tot:.0f}%)" for v, tot in zip(contact, totals)],
                 fmt_slope(growth_exponent(n, contact))])
    rows.append(["total", *[fmt(v, 1e3) for v in totals], fmt_slope(growth_exponent(n, totals))])
    rows.append(["path: wall per iteration",
                 *[fmt(r["run"].wall / max(r["run"].timings.iterations, 1), 1e3) for r in results], ""])
    print(table(["", *[f"{k} disks" for k in n], "fit p"], rows))
    print("linear solve: one solve, new/same pattern weighted by the share of re-analysed solves along the path;")
    print("the path's wall per iteration includes line-search trials, damping retries and the driver.")


# --------------------------------------------------------------------------------------------


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="smoke run: 4 and 16 disks only")
    p.add_argument("--ipc-threads", type=int, default=None,
                   help="ipctk (TBB) threads (default: the library's own; 1 makes the paths reproducible)")
    p.add_argument("--path-cap", type=float, default=None,
                   help="seconds of load path for every size (default: 60, 40, 110 s for 4, 16, 64 disks; "
                        f"--quick {QUICK_PATH_CAP_S:g} s)")
    return p.parse_args(argv)


def path_cap(n_side: int, args: argparse.Namespace) -> float:
    if args.path_cap is not None:
        return args.path_cap
    return QUICK_PATH_CAP_S if args.quick else PATH_CAP_S[n_side]


def main(argv=None) -> None:
    args = parse_args(argv)
    t_start = time.perf_counter()
    print("hydrojam contact benchmark" + (" (--quick)" if args.quick else ""))
    print_environment(["hydrojam", "numpy", "scipy", "ipctk", "pypardiso", "mkl", "gmsh"])
    if args.ipc_threads is not None:
        ipctk.set_num_threads(args.ipc_threads)
    print(f"ipctk   : {ipctk.get_num_threads()} threads" + ("" if args.ipc_threads else " (library default)"))
    print(f"setup   : gel disks R = {RADIUS:g} mm (free-swollen diameter {free_swollen_diameter():.3f} mm) in a "
          f"rigid box {100 * OVER_CONFINEMENT:g}% smaller, jitter {JITTER:g} c (seed {SEED}), mesh {MESH_SIZE:g} mm "
          f"tri6; dhat = {DHAT:g} mm, kappa = {10 * GEL.shear_modulus_ref:.3g} MPa")
    results = []
    for n_side in QUICK_GRIDS if args.quick else GRIDS:
        t0 = time.perf_counter()
        case = build_case(n_side)
        t_build = time.perf_counter() - t0
        run = follow_path(case, path_cap(n_side, args))
        micro = measure_micro(case, run.x, run.s)
        results.append({"case": case, "run": run, "micro": micro})
        print(f"  [{case.n_particles} disks, {case.mesh.points.size} DOFs: mesh + setup {t_build:.1f} s, "
              f"path {run.wall:.1f} s to s = {run.s:.4g}, total {time.perf_counter() - t0:.1f} s]", flush=True)
    print_path_table(results)
    print_micro_table(results)
    print_iteration_table(results)
    print(f"\ntotal benchmark time: {time.perf_counter() - t_start:.1f} s")
    print_load("end load")


if __name__ == "__main__":
    main()
