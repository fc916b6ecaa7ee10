"""The assessment's report (``hydrojam assess``): report.md, assessment.json, the figures and
actuated.vtu (the contact pressure on the membrane as a surface field), written atomically
(docs/assess.md). The answer is worded from the numbers alone."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from matplotlib.figure import Figure

from hydrojam._format import duration
from hydrojam._html import markdown_page
from hydrojam._io import atomic_path, make_folder, write_text_atomic
from hydrojam.actuator.design import design_to_toml
from hydrojam.assess.assessment import Assessment

#: bending-stiffness gains the authors' later work reports for active particle jamming
REPORTED_GAIN = (9.0, 30.0)

#: the authors' later numbers the report sets its own against: (quantity, their value, the key of
#: ours, why they differ)
AUTHORS = (
    ("bending angle", "up to 128 deg, rising with the number of sphere layers (Soft Robotics, "
     "doi 10.1089/soro.2023.0185)", "bending_angle_deg",
     "their chambers are longer and their beads other materials; the angle here is one design's"),
    ("bending stiffness gain", "30x with embedded strips (Soft Robotics, doi 10.1089/soro.2023.0185)",
     "stiffness_ratio", "their strips lock the jammed column to the wall; none are modelled here"),
    ("bending angle, coupled DEM-FEM model", "up to 138 deg (J. Mech. Robot. 15(5), 2023, doi 10.1115/1.4062647)",
     "bending_angle_deg", "their DEM particles are rigid spheres with friction; here they are swelling gel continua"),
    ("stiffness against a pneumatic actuator", "up to 9x (J. Mech. Robot. 15(5), 2023, doi 10.1115/1.4062647)",
     "stiffness_active_over_pneumatic",
     "their pneumatic actuator is their own design and their particles stiffer; here it is the same chamber, empty"),
)
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
    scale = 1.0 if a.three_d else 1e3
    for name, c in a.curves.items():
        ax.plot(c.deflections, scale * c.forces, "o-", label=labels.get(name, name))
    ax.axhline(0, color="0.7", lw=0.8)
    ax.axvline(0, color="0.7", lw=0.8)
    ax.set_xlabel("tip deflection in x [mm]")
    ax.set_ylabel("tip force in x [N, whole actuator]" if a.three_d else "tip force in x [mN per mm of depth]")
    ax.legend()
    ax.set_title("tip load-deflection (3D)" if a.three_d else "tip load-deflection (2D, plane strain)")
    _save(fig, Path(path))


def plot_blocked(a: Assessment, path: str | os.PathLike) -> None:
    """Blocked force against temperature [N (3D) or mN per mm of depth (2D), K]."""
    fig = Figure(figsize=(5.5, 4))
    ax = fig.add_subplot()
    scale = 1.0 if a.three_d else 1e3
    T = [b["temperature_K"] for b in a.blocked]
    F = [None if b["force_x"] is None else scale * b["force_x"] for b in a.blocked]
    ax.plot(T, F, "o-")
    ax.set_xlabel("temperature T [K]")
    ax.set_ylabel("blocked force F_x [N, whole actuator]" if a.three_d else "blocked force F_x [mN per mm of depth]")
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


def units_line(three_d: bool) -> str:
    """The one line that says what the forces and stiffnesses are."""
    if three_d:
        return ("3D: every force is in N and every stiffness in N/mm for the whole actuator, twice the half "
                "model's under symmetric loads.")
    return ("2D (plane strain): every force is per mm of depth [N/mm] and every stiffness [N/mm per mm of "
            "depth]; the 3D actuator's are not these times its depth (cylinders are not spheres).")


def force_text(x, three_d: bool) -> str:
    """A force with its unit: N (3D, whole actuator) or mN per mm of depth (2D)."""
    if x is None:
        return "n/a"
    return f"{_f(x)} N" if three_d else f"{_f(1e3 * x)} mN/mm"


def answer(v: dict, design, blocked: list[dict], three_d: bool) -> list[str]:
    """The answer in plain words, one statement per line, worded from the numbers ``v`` (an
    assessment's values, or the replicas' means) alone: how stiff, how strong and how fast,
    against vacuum and pneumatic, whether the wall holds the gel, and what a designer would change."""
    lines = []
    r = v.get("stiffness_ratio")
    lo, hi = REPORTED_GAIN
    su = "N/mm" if three_d else "N/mm per mm of depth"
    if r is None:
        lines.append("The actuated state is not a stable equilibrium (its tip stiffness is not positive): "
                     "no stiffness ratio.")
    else:
        where = "below" if r < lo else ("within" if r <= hi else "above")
        lines.append(f"How stiff: actuation stiffens the actuator {r:.2g}x (tangent bending stiffness at the tip, "
                     f"{_f(v.get('stiffness_unactuated'))} to {_f(v.get('stiffness_actuated'))} {su}), {where} the "
                     f"{lo:g}x-{hi:g}x gain the authors' later work reports.")
    if v.get("stiffness_ratio_vacuum") is not None and r is not None:
        rv = v["stiffness_ratio_vacuum"]
        held = v.get("vacuum_pressure_kPa")
        better = "more" if r > rv else "less"
        note = "" if v.get("vacuum_converged", True) else f" (vacuum: {v.get('vacuum_message')})"
        lines.append(f"Against vacuum: jamming the same chamber's particles (passive, not swelling) at {_f(held)} kPa "
                     f"stiffens it {rv:.2g}x: the active particles stiffen it {better} than this vacuum baseline{note}.")
    kp = v.get("stiffness_active_over_pneumatic")
    if kp is not None and v.get("pneumatic_converged") is False:
        lines.append(f"Against pneumatic: the same chamber, empty, does not bend as far under pressure: "
                     f"{v.get('pneumatic_message')}. At the largest pressure it held ({_f(v.get('pneumatic_pressure_kPa'))} "
                     f"kPa, {_f(v.get('pneumatic_angle_deg'))} deg) its tip stiffness is {_f(v.get('stiffness_pneumatic'))} "
                     f"{su}: the active-particle actuator is {kp:.2g}x as stiff (the authors report up to 9x).")
    elif kp is not None:
        lines.append(f"Against pneumatic: the same chamber, empty, bends as far ({_f(v.get('pneumatic_angle_deg'))} deg) "
                     f"at {_f(v.get('pneumatic_pressure_kPa'))} kPa, where its tip stiffness is "
                     f"{_f(v.get('stiffness_pneumatic'))} {su}: the active-particle actuator is {kp:.2g}x as stiff "
                     f"(the authors report up to 9x).")
    elif v.get("pneumatic_message") and v.get("pneumatic_message") != "converged":
        lines.append(f"Against pneumatic: {v['pneumatic_message']}.")
    if blocked:
        F = [(b["temperature_K"], b.get("force_x")) for b in blocked]
        line = "How strong: the blocked force is " + ", ".join(f"{force_text(f, three_d)} at {T:g} K" for T, f in F)
        if v.get("pneumatic_blocked_force") is not None:
            line += (f"; the pneumatic chamber at its pressure pushes the stop with "
                     f"{force_text(v['pneumatic_blocked_force'], three_d)}")
        lines.append(line + ".")
    swelling = v.get("swelling_pressure")
    if swelling and swelling > 0 and v.get("contact_pressure_mean") is not None:
        share = v["contact_pressure_mean"] / swelling
        holds = share >= HOLDS_SHARE
        lines.append(f"The wall presses on the particles with {1e3 * v['contact_pressure_mean']:.3g} kPa on average "
                     f"({1e3 * v['contact_pressure_max']:.3g} kPa at most) against the {1e3 * swelling:.4g} kPa "
                     f"the gel would exert if held at its as-prepared size: {share:.2g} of it. "
                     + ("The wall holds the gel." if holds else
                        f"The wall does not hold the gel: the particles swell almost freely (mean swelling ratio "
                        f"{_f(v.get('mean_swelling_ratio'))}); the contact pressure is what the membrane gives, not "
                        f"what the gel could exert."))
    if v.get("particle_swelling_t90_s") is not None:
        line = (f"How fast: a free particle of this swollen size makes 90% of its swelling in "
                f"{duration(v['particle_swelling_t90_s'])} (tau = {duration(v.get('particle_time_constant_s'))} at "
                f"D = {design.hydrogel.diffusivity:g} mm^2/s); the time falls with the square of the bead's size.")
        if v.get("angle_t90_s") is not None:
            line += f" This run's angle made 90% of its change in {duration(v['angle_t90_s'])}."
        lines.append(line)
    lines.append("What a designer would change: smaller beads for speed (the time goes with the bead size squared; "
                 "docs/kinetics.md, the bead-size study), and a stiffer or thicker membrane for confinement (the "
                 "design map in docs/assess.md), at the cost of bending.")
    return lines


def conclusion(a: Assessment) -> list[str]:
    """Plain-words statements that follow from an assessment's numbers (:func:`answer`)."""
    return answer(a.values, a.design, a.blocked, a.three_d)


