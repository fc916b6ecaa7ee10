"""Is a run bit-identical whatever the thread settings? And what does friction change? (issue 14)

Run:  .venv/bin/python benchmarks/determinism.py [--design one_layer default] [--repeat 2]
                                               [--setting NAME ...] [--set key=value ...]

Every run is a fresh subprocess (MKL, numba and ipctk read their thread counts at start-up) with
the environment of one named setting (:data:`SETTINGS`); it prints the bending angle to all
digits (``repr``), the tip, Newton iterations, the first load parameter at which the physical
Hessian lost definiteness (``buckled_at_s``, where the run reports it), the number of unstable
states and the final state's negative eigenvalues, the linear solver's time per call and the wall
time. ``--repeat`` runs every setting again (run-to-run repeatability).
``--set`` applies design overrides (e.g. ``friction=0.1``) to every design.

Angles and iteration counts are deterministic figures; times are disturbed by whatever else runs
(the load is printed).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_load, table  # noqa: E402

DESIGNS = {"one_layer": ["particle_layers=1"], "default": []}

#: named thread settings: environment variables set for the child process
SETTINGS = {
    "base": {},
    "solver2": {"HYDROJAM_SOLVER_THREADS": "2"},
    "ipc2": {"HYDROJAM_IPC_THREADS": "2"},
    "numba1": {"NUMBA_NUM_THREADS": "1"},
    "blas1": {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"},
    "all2": {"HYDROJAM_SOLVER_THREADS": "2", "HYDROJAM_IPC_THREADS": "2", "NUMBA_NUM_THREADS": "2",
             "OMP_NUM_THREADS": "2", "OPENBLAS_NUM_THREADS": "2"},
}

_CHILD = """
import json, sys, time
from hydrojam.actuator.design import apply_overrides, default_design
from hydrojam.actuator.model import build_model
from hydrojam.actuator.simulate import simulate
model = build_model(apply_overrides(default_design(), json.loads(sys.argv[1])))
t0 = time.perf_counter()
res = simulate(model)
wall = time.perf_counter() - t0
m = res.metrics
print(json.dumps({"angle": repr(m["bending_angle_deg"]), "dx": m["tip_dx_mm"], "dz": m["tip_dz_mm"],
                  "its": m["newton_iterations"], "converged": m["converged"], "buckled": m.get("buckled_at_s"),
                  "unstable": m.get("unstable_states"), "final_negative": res.final.negative_eigenvalues,
                  "solve_s": res.timings.get("linear_solve", 0.0), "path_its": res.timings.get("newton_iterations", 0),
                  "wall": wall}))
"""


def run_child(design: list[str], env: dict[str, str]) -> dict:
    """One simulation in a fresh interpreter with ``env`` added to this process's environment."""
    full = {**os.environ, **env}
    out = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(design)], env=full, capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", nargs="+", default=["one_layer"], choices=sorted(DESIGNS))
    ap.add_argument("--setting", nargs="+", default=["base", "solver2", "ipc2"], choices=sorted(SETTINGS))
    ap.add_argument("--repeat", type=int, default=1, help="runs of every setting")
    ap.add_argument("--set", nargs="*", default=[], help="design overrides, e.g. friction=0.1")
    args = ap.parse_args(argv)
    print_load()
    rows = []
    for design in args.design:
        for setting in args.setting:
            for k in range(args.repeat):
                t0 = time.perf_counter()
                r = run_child(DESIGNS[design] + args.set, SETTINGS[setting])
                rows.append([design + ("," + ",".join(args.set) if args.set else ""), setting, str(k), r["angle"],
                             f"({r['dx']:.3f}, {r['dz']:.3f})", str(r["its"]), f"{r['buckled']} ({r.get('unstable')}, {r.get('final_negative')})",
                             f"{1e3 * r['solve_s'] / max(r['path_its'], 1):.1f}", f"{r['wall']:.1f}",
                             f"{time.perf_counter() - t0:.1f}"])
                print("  " + " | ".join(rows[-1]), flush=True)
    print_load()
    print()
    print(table(["design", "setting", "run", "angle [deg]", "tip (dx, dz) [mm]", "Newton its", "buckled at s (unstable states, final)",
                 "solve/it [ms]", "wall [s]", "with start-up [s]"], rows, left=3))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
