"""The assessment's report (``hydrojam assess``): report.md, assessment.json and three figures,
written atomically (docs/assess.md). The conclusion is worded from the numbers alone."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from hydrojam._format import duration
from hydrojam._html import markdown_page
from hydrojam._io import atomic_path, make_folder, write_text_atomic
from hydrojam.actuator.design import design_to_toml
from hydrojam.assess.assessment import Assessment

#: bending-stiffness gains the authors' later work reports for active particle jamming
REPORTED_GAIN = (9.0, 30.0)
#: the wall "holds" the gel when the contact pressure is at least this share of the swelling pressure
HOLDS_SHARE = 0.1


def _save(fig: Figure, path: Path) -> None:
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")


def plot_curves(a: Assessment, path: str | os.PathLike) -> None:
    """Tip force against the tip's x deflection, each state's curve [N/mm per unit depth, mm]."""
    fig = Figure(figsize=(6.5, 4.5))
    ax = fig.add_subplot()
    labels = {"unactuated": "unactuated (mu0, T0)", "actuated": f"actuated ({a.design.stimulus.temperature:g} K)",
              "vacuum": f"vacuum-jammed ({a.values.get('vacuum_pressure_kPa', 0):.3g} kPa)"}
    for name, c in a.curves.items():
        ax.plot(c.deflections, 1e3 * c.forces, "o-", label=labels.get(name, name))
    ax.axhline(0, color="0.7", lw=0.8)
    ax.axvline(0, color="0.7", lw=0.8)
    ax.set_xlabel("tip deflection in x [mm]")
    ax.set_ylabel("tip force in x [mN per mm of depth]")
    ax.legend()
    ax.set_title("tip load-deflection (2D, plane strain)")
    _save(fig, Path(path))


def plot_blocked(a: Assessment, path: str | os.PathLike) -> None:
    """Blocked force against temperature [mN per mm of depth, K]."""
    fig = Figure(figsize=(5.5, 4))
    ax = fig.add_subplot()
    T = [b["temperature_K"] for b in a.blocked]
    F = [1e3 * b["force_x_N_per_mm"] for b in a.blocked]
    ax.plot(T, F, "o-")
    ax.set_xlabel("temperature T [K]")
    ax.set_ylabel("blocked force F_x [mN per mm of depth]")
    ax.set_title("force of the stop that holds the tip")
    _save(fig, Path(path))


def plot_confinement(a: Assessment, path: str | os.PathLike) -> None:
    """Contact pressures on the membrane against the gel's confined swelling pressure [kPa, log]."""
    v = a.values
    names = ["contact, mean", "contact, max", "swelling pressure\n(held as prepared)"]
    vals = [v["contact_pressure_mean"], v["contact_pressure_max"], v["swelling_pressure"]]
    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    ax.bar(names, [max(1e3 * x, 1e-6) for x in vals], color=["C0", "C0", "C3"])
    ax.set_yscale("log")
    ax.set_ylabel("pressure [kPa]")
    ax.set_title(f"confinement at {a.design.stimulus.temperature:g} K")
    _save(fig, Path(path))


def _f(x, digits: int = 3) -> str:
    return "n/a" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f"{x:.{digits}g}"