def authors_table(v: dict) -> list[str]:
    """Markdown rows: the authors' later numbers against these (:data:`AUTHORS`)."""
    rows = ["| quantity | authors' later work | hydrojam | why they differ |", "|---|---|---|---|"]
    for name, theirs, key, why in AUTHORS:
        ours = v.get(key)
        text = "n/a" if ours is None else (f"{ours:.3g} deg" if key.endswith("_deg") else f"{ours:.2g}x")
        rows.append(f"| {name} | {theirs} | {text} | {why} |")
    return rows


def write_contact_vtu(a: Assessment, path: str | os.PathLike) -> None:
    """The actuated state as a VTU (the whole actuator for a half model), with the point field
    ``contact_pressure`` [MPa]: the particles' pressure on the cavity wall, zero elsewhere."""
    import meshio

    from hydrojam.actuator.results import vtu_mesh

    model = a.model
    nodal = a.fields.get("contact_pressure")
    if model is None or nodal is None or "actuated" not in a.states:
        return
    mesh = vtu_mesh(model, SimpleNamespace(x=a.states["actuated"], s=1.0))
    if len(mesh.points) > len(nodal):  # the half model mirrored: the image's nodes follow, off the plane
        on_plane = np.zeros(len(nodal), dtype=bool)
        on_plane[model.symmetry_nodes] = True
        nodal = np.concatenate([nodal, nodal[~on_plane]])
    mesh.point_data["contact_pressure"] = nodal
    with atomic_path(Path(path)) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")


