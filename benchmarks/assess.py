"""Run `hydrojam assess` and write its results table into a marked section of a docs page.

    python benchmarks/assess.py DESIGN.toml -o OUT --section NAME [--page docs/assess.md] [ASSESS OPTIONS ...]

Runs ``hydrojam assess DESIGN.toml -o OUT [ASSESS OPTIONS]`` in this process (``--replicas N``
included), then reads OUT/assessment.json and replaces the lines between
``<!-- assess.py: NAME -->`` and ``<!-- /assess.py: NAME -->`` of the page with one line of
conditions (the command, the commit, cores, solver threads, the mesh, the wall time) and the
table: every figure of the assessment (with its spread over replicas: mean ± std, min-max),
active particles, vacuum and pneumatic side by side. Exit status: the assessment's.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import measured_by, page_parser, write_section  # noqa: E402

#: (key, label, unit in 2D, unit in 3D): the rows of the table
ROWS = (
    ("bending_angle_deg", "bending angle", "deg", "deg"),
    ("stiffness_unactuated", "tangent stiffness, unactuated", "N/mm per mm", "N/mm"),
    ("stiffness_actuated", "tangent stiffness, actuated", "N/mm per mm", "N/mm"),
    ("stiffness_ratio", "**stiffness ratio** (actuated / unactuated)", "-", "-"),
    ("secant_actuated_plus", "secant stiffness at +max force, actuated", "N/mm per mm", "N/mm"),
    ("secant_actuated_minus", "secant stiffness at -max force, actuated", "N/mm per mm", "N/mm"),
    ("max_force", "largest tip force of the curves", "N/mm", "N"),
    ("vacuum_pressure_kPa", "vacuum baseline: pressure held", "kPa", "kPa"),
    ("stiffness_vacuum", "vacuum baseline: tangent stiffness", "N/mm per mm", "N/mm"),
    ("stiffness_ratio_vacuum", "vacuum baseline: **stiffness ratio**", "-", "-"),
    ("pneumatic_angle_deg", "pneumatic baseline: angle reached", "deg", "deg"),
    ("pneumatic_pressure_kPa", "pneumatic baseline: pressure to that angle", "kPa", "kPa"),
    ("stiffness_pneumatic", "pneumatic baseline: tangent stiffness there", "N/mm per mm", "N/mm"),
    ("stiffness_active_over_pneumatic", "**active over pneumatic stiffness**", "-", "-"),
    ("pneumatic_blocked_force", "pneumatic baseline: blocked force", "N/mm", "N"),
    ("contact_pressure_mean_kPa", "contact pressure on the membrane, mean", "kPa", "kPa"),
    ("contact_pressure_max_kPa", "contact pressure on the membrane, max", "kPa", "kPa"),
    ("particle_swelling_t90_s", "particle swelling time t90", "s", "s"),
    ("actuation_newton_iterations", "Newton iterations of the actuation", "-", "-"),
)


def _g(x, digits=3) -> str:
    return "n/a" if x is None else f"{x:.{digits}g}"


def table(out: Path, three_d: bool) -> list[str]:
    """The results table of OUT/assessment.json (one assessment or its replicas)."""
    data = json.loads((out / "assessment.json").read_text(encoding="utf-8"))
    values = data["values"]
    replicas = "replicas" in data
    unit = (lambda r: r[3]) if three_d else (lambda r: r[2])
    if replicas:
        lines = ["| quantity | mean ± std | min-max | n | unit |", "|---|---:|---:|---:|---|"]

        def row(label, sp, u):
            std = "" if sp.get("std") is None else f" ± {_g(sp['std'], 2)}"
            return f"| {label} | {_g(sp.get('mean'))}{std} | {_g(sp.get('min'))}-{_g(sp.get('max'))} | {sp.get('n')} | {u} |"
    else:
        lines = ["| quantity | value | unit |", "|---|---:|---|"]

        def row(label, x, u):
            return f"| {label} | {_g(x)} | {u} |"
    keys = [r for r in ROWS if r[0] in values]
    for r in keys:
        lines.append(row(r[1], values[r[0]], unit(r)))
    blocked = sorted((k for k in values if k.startswith("blocked_force_") and k.endswith("K")),
                     key=lambda k: float(k[len("blocked_force_"):-1]))
    for k in blocked:
        lines.append(row(f"blocked force at {k[len('blocked_force_'):-1]} K", values[k], "N" if three_d else "N/mm"))
    return lines


def cost_table(out: Path) -> list[str]:
    """Where one assessment's time goes: each part's Newton iterations and wall time, from
    OUT/assessment.json (a single assessment; empty for replicas)."""
    data = json.loads((out / "assessment.json").read_text(encoding="utf-8"))
    if "replicas" in data:
        return []
    v, curves = data["values"], data.get("curves", {})
    rows = [("actuation", v.get("actuation_newton_iterations"), v.get("actuation_wall_time_s"))]
    for name in ("unactuated", "actuated"):
        if name in curves:
            rows.append((f"tip curve, {name} (8 loads)", curves[name].get("newton_iterations"),
                         v.get(f"curve_{name}_wall_time_s")))
    for b in data.get("blocked_force", []):
        rows.append((f"blocked actuation at {b['temperature_K']:g} K", b.get("newton_iterations"), b.get("wall_time_s")))
    if "vacuum_newton_iterations" in v:
        its = v["vacuum_newton_iterations"] + (curves.get("vacuum", {}).get("newton_iterations") or 0)
        rows.append(("vacuum: jamming, release, tip curve", its, v.get("vacuum_wall_time_s")))
    if "pneumatic_newton_iterations" in v:
        rows.append(("pneumatic: pressure to the angle (blocked force not counted in iterations)",
                     v["pneumatic_newton_iterations"], v.get("pneumatic_wall_time_s")))
    lines = ["", "| part | Newton iterations | wall [s] |", "|---|---:|---:|"]
    lines += [f"| {name} | {_g(its, 4)} | {_g(wall, 3)} |" for name, its, wall in rows]
    lines.append(f"| **all** | | {_g(v.get('wall_time_s'), 4)} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = page_parser(__doc__, "assess.py")
    parser.add_argument("--no-run", action="store_true",
                        help="write the table of the assessment already in OUT (its own wall time) instead of running it")
    args, rest = parser.parse_known_args(argv)
    from hydrojam.actuator.design import load_design
    from hydrojam.cli import main as hydrojam

    out = Path(args.out)
    if args.no_run:
        code, data = 0, json.loads((out / "assessment.json").read_text(encoding="utf-8"))
        wall = data.get("wall_time_s") if "replicas" in data else data["values"].get("wall_time_s")
    else:
        t0 = time.perf_counter()
        code = hydrojam(["assess", args.design, "-o", args.out, *rest])
        wall = time.perf_counter() - t0
    if not (out / "assessment.json").is_file():
        return code
    design = load_design(out / "design.toml")
    three_d = design.dimension == 3
    model = ("3D half model, forces and stiffnesses of the whole actuator" if three_d and design.mesh.symmetry
             else ("3D" if three_d else "2D, per mm of depth"))
    text = "\n".join([f"{measured_by('assess.py', argv)}, mesh {design.mesh_size:g} mm ({model}), "
                      f"friction {design.friction:g}, wall {wall:.0f} s"
                      f"{'' if args.no_run else f', exit {code}'}.", "", *table(out, three_d), *cost_table(out)])
    write_section(args.page, "assess.py", args.section, text)
    print(f"results table written to {args.page}, section {args.section}")
    return code


if __name__ == "__main__":
    sys.exit(main())
