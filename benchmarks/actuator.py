"""What one actuator simulation costs: the default design (docs/actuator.md, "Design") from the
as-prepared state to (0 kT, 275 K), end to end.

Run:  .venv/bin/python benchmarks/actuator.py [--set key=value ...] [--quick] [--dimension 3]

``--quick`` runs one particle layer instead of five (a smoke test of the benchmark itself).
``--dimension 3`` runs the 3D actuator (the half model unless ``--set mesh.symmetry=false``) at
the quick mesh (4 mm) unless ``--set mesh.size=...`` says otherwise; the peak memory (the
process's largest resident set) is printed at the end.
Prints the problem size, the wall time split into meshing (gmsh and the model set-up), elastic
terms (the Solid's energy, gradient and Hessian), contact (collision detection, barrier, CCD),
linear solves and the rest (line search bookkeeping, metrics after every step, driver), Newton
iterations, load steps and rejected attempts, and the final metrics. The time spent releasing
the stabilisation at s = 1 (docs/actuator.md) is shown separately as well (it is part of the
phases above).
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import fmt, print_environment, print_load, table  # noqa: E402

from hydrojam.actuator.design import apply_overrides, default_design  # noqa: E402
from hydrojam.actuator.model import build_model  # noqa: E402
from hydrojam.actuator.simulate import simulate  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", dest="overrides", action="append", default=[], help="design override key=value")
    ap.add_argument("--quick", action="store_true", help="one particle layer (smoke test)")
    ap.add_argument("--dimension", type=int, choices=(2, 3), default=2,
                    help="2 (plane strain) or 3 (spheres, half model, 4 mm mesh by default)")
    args = ap.parse_args(argv)
    overrides = (["particle_layers=1"] if args.quick else []) + args.overrides
    if args.dimension == 3:
        overrides = ["dimension=3", "mesh.size=4"] + overrides
    design = apply_overrides(default_design(), overrides)
    print_environment(["numpy", "scipy", "ipctk", "gmsh", "pypardiso"])
    print_load()
    print(f"design: default{'' if not overrides else ' with ' + ', '.join(overrides)}; "
          f"T -> {design.stimulus.temperature:g} K, mu -> {design.stimulus.mu:g} kT")

    t0 = time.perf_counter()
    model = build_model(design)
    t_mesh = time.perf_counter() - t0
    kind = "quadratic tetrahedra" if model.mesh.dim == 3 else "quadratic triangles"
    half = " (half model y >= 0)" if getattr(model, "half", False) else ""
    print(f"mesh{half}: {model.mesh.n_cells} {kind}, {model.mesh.n_nodes} nodes, "
          f"{model.mesh.points.size} DOFs, {model.n_particles} particles, "
          f"dhat {model.contact.settings.dhat:g} mm, kappa {model.contact.settings.kappa:g} MPa")
    last = [0.0]

    def progress(state):
        if time.perf_counter() - last[0] > 10 or state.s >= 1.0:
            last[0] = time.perf_counter()
            m = state.metrics
            print(f"  s = {state.s:.3f}  T = {state.T:.1f} K  angle {m['bending_angle_deg']:7.2f} deg  "
                  f"t = {state.wall_time_s:.0f} s", flush=True)

    res = simulate(model, on_step=progress)
    tm = res.timings
    total = t_mesh + res.wall_time_s
    other = res.wall_time_s - tm["elastic"] - tm["contact"] - tm["linear_solve"]
    rows = [
        ["meshing + set-up", fmt(t_mesh), fmt(100 * t_mesh / total, digits=2)],
        ["elastic terms", fmt(tm["elastic"]), fmt(100 * tm["elastic"] / total, digits=2)],
        ["contact", fmt(tm["contact"]), fmt(100 * tm["contact"] / total, digits=2)],
        ["linear solve", fmt(tm["linear_solve"]), fmt(100 * tm["linear_solve"] / total, digits=2)],
        ["other", fmt(other), fmt(100 * other / total, digits=2)],
        ["total", fmt(total), "100"],
        ["  of which: releasing the stabilisation at s = 1", fmt(tm["release"]), fmt(100 * tm["release"] / total, digits=2)],
    ]
    print()
    print(table(["phase", "wall [s]", "share [%]"], rows))
    print()
    m = res.metrics
    print(f"converged: {res.converged} ({res.message})")
    print(f"load steps {m['load_steps']}, rejected attempts {m['rejected_steps']}, "
          f"Newton iterations {res.newton_iterations} ({1e3 * res.wall_time_s / max(res.newton_iterations, 1):.0f} ms each)")
    print(f"bending angle {m['bending_angle_deg']:.2f} deg, tip dx {m['tip_dx_mm']:.2f} mm, dz {m['tip_dz_mm']:.2f} mm, "
          f"curling index {m['curling_index']}, packing fraction {m['packing_fraction']:.3f}, "
          f"contacts per particle {m['contacts_per_particle']:.2f}, "
          f"stabilisation energy / elastomer energy (max over steps) {m['stabilisation_energy_ratio']:.3g}")
    print(f"CPU time of this process {time.process_time():.0f} s (all its threads; the wall time of a loaded machine "
          f"is longer)")
    print(f"peak memory (largest resident set of this process) {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    print_load("load at the end")
    return 0 if res.converged else 1


if __name__ == "__main__":
    sys.exit(main())