def write_report(a: Assessment, out: str | os.PathLike) -> Path:
    """Write an assessment's report and its files into a folder.

    The files are report.md, report.html (the same with its figures inlined: one file that opens
    offline), assessment.json, design.toml, actuated.vtu (with the contact pressure on the
    membrane) and the figures (load_deflection.png, blocked_force.png,
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
    write_contact_vtu(a, out / "actuated.vtu")
    write_text_atomic(out / "assessment.json", json.dumps(a.summary(), indent=1, allow_nan=False) + "\n")
    write_text_atomic(out / "design.toml", design_to_toml(a.design))
    d = a.design
    su, fu = a.stiffness_unit, a.force_unit
    rows = [("bending angle", _f(v["bending_angle_deg"]), "deg"),
            ("tip displacement (x, z)", f"{_f(v['tip_dx_mm'])}, {_f(v['tip_dz_mm'])}", "mm"),
            ("stiffness, unactuated", _f(v["stiffness_unactuated"]), su),
            ("stiffness, actuated", _f(v["stiffness_actuated"]), su),
            ("**stiffness ratio**", _f(v["stiffness_ratio"]), "-"),
            ("secant stiffness at +-max force, unactuated", f"{_f(v['secant_unactuated_plus'])}, {_f(v['secant_unactuated_minus'])}", su),
            ("secant stiffness at +-max force, actuated", f"{_f(v['secant_actuated_plus'])}, {_f(v['secant_actuated_minus'])}", su),
            ("max tip force of the curves", _f(v["max_force"]), fu),
            ("contact pressure on the membrane, mean / max", f"{_f(1e3 * v['contact_pressure_mean'])} / {_f(1e3 * v['contact_pressure_max'])}", "kPa"),
            ("confined swelling pressure of the gel", _f(1e3 * v["swelling_pressure"], 4), "kPa"),
            ("mean swelling ratio of the particles", _f(v["mean_swelling_ratio"]), "-"),
            ("particle swelling time t90 (tau)", f"{duration(v.get('particle_swelling_t90_s'))} "
             f"({duration(v.get('particle_time_constant_s'))})", "-")]
    model = "3D, half model" if a.model is not None and getattr(a.model, "half", False) else (
        "3D" if a.three_d else "2D, plane strain")
    lines = ["# hydrojam assessment: are these active particles suitable for jamming?", "",
             f"Design: {d.particle_layers} layer{'s' if d.particle_layers != 1 else ''} of {d.particle_diameter:g} mm particles, membrane G = "
             f"{d.membrane.shear_modulus:g} MPa, t0 = {d.side_wall_thickness:g} mm, strain-limit layer h = "
             f"{d.strain_limit_thickness:g} mm, actuated at T = {d.stimulus.temperature:g} K ({model}, mesh "
             f"{d.mesh_size:g} mm). Wall time {v['wall_time_s']:.0f} s.", "", units_line(a.three_d), "",
             "## The answer", ""]
    lines += [f"- {c}" for c in conclusion(a)]
    lines += ["", "## Against the authors' later numbers", ""] + authors_table(v)
    lines += ["", "## Numbers", "", "| quantity | value | unit |", "|---|---|---|"]
    lines += [f"| {n} | {x} | {u} |" for n, x, u in rows]
    first_T = a.blocked[0]["temperature_K"] if a.blocked else None
    lines += ["", "## Active particles, vacuum and pneumatic", ""] + baselines_table(lambda k: _f(v.get(k)), first_T,
                                                                                    a.three_d)
    for key in ("vacuum", "pneumatic"):
        if v.get(f"{key}_converged") is False:
            lines += ["", f"{key.capitalize()}: {v.get(f'{key}_message')}."]
    if a.blocked:
        lines += ["", "## Blocked force", "", f"| T [K] | blocked force F_x [{fu}] | stop's give [mm] | "
                  "swelling pressure [MPa] | converged |", "|---|---|---|---|---|"]
        lines += [f"| {b['temperature_K']:g} | {_f(b['force_x'])} | {_f(b['give_mm'])} | "
                  f"{_f(b['swelling_pressure_MPa'])} | {b['converged']} |" for b in a.blocked]
        lines += ["", "![blocked force](blocked_force.png)"]
    lines += ["", "## Figures", "", "![load-deflection](load_deflection.png)", "", "![confinement](confinement.png)", "",
              "actuated.vtu: the actuated state with the point field contact_pressure [MPa] on the cavity wall.", "",
              "Definitions, units and the verification: docs/assess.md."]
    report = out / "report.md"
    write_text_atomic(report, "\n".join(lines) + "\n")
    write_text_atomic(out / "report.html", markdown_page("\n".join(lines) + "\n", out, "hydrojam assessment"))
    return report


def baselines_table(cell, first_T: float | None, three_d: bool) -> list[str]:
    """Markdown rows: active particles, vacuum jamming and pneumatic side by side (stiffness
    before and jammed or pressurised, the ratio, the force on a stop, the contact pressure);
    ``cell(key)`` formats the value of an assessment's key (a number, or a mean and its spread)
    and ``first_T`` [K] is the first blocked-force temperature (None: none computed)."""
    su = "N/mm" if three_d else "N/mm per mm"
    fu = "N" if three_d else "N/mm"
    active_force = "n/a" if first_T is None else f"{cell(f'blocked_force_{first_T:g}K')} (at {first_T:g} K)"
    return ["| | active particles | vacuum jamming | pneumatic |", "|---|---|---|---|",
            f"| stiffened by | T = {cell('temperature_K')} K | {cell('vacuum_pressure_kPa')} kPa vacuum | "
            f"{cell('pneumatic_pressure_kPa')} kPa inside, bent to {cell('pneumatic_angle_deg')} deg |",
            f"| stiffness before [{su}] | {cell('stiffness_unactuated')} | {cell('stiffness_vacuum_unjammed')} | "
            f"{cell('stiffness_empty')} (empty) |",
            f"| stiffness after [{su}] | {cell('stiffness_actuated')} | {cell('stiffness_vacuum')} | "
            f"{cell('stiffness_pneumatic')} |",
            f"| **ratio** (after / before) | {cell('stiffness_ratio')} | {cell('stiffness_ratio_vacuum')} | "
            f"{cell('stiffness_ratio_pneumatic')} |",
            f"| active particles' stiffness over this one | 1 | {cell('stiffness_active_over_vacuum')} | "
            f"{cell('stiffness_active_over_pneumatic')} |",
            f"| force on a stop at the tip [{fu}] | {active_force} | none (it holds a shape, it does not move) | "
            f"{cell('pneumatic_blocked_force')} |",
            f"| contact pressure on the membrane, mean / max [kPa] | {cell('contact_pressure_mean_kPa')} / "
            f"{cell('contact_pressure_max_kPa')} | {cell('vacuum_contact_pressure_mean_kPa')} / "
            f"{cell('vacuum_contact_pressure_max_kPa')} | none (empty) |"]


#: a difference of blocked-force means beyond this many standard errors of the difference is a
#: trend; within it, the spread of the replicas covers it
TREND_STANDARD_ERRORS = 2.0

#: the values the replicas' report lists with their spread: (key, label, unit key)
REPLICA_ROWS = (
    ("bending_angle_deg", "bending angle", "deg"), ("stiffness_unactuated", "stiffness, unactuated", "k"),
    ("stiffness_actuated", "stiffness, actuated", "k"), ("stiffness_ratio", "**stiffness ratio**", "-"),
    ("secant_actuated_plus", "secant stiffness at +max force, actuated", "k"),
    ("secant_actuated_minus", "secant stiffness at -max force, actuated", "k"),
    ("stiffness_vacuum", "stiffness, vacuum-jammed", "k"), ("stiffness_ratio_vacuum", "stiffness ratio, vacuum", "-"),
    ("pneumatic_pressure_kPa", "pneumatic pressure to the same angle", "kPa"),
    ("stiffness_pneumatic", "stiffness, pneumatic at that angle", "k"),
    ("stiffness_active_over_pneumatic", "active over pneumatic stiffness", "-"),
    ("pneumatic_blocked_force", "pneumatic blocked force", "F"),
    ("contact_pressure_mean_kPa", "contact pressure on the membrane, mean", "kPa"),
    ("contact_pressure_max_kPa", "contact pressure on the membrane, max", "kPa"),
    ("particle_swelling_t90_s", "particle swelling time t90", "s"),
    ("actuation_newton_iterations", "Newton iterations of the actuation", "-"),
    ("wall_time_s", "wall time of one replica's assessment", "s"),
)


def _pm(sp) -> str:
    if sp is None or sp.mean is None:
        return "n/a"
    return _f(sp.mean) if sp.std is None else f"{_f(sp.mean)} ± {_f(sp.std, 2)}"


def blocked_trend(stats: dict, temperatures) -> str | None:
    """Whether the blocked force's change between the first and the last temperature is beyond
    the replicas' spread (:data:`TREND_STANDARD_ERRORS` standard errors of the difference of
    means), in words; None with fewer than two temperatures or two replicas."""
    if len(temperatures) < 2:
        return None
    a, b = (stats.get(f"blocked_force_{T:g}K") for T in (temperatures[0], temperatures[-1]))
    if a is None or b is None or a.std is None or b.std is None or a.mean is None or b.mean is None:
        return None
    se = math.sqrt(a.std**2 / a.n + b.std**2 / b.n)
    diff = b.mean - a.mean
    times = abs(diff) / se if se > 0 else math.inf
    word = "rises" if diff > 0 else "falls"
    verdict = ("beyond the spread: a trend" if times > TREND_STANDARD_ERRORS
               else "within the spread: not a trend these replicas can tell from the path's scatter")
    return (f"From {temperatures[0]:g} to {temperatures[-1]:g} K the blocked force {word} by {_f(abs(diff))} "
            f"({times:.2g} standard errors of the difference of the means over {a.n} and {b.n} replicas): {verdict}.")


def plot_replica_blocked(stats: dict, temperatures, three_d: bool, path) -> None:
    """Blocked force against temperature: the replicas' mean with its standard deviation, and
    every replica's value."""
    scale = 1.0 if three_d else 1e3
    fig = Figure(figsize=(5.5, 4))
    ax = fig.add_subplot()
    T = list(temperatures)
    sps = [stats.get(f"blocked_force_{t:g}K") for t in T]
    means = [np.nan if s is None or s.mean is None else scale * s.mean for s in sps]
    stds = [0.0 if s is None or s.std is None else scale * s.std for s in sps]
    ax.errorbar(T, means, yerr=stds, fmt="o-", capsize=4, label="mean ± std")
    for t, s in zip(T, sps):
        if s is not None:
            ax.plot([t] * s.n, [scale * x for x in s.values if x is not None], "k.", alpha=0.5)
    ax.set_xlabel("temperature T [K]")
    ax.set_ylabel("blocked force F_x [N, whole actuator]" if three_d else "blocked force F_x [mN per mm of depth]")
    ax.set_title("blocked force over the replicas")
    ax.legend()
    _save(fig, Path(path))