def conclusion(a: Assessment) -> list[str]:
    """Plain-words statements that follow from the numbers (one per line)."""
    v = a.values
    lines = []
    r = v["stiffness_ratio"]
    lo, hi = REPORTED_GAIN
    if r is None:
        lines.append("The actuated state is not a stable equilibrium (its tip stiffness is not positive): "
                     "no stiffness ratio.")
    else:
        where = "below" if r < lo else ("within" if r <= hi else "above")
        lines.append(f"Actuation stiffens the actuator {r:.2g}x (tangent bending stiffness at the tip), {where} the "
                     f"{lo:g}x-{hi:g}x gain the authors' later work reports.")
    if v.get("stiffness_ratio_vacuum") is not None and r is not None:
        rv = v["stiffness_ratio_vacuum"]
        held = v["vacuum_pressure_kPa"]
        better = "more" if r > rv else "less"
        note = "" if v["vacuum_converged"] else f" (vacuum: {v['vacuum_message']})"
        lines.append(f"Vacuum jamming of the same chamber at {held:.3g} kPa stiffens it {rv:.2g}x: "
                     f"the active particles stiffen it {better} than this vacuum baseline{note}.")
    share = v["contact_pressure_mean"] / v["swelling_pressure"] if v["swelling_pressure"] > 0 else None
    if share is not None:
        holds = share >= HOLDS_SHARE
        lines.append(f"The wall presses on the particles with {1e3 * v['contact_pressure_mean']:.3g} kPa on average "
                     f"({1e3 * v['contact_pressure_max']:.3g} kPa at most) against the {1e3 * v['swelling_pressure']:.4g} kPa "
                     f"the gel would exert if held at its as-prepared size: {share:.2g} of it. "
                     + ("The wall holds the gel." if holds else
                        f"The wall does not hold the gel: the particles swell almost freely (mean swelling ratio "
                        f"{v['mean_swelling_ratio']:.3g}); the contact pressure is what the membrane gives, not what the "
                        f"gel could exert."))
    if v.get("particle_swelling_t90_s") is not None:
        line = (f"Speed: a free particle of this swollen size makes 90% of its swelling in "
                f"{duration(v['particle_swelling_t90_s'])} (tau = {duration(v['particle_time_constant_s'])} at "
                f"D = {a.design.hydrogel.diffusivity:g} mm^2/s); time falls with the square of the bead's size.")
        if v.get("angle_t90_s") is not None:
            line += f" This run's angle made 90% of its change in {duration(v['angle_t90_s'])}."
        lines.append(line)
    if a.blocked:
        F = [(b["temperature_K"], b["force_x_N_per_mm"]) for b in a.blocked]
        lines.append("Blocked force: " + ", ".join(f"{1e3 * f:.3g} mN/mm at {T:g} K" for T, f in F)
                     + " (per mm of depth).")
    return lines


