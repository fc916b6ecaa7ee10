"""Run `hydrojam design-map` and write its table into a marked section of a docs page.

    python benchmarks/design_map.py DESIGN.toml -o OUT --section NAME [--page docs/assess.md] [DESIGN-MAP OPTIONS ...]

Runs ``hydrojam design-map DESIGN.toml -o OUT [DESIGN-MAP OPTIONS]`` in this process (cached
points are loaded, not run again), then reads OUT/design_map.csv and replaces the lines between
``<!-- design_map.py: NAME -->`` and ``<!-- /design_map.py: NAME -->`` of the page with one line
of conditions (the command, the commit, cores, solver threads, the mesh, the points' compute
time and this call's wall time) and the
table: per (t0, G) point the bending angle [deg], the stiffness ratio, the wall's mean and largest
contact pressure [kPa] and their share of the gel's confined swelling pressure. Exit status: the
design map's.
"""

from __future__ import annotations

import csv
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import measured_by, page_parser, write_section  # noqa: E402

#: MPa -> kPa
KPA = 1000.0


def _cell(row: dict, key: str, scale: float = 1.0, fmt: str = "{:.3g}") -> str:
    text = row.get(key, "")
    return "n/a" if text in ("", None) else fmt.format(float(text) * scale)


def table(out: Path) -> list[str]:
    """The rows of OUT/design_map.csv as a Markdown table (one row per point)."""
    with open(out / "design_map.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    lines = ["| t0 [mm] | G [MPa] | angle [deg] | stiffness ratio | contact mean / max [kPa] | contact / swelling pressure |",
             "|---|---|---:|---:|---:|---:|"]
    for r in rows:
        angle = _cell(r, "bending_angle_deg", fmt="{:.1f}").replace("-", "\u2212")
        lines.append(f"| {float(r['side_wall_thickness']):g} | {float(r['membrane.shear_modulus']):g} | {angle} | "
                     f"{_cell(r, 'stiffness_ratio', fmt='{:.1f}')} | {_cell(r, 'contact_pressure_mean', KPA, '{:.1f}')} / "
                     f"{_cell(r, 'contact_pressure_max', KPA, '{:.3g}')} | {_cell(r, 'confinement_share', fmt='{:.2g}')} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = page_parser(__doc__, "design_map.py")
    args, rest = parser.parse_known_args(argv)
    from hydrojam.actuator.design import apply_overrides, load_design
    from hydrojam.cli import main as hydrojam

    out = Path(args.out)
    t0 = time.perf_counter()
    code = hydrojam(["design-map", args.design, "-o", args.out, *rest])
    wall = time.perf_counter() - t0
    if not (out / "design_map.csv").is_file():
        return code
    design = load_design(args.design)
    sets = [rest[i + 1] for i, a in enumerate(rest[:-1]) if a == "--set"]
    design = apply_overrides(design, sets)  # the mesh and layers the map ran with
    compute = sum(json.loads(f.read_text(encoding="utf-8")).get("point_time_s") or 0.0
                  for f in (out / "points").glob("*/point.json"))
    text = "\n".join([f"{measured_by('design_map.py', argv)}, {design.dimension}D, {design.particle_layers} particle "
                      f"layer(s), mesh {design.mesh_size:g} mm, friction {design.friction:g}, points' compute "
                      f"{compute:.0f} s summed, wall {wall:.0f} s (points already in OUT load instead of running), "
                      f"exit {code}.", "", *table(out)])
    write_section(args.page, "design_map.py", args.section, text)
    print(f"design map table written to {args.page}, section {args.section}")
    return code


if __name__ == "__main__":
    sys.exit(main())