def write_replica_report(r, out: str | os.PathLike) -> Path:
    """Write the replicas' report into ``out``: report.md (the answer from the means, every
    figure with its spread, the baselines side by side, the blocked force against T and whether
    its change is beyond the spread), assessment.json (every value's spread), design.toml and
    blocked_force.png. ``r``: a :class:`~hydrojam.assess.replicas.ReplicaAssessment`."""
    out = make_folder(out)
    d = r.design
    three_d = d.dimension == 3
    stats = r.stats
    means = r.mean()
    for part in ("vacuum", "pneumatic"):  # the answer words a baseline's stop as the replicas report it
        flags = [run["values"].get(f"{part}_converged") for run in r.runs if run.get("values")]
        if any(f is False for f in flags):
            means[f"{part}_converged"] = False
            means[f"{part}_message"] = next(
                (run["values"].get(f"{part}_message") for run in r.runs
                 if run.get("values") and run["values"].get(f"{part}_message")), "it stopped short of its target")
    temps = list(r.loads.temperatures) if r.loads.blocking else []
    blocked = [{"temperature_K": T, "force_x": means.get(f"blocked_force_{T:g}K")} for T in temps]
    write_text_atomic(out / "assessment.json", json.dumps(r.to_json(), indent=1, allow_nan=False) + "\n")
    write_text_atomic(out / "design.toml", design_to_toml(d))
    if temps:
        plot_replica_blocked(stats, temps, three_d, out / "blocked_force.png")
    units = {"k": "N/mm" if three_d else "N/mm per mm", "F": "N" if three_d else "N/mm", "deg": "deg", "kPa": "kPa",
             "s": "s", "-": "-"}
    ok = sum(1 for run in r.runs if run.get("status") == "ok")
    lines = ["# hydrojam assessment over replicas: are these active particles suitable for jamming?", "",
             f"Design: {d.particle_layers} layer{'s' if d.particle_layers != 1 else ''} of {d.particle_diameter:g} mm "
             f"particles, membrane G = {d.membrane.shear_modulus:g} MPa, t0 = {d.side_wall_thickness:g} mm, actuated at "
             f"T = {d.stimulus.temperature:g} K ({'3D, half model' if three_d and d.mesh.symmetry else ('3D' if three_d else '2D, plane strain')}, "
             f"mesh {d.mesh_size:g} mm); {len(r.runs)} replicas (seed {d.replicas.seed}, jitter {d.replicas.jitter:g} x "
             f"clearance), {ok} converged in every part. Wall time {r.wall_time_s:.0f} s (replicas in parallel), "
             f"{r.compute_time_s:.0f} s summed.", "", units_line(three_d),
             "Every figure is the mean ± the standard deviation over the replicas (n - 1).", "", "## The answer", ""]
    lines += [f"- {c}" for c in answer(means, d, blocked, three_d)]
    trend = blocked_trend(stats, temps)
    if trend:
        lines += [f"- {trend}"]
    lines += ["", "## Against the authors' later numbers (replicas' means)", ""] + authors_table(means)
    lines += ["", "## Numbers", "", "| quantity | mean ± std | min | max | n | unit |", "|---|---|---|---|---|---|"]
    for key, label, unit in REPLICA_ROWS:
        sp = stats.get(key)
        if sp is not None and sp.n:
            lines.append(f"| {label} | {_pm(sp)} | {_f(sp.min)} | {_f(sp.max)} | {sp.n} | {units[unit]} |")
    lines += ["", "## Active particles, vacuum and pneumatic", ""]
    lines += baselines_table(lambda k: _pm(stats.get(k)), temps[0] if temps else None, three_d)
    if temps:
        fu = units["F"]
        lines += ["", "## Blocked force", "", f"| T [K] | mean ± std [{fu}] | min | max | n |", "|---|---|---|---|---|"]
        for T in temps:
            sp = stats.get(f"blocked_force_{T:g}K")
            if sp is not None:
                lines.append(f"| {T:g} | {_pm(sp)} | {_f(sp.min)} | {_f(sp.max)} | {sp.n} |")
        lines += ["", "![blocked force](blocked_force.png)"]
    lines += ["", "## Replicas", "", "| replica | status | folder |", "|---|---|---|"]
    lines += [f"| {run['replica']} | {run['status']}{'' if not run.get('error') else ': ' + run['error']} | "
              f"points/{run['key']} |" for run in r.runs]
    lines += ["", "Each replica's own report, figures and actuated.vtu are in its folder. Definitions, units and "
              "the verification: docs/assess.md."]
    report = out / "report.md"
    write_text_atomic(report, "\n".join(lines) + "\n")
    return report
