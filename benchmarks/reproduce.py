"""What reproducing the paper costs: `hydrojam reproduce` (the Section IV sweeps) end to end,
on a local dask cluster, from an empty output folder.

Run:  .venv/bin/python benchmarks/reproduce.py [--full] [--workers N] [-o OUT]

Default: the quick study (11 distinct designs, mesh size 4 mm). ``--full``
runs the full study (23 designs at the default 2 mm mesh: hours on 2 cores). Prints, per point,
its wall time, Newton iterations, load steps and the share of its time in elastic terms, contact
and linear solves, then the sweep's wall time, the compute time summed over points and the
parallel efficiency (summed compute / (wall x workers)). OUT (default: a temporary folder) keeps
the results; the benchmark refuses an OUT that already holds points, since cached points would
not be timed.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import fmt, print_environment, print_load, table  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="the full study instead of the quick one")
    ap.add_argument("--workers", type=int, default=None, help="local workers (default: one per CPU)")
    ap.add_argument("-o", "--out", type=Path, default=None, help="output folder (default: temporary)")
    args = ap.parse_args(argv)

    from hydrojam.paper.reproduce import reproduce

    print_environment(["numpy", "scipy", "ipctk", "gmsh", "pypardiso", "distributed"])
    print_load()
    workers = args.workers or os.cpu_count()
    with tempfile.TemporaryDirectory(prefix="hydrojam-bench-") as tmp:
        out = args.out or Path(tmp) / "reproduce"
        if (out / "points").is_dir() and any((out / "points").iterdir()):
            print(f"{out}/points holds cached points: choose an empty OUT", file=sys.stderr)
            return 2
        print(f"study: {'full' if args.full else 'quick'}; {workers} local workers; OUT = {out}")
        t0 = time.perf_counter()
        table_, report = reproduce(out, quick=not args.full, workers=workers)
        wall = time.perf_counter() - t0
        rows, seen = [], set()
        compute = 0.0
        for r in table_.rows:
            if r["key"] in seen:
                continue
            seen.add(r["key"])
            metrics_file = out / r["point_dir"] / "metrics.json"
            tm = json.loads(metrics_file.read_text())["timings_s"] if metrics_file.is_file() else {}
            total = tm.get("total") or 0.0
            compute += r["wall_time_s"] or 0.0
            share = (lambda k: f"{100 * tm.get(k, 0.0) / total:.0f}%" if total else "-")
            values = {"T [K]": r["stimulus.temperature"], "PL": r["particle_layers"], "h [mm]": r["strain_limit_thickness"]}
            rows.append([fmt(values["T [K]"]), str(values["PL"]), fmt(values["h [mm]"]), r["status"],
                         fmt(r["wall_time_s"]), str(r["newton_iterations"]), str(r["load_steps"]),
                         share("elastic"), share("contact"), share("linear_solve")])
        print(table(["T [K]", "PL", "h [mm]", "status", "wall [s]", "Newton its", "steps", "elastic", "contact",
                     "linear solve"], rows))
        print(f"sweep wall time: {wall:.0f} s ({wall / 60:.1f} min) for {len(seen)} designs on {workers} workers")
        print(f"compute time summed over points: {compute:.0f} s; parallel efficiency "
              f"{compute / (wall * workers):.0%}")
        print(f"report: {report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
