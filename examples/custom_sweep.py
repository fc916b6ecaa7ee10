"""A custom study built in Python: the same actuator at two temperatures.

The study is a base design (one particle layer, coarse mesh) and one sweep over the target
temperature; `run_sweep` runs its points (here one at a time), caches each in
OUT_DIR/points/<key>/ and returns the table, also written to OUT_DIR/results.csv and
results.parquet. Run it again and the points are loaded from the cache at once.

    python examples/custom_sweep.py [OUT_DIR]      # default ./custom-sweep-out
"""

import sys
from pathlib import Path

from hydrojam.study.spec import study_from_dict
from hydrojam.study.sweep import run_sweep


def main(out: Path) -> int:
    # the same as a study.toml file with [design] and [[sweep]] tables (see docs/sweeps.md)
    study = study_from_dict({
        "name": "two-temperatures",
        "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
        "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [285.0, 295.0]}}],
    })
    table = run_sweep(study, out, workers=1)

    print(f"study '{study.name}': {len(table)} points -> {out}/results.csv")
    print(f"{'T [K]':>6}  {'angle [deg]':>11}  {'tip dx [mm]':>11}  {'tip dz [mm]':>11}  status")
    for row in table.rows:
        print(f"{row['stimulus.temperature']:6.1f}  {row['bending_angle_deg']:11.2f}  "
              f"{row['tip_dx_mm']:11.2f}  {row['tip_dz_mm']:11.2f}  {row['status']}")
    return 0 if all(r["status"] == "ok" for r in table.rows) else 1


# The guard is needed: the sweep's worker processes re-import this file, and without it each
# of them would start a sweep of its own.
if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1] if len(sys.argv) > 1 else "custom-sweep-out")))