def write_report(a: Assessment, out: str | os.PathLike) -> Path:
    """Write an assessment's report and its files into a folder.

    The files are report.md, report.html (the same with its figures inlined: one file that opens
    offline), assessment.json, design.toml and the figures (load_deflection.png, blocked_force.png,
    confinement.png).

    Parameters
    ----------
    a : Assessment
        The assessment.
    out : str or os.PathLike
        The folder (made if missing).

    Returns
    -------
    Path
        The report's path.
    """
    out = make_folder(out)
    v = a.values
    plot_curves(a, out / "load_deflection.png")
    plot_confinement(a, out / "confinement.png")
    if a.blocked:
        plot_blocked(a, out / "blocked_force.png")
    write_text_atomic(out / "assessment.json", json.dumps(a.summary(), indent=1, allow_nan=False) + "\n")
    write_text_atomic(out / "design.toml", design_to_toml(a.design))
    d = a.design
    rows = [("bending angle", _f(v["bending_angle_deg"]), "deg"),
            ("tip displacement (x, z)", f"{_f(v['tip_dx_mm'])}, {_f(v['tip_dz_mm'])}", "mm"),
            ("stiffness, unactuated", _f(v["stiffness_unactuated"]), "N/mm per mm"),
            ("stiffness, actuated", _f(v["stiffness_actuated"]), "N/mm per mm"),
            ("**stiffness ratio**", _f(v["stiffness_ratio"]), "-"),
            ("secant stiffness at +-max force, unactuated", f"{_f(v['secant_unactuated_plus'])}, {_f(v['secant_unactuated_minus'])}", "N/mm per mm"),
            ("secant stiffness at +-max force, actuated", f"{_f(v['secant_actuated_plus'])}, {_f(v['secant_actuated_minus'])}", "N/mm per mm"),
            ("max tip force of the curves", _f(v["max_force"]), "N/mm"),
            ("contact pressure on the membrane, mean / max", f"{_f(1e3 * v['contact_pressure_mean'])} / {_f(1e3 * v['contact_pressure_max'])}", "kPa"),
            ("confined swelling pressure of the gel", _f(1e3 * v["swelling_pressure"], 4), "kPa"),
            ("mean swelling ratio of the particles", _f(v["mean_swelling_ratio"]), "-"),
            ("particle swelling time t90 (tau)", f"{duration(v.get('particle_swelling_t90_s'))} "
             f"({duration(v.get('particle_time_constant_s'))})", "-")]
    lines = [f"# hydrojam assessment: are these active particles suitable for jamming?", "",
             f"Design: {d.particle_layers} layer{'s' if d.particle_layers != 1 else ''} of {d.particle_diameter:g} mm particles, membrane G = "
             f"{d.membrane.shear_modulus:g} MPa, t0 = {d.side_wall_thickness:g} mm, strain-limit layer h = "
             f"{d.strain_limit_thickness:g} mm, actuated at T = {d.stimulus.temperature:g} K (2D, plane strain: "
             f"forces per mm of depth). Wall time {v['wall_time_s']:.0f} s.", "", "## Conclusion", ""]
    lines += [f"- {c}" for c in conclusion(a)]
    lines += ["", "## Numbers", "", "| quantity | value | unit |", "|---|---|---|"]
    lines += [f"| {n} | {x} | {u} |" for n, x, u in rows]
    if "stiffness_ratio_vacuum" in v:
        lines += ["", "## Active particles against vacuum jamming", "",
                  "| | active particles | vacuum jamming |", "|---|---|---|",
                  f"| jammed by | T = {d.stimulus.temperature:g} K | {_f(v['vacuum_pressure_kPa'])} kPa "
                  f"(target {v['vacuum_pressure_target_kPa']:g}) |",
                  f"| stiffness before [N/mm per mm] | {_f(v['stiffness_unactuated'])} | {_f(v['stiffness_vacuum_unjammed'])} |",
                  f"| stiffness jammed [N/mm per mm] | {_f(v['stiffness_actuated'])} | {_f(v['stiffness_vacuum'])} |",
                  f"| **ratio** | {_f(v['stiffness_ratio'])} | {_f(v['stiffness_ratio_vacuum'])} |",
                  f"| contact pressure mean / max [kPa] | {_f(1e3 * v['contact_pressure_mean'])} / "
                  f"{_f(1e3 * v['contact_pressure_max'])} | {_f(1e3 * v['vacuum_contact_pressure_mean'])} / "
                  f"{_f(1e3 * v['vacuum_contact_pressure_max'])} |"]
        if not v["vacuum_converged"]:
            lines += ["", f"Vacuum: {v['vacuum_message']}."]
    if a.blocked:
        lines += ["", "## Blocked force", "", "| T [K] | blocked force F_x [mN/mm] | stop's give [mm] | "
                  "swelling pressure [MPa] | converged |", "|---|---|---|---|---|"]
        lines += [f"| {b['temperature_K']:g} | {_f(1e3 * b['force_x_N_per_mm'])} | {_f(b['give_mm'])} | "
                  f"{_f(b['swelling_pressure_MPa'])} | {b['converged']} |" for b in a.blocked]
        lines += ["", "![blocked force](blocked_force.png)"]
    lines += ["", "## Figures", "", "![load-deflection](load_deflection.png)", "", "![confinement](confinement.png)", "",
              "Definitions, units and the verification: docs/assess.md."]
    report = out / "report.md"
    write_text_atomic(report, "\n".join(lines) + "\n")
    write_text_atomic(out / "report.html", markdown_page("\n".join(lines) + "\n", out, "hydrojam assessment"))
    return report
