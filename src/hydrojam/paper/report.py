"""``OUT/report.md`` of the paper's Section IV study: what was run, per sweep its figures and a
table of the points, the paper's statements beside hydrojam's numbers with verdicts
(:mod:`hydrojam.paper.claims`), how they are checked, and the model differences. Measured
results of hydrojam (what agrees, by how much, why not) are in docs/reproduce.md, not here.
"""

from __future__ import annotations

import os
from pathlib import Path

from hydrojam._version import __version__
from hydrojam._format import duration
from hydrojam._io import write_text_atomic
from hydrojam.actuator.design import Design
from hydrojam.paper._rows import (cell, cell_pm, fmt_param, number, point_status, rows_of, sorted_by, truthy,
                                  without_result)
from hydrojam.paper.claims import (
    ANGLE_TOL,
    CURLING_MARGIN,
    DISPLACEMENT_TOL,
    DISAGREEMENT_REASONS_3D,
    paper_claims,
    Verdict,
    check_claims,
    check_state_claims,
)
from hydrojam.paper.compare import comparison_lines
from hydrojam.paper.figures import figure_names, state_figure_name
from hydrojam.paper.study import PaperSweep, paper_base, paper_sweeps, reproduce_command
from hydrojam.study.cache import ROW_STATUSES, PointStatus

__all__ = ["MODEL_DIFFERENCES", "MODEL_DIFFERENCES_3D", "model_differences", "write_report"]

#: how hydrojam's model differs from the paper's, as the report lists it (no measured results)
MODEL_DIFFERENCES: tuple[str, ...] = (
    "hydrojam is 2D plane strain: its particles are infinitely long cylinders, the paper's (ABAQUS, 3D) are "
    "spheres. In plane strain all of a particle's swelling goes into the plane, and the membrane (softer than "
    "the gel, with no out-of-plane hoop stretch to resist it) can balloon round the particles: a long chamber "
    "need not stay a column (see the particle-layer shapes).",
    "Contact is the IPC barrier with lagged Coulomb friction (μ = 0.01 by default: swollen hydrogel in water), "
    "the paper's is ABAQUS contact (its friction is not stated). Such slippery particles slide past each other: "
    "a column rearranges (zig-zags) instead of pushing along its axis.",
    "Our membrane and strain-limit layer are compressible neo-Hookean Ecoflex 00-30 (G = 0.023 MPa, ν = 0.45); "
    "the paper does not give its elastomer parameters.",
    "Our load path is quasi-static: every step is tried undamped, a viscous stabilisation comes in only where "
    "a step snaps and is released at that step, so every reported state is an equilibrium; a column of nearly "
    "frictionless particles has many equilibria and round-off selects one, so an end state is path dependent, the more so "
    "the longer the chamber (measured spreads: docs/reproduce.md).",
    "The paper's trends are read from its figures and words (curling judged by eye; the text puts the "
    "strain-limit layer on the left yet says the actuator bends to the right in Sec. IV-A and to the left in "
    "IV-C); one run per point, no uncertainty given.",
)

#: the same for the 3D study (spheres, the half model): the model differences that remain
MODEL_DIFFERENCES_3D: tuple[str, ...] = (
    "hydrojam's 3D model has spheres, like the paper's (ABAQUS, 3D), in a chamber of rectangular cross-section "
    "as deep as one particle plus the clearance. By default it models the half y ≥ 0 with y = 0 a symmetry "
    "plane (u_y = 0 there), so every state is symmetric about that plane: a column buckling out of it is not "
    "modelled (the full model: `--set mesh.symmetry=false`, 6-9x the CPU time).",
    *MODEL_DIFFERENCES[1:],
)


def model_differences(dimension: int) -> tuple[str, ...]:
    """How hydrojam's model differs from the paper's in a study of ``dimension`` 2 or 3."""
    return MODEL_DIFFERENCES_3D if dimension == 3 else MODEL_DIFFERENCES


_cell = cell
_pm = cell_pm


def _md(text: str) -> str:
    """Text made safe for one cell of a Markdown table."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _replicated(rows) -> int:
    """The most replicas of any row (1: single runs)."""
    return int(max((number(r.get("replicas")) or 1.0 for r in rows), default=1.0))


def _points_table(rows: list[dict], sw: PaperSweep) -> list[str]:
    """The Markdown table of one sweep's points, sorted by the parameter (signed δx, δz); with
    replicas, mean ± standard deviation, the replicas used of those run, and summed wall times."""
    head = f"{sw.symbol} [{sw.unit}]" if sw.unit != "layers" else sw.symbol
    if _replicated(rows) > 1:
        lines = [f"| {head} | θ [deg] | δx [mm] | δz [mm] | curling index | replicas used | states | Newton "
                 "iterations (mean) | wall time, summed [s] | status |",
                 "|---:|---:|---:|---:|---:|---:|:---|---:|---:|:---|"]
        for r in sorted_by(rows, sw.field):
            status = point_status(r)
            note = status
            if r.get("error"):
                note += f": {r.get('error')}"
            used = f"{_cell(r.get('replicas_used'), '{:.0f}')}/{_cell(r.get('replicas'), '{:.0f}')}"
            lines.append(
                f"| {fmt_param(number(r.get(sw.field)))} | {_pm(r, 'bending_angle_deg')} | {_pm(r, 'tip_dx_mm')} | "
                f"{_pm(r, 'tip_dz_mm')} | {_pm(r, 'curling_index', '{:.2f}')} | {used} | {_md(r.get('states') or '—')} | "
                f"{_cell(r.get('newton_iterations'), '{:.0f}')} | {_cell(r.get('wall_time_s'), '{:.0f}')} | "
                f"{_md(note)} |")
        return lines
    lines = [f"| {head} | θ [deg] | δx [mm] | δz [mm] | curling index | converged | Newton iterations | "
             "wall time [s] | status |",
             "|---:|---:|---:|---:|---:|:---:|---:|---:|:---|"]
    for r in sorted_by(rows, sw.field):
        status = point_status(r)
        conv = truthy(r.get("converged"))
        if status == PointStatus.UNFINISHED:  # its error says where it stands: "not started", "not finished: ..."
            note = r.get("error") or "not finished"
        else:
            note = str(status) if status != PointStatus.FAILED else f"failed: {r.get('error') or 'no result'}"
        if status == PointStatus.OK and truthy(r.get("stabilisation_released")) is False:
            note += " (stabilisation not released)"
        lines.append(
            f"| {fmt_param(number(r.get(sw.field)))} | {_cell(r.get('bending_angle_deg'))} | "
            f"{_cell(r.get('tip_dx_mm'))} | {_cell(r.get('tip_dz_mm'))} | {_cell(r.get('curling_index'), '{:.2f}')} | "
            f"{'—' if conv is None else ('yes' if conv else 'no')} | {_cell(r.get('newton_iterations'), '{:.0f}')} | "
            f"{_cell(r.get('wall_time_s'), '{:.0f}')} | {_md(note)} |")
    return lines


def _states_lines(table, states: dict, sweeps, results) -> list[str]:
    """The report's section on states: each point's runs by state with θ per state, and every
    claim's verdict on each state's runs alone (:func:`hydrojam.study.table.state_tables`)."""
    L = ["## States", "",
         "A point's replicas can reach distinct equilibria: the column stays one **arc**, or it **folds** (a "
         "layer of particles beside the one before it instead of beyond it; the metric `column_folds`, "
         "docs/replicas.md). A mean over both describes neither, so each state is given apart: its runs and "
         "θ (mean ± standard deviation over its runs), and below, every statement checked on each state's "
         "runs alone, over the points where the state occurs (a summary ending \"checked on the points run, a to b\" "
         "names the part of the paper's range that state covers).", ""]
    names = list(states)
    L += ["| sweep | point | " + " | ".join(f"{n}: runs, θ [deg]" for n in names) + " |",
          "|---|---:|" + "---:|" * len(names)]
    for sw in sweeps:
        by_state = {n: {r.get("point"): r for r in rows_of(t, sw.name)} for n, t in states.items()}
        for r in sorted_by(rows_of(table, sw.name), sw.field):
            cells = []
            for n in names:
                q = by_state[n].get(r.get("point"))
                ok = q is not None and not without_result(q)
                runs = _cell(q.get("replicas_used"), "{:.0f}") if ok and q.get("replicas_used") is not None else ("1" if ok else "0")
                cells.append(f"{runs}, {_pm(q, 'bending_angle_deg')}" if ok else "0")
            L.append(f"| {sw.name} | {fmt_param(number(r.get(sw.field)), sw.unit)} | " + " | ".join(cells) + " |")
    L += ["", "| # | all runs | " + " | ".join(f"{n} runs only" for n in names) + " |",
          "|---|---|" + "---|" * len(names)]
    per_state = {n: {c.claim.id: c for c in check_state_claims(t, _dim_of(sweeps))} for n, t in states.items()}
    for c in results:
        L.append(f"| {c.claim.id} | **{c.verdict}** | "
                 + " | ".join(f"**{per_state[n][c.claim.id].verdict}**: {_md(per_state[n][c.claim.id].summary)}"
                              for n in names) + " |")
    return L + [""]


def _dim_of(sweeps) -> int:
    """The study dimension whose sweeps these are (3 with a 3D-only sweep)."""
    return 3 if any(2 not in sw.dimensions for sw in sweeps) else 2


def _tolerance_text() -> list[str]:
    """How the trend words, tolerances, ranges and verdicts are read, as Markdown bullets."""
    return [
        f"- *rises* (*falls*) from a to b: v(b) − v(a) > tol (v(a) − v(b) > tol); *levels* from a to b: "
        f"|v(b) − v(a)| ≤ tol and the range (max − min) over the points in [a, b] ≤ 2 tol.",
        f"- tol = {ANGLE_TOL:g} × the sweep's largest |θ| for the bending angle, and {DISPLACEMENT_TOL:g} × the "
        f"sweep's largest magnitude for |δx| and |δz| (the tip is more path dependent than the angle; "
        f"docs/reproduce.md).",
        f"- Displacements are compared as magnitudes |δx|, |δz|, as the paper plots them; the signed values are "
        f"in the tables (δx < 0: toward the strain-limit layer, δz < 0: downward).",
        "- With replicas (`--replicas N`) each point's value is the mean over its replicas that converged, and a "
        "part of a check agrees or disagrees only beyond the spread: its distance from the threshold (e.g. "
        "v(b) − v(a) − tol for *rises*) must exceed u = √(s_a² + s_b²), s the points' standard deviations "
        "over the replicas (the spread of one filling against another). Otherwise the part, and the claim "
        f"unless another part disagrees, is *{Verdict.SPREAD}*, with the numbers. A point with one run "
        "measures no spread and takes the largest its sweep measured (\"one run\" after its value); a point "
        "with some of its replicas finished is read with those runs (\"k of n runs\"), and its claims are not "
        "final until it finishes.",
        f"- Curling index: share of the strain-limit layer mid-line's rotation accumulated in the half nearest "
        f"the clamp (0.5 uniform bending, toward 1 curling); the transition check needs the median of PL ≥ 10 "
        f"to exceed that of PL ≤ 9 by {CURLING_MARGIN:g} and the largest rise between neighbouring points "
        f"within PL 8-11.",
        "- A range of the paper (e.g. h from 4 to 10 mm) is checked between the first and the last point run "
        "within it, and the summary says so where they are not the paper's end points. "
        "A part of a check is *undetermined* where such an end point failed or did not converge, or fewer "
        "than two points lie in the range; other unusable points are skipped and named.",
        "- A claim *disagrees* if any part of its check does, else it is *undetermined* if any part is (for want "
        f"of points), else *{Verdict.SPREAD}* if any part is, else it *agrees*. In an interim report "
        "(`--report-only`) every claim of a sweep with a point not finished is *undetermined*, its summary "
        "beginning with what the finished points alone read.",
    ]


def write_report(out: str | os.PathLike, table, quick: bool, wall_time_s: float | None,
                 explanations: dict[str, str] | None = None, *, workers: int | None = None,
                 scheduler: str | None = None, base: Design | None = None, compare_2d=None,
                 compare_source: str | os.PathLike | None = None, computed: int | None = None,
                 ran: bool = True, states: dict | None = None, overrides=()) -> Path:
    """Write ``OUT/report.md`` (atomically) and return its path.

    What was run (quick or full, mesh size, points, workers, wall time, hydrojam version); per
    sweep its figures (``figures/<sweep>_shapes.png``, ``_trends.png``, when written) and a table
    of the points; the claims of PAPER_CLAIMS with hydrojam's numbers and verdicts, the "why" of a
    disagreement; the tolerances and the model differences. A 3D report adds the section "2D
    against 3D" (:func:`hydrojam.paper.compare.comparison_lines`), or says how to get it.

    Parameters
    ----------
    out : str or os.PathLike
        The study's output folder OUT.
    table : SweepTable or list of dict
        The study's results.
    quick : bool
        Whether it is the quick study.
    wall_time_s : float or None
        The run's wall time [s].
    explanations : dict of str to str, optional
        Claim id -> the "why" of a disagreement (default: the claim's ``reason``).
    workers : int, optional
        The local workers used, for the report.
    scheduler : str, optional
        The dask scheduler's address used, for the report.
    base : Design, optional
        The study's base design (default :func:`paper_base`); its dimension makes it the 2D or the
        3D study's report.
    compare_2d : SweepTable, optional
        The 2D study's table of the same kind, for a 3D report.
    compare_source : str or os.PathLike, optional
        The folder ``compare_2d`` was read from.
    computed : int, optional
        How many distinct points this run computed (finished or went on from a checkpoint) rather
        than reused from an earlier run into the same folder.
    ran : bool, optional
        False: the report of a study in progress, written from its finished points without running
        anything (``reproduce(report_only=True)``): its unfinished points are listed as such and
        the report says that it is an interim one.
    states : dict of str to SweepTable, optional
        State -> the table of that state's runs alone (:func:`hydrojam.study.table.state_tables`);
        with two or more, the section "States" gives each point's runs by state and every claim's
        verdict per state.
    overrides : sequence of str, optional
        The model choices the study changed for every point (``--set``), named in the report.

    Returns
    -------
    Path
        ``OUT/report.md``.
    """
    out = Path(out)
    base = base if base is not None else paper_base(quick)
    dim = base.dimension
    results = check_claims(table, dim)
    sweeps = paper_sweeps(dim)
    explanations = {**(DISAGREEMENT_REASONS_3D if dim == 3 else {}), **(explanations or {})}
    all_rows = [r for sw in sweeps for r in rows_of(table, sw.name)]
    by_key = {}
    for r in all_rows:
        by_key.setdefault(r.get("key") or id(r), r)
    n_points = len(by_key)
    compute = sum(number(r.get("wall_time_s")) or 0.0 for r in by_key.values())
    counts = {s: sum(1 for r in by_key.values() if point_status(r) == s) for s in ROW_STATUSES}
    verdicts = {v: sum(1 for c in results if c.verdict == v) for v in Verdict}
    n_replicas = _replicated(all_rows)

    command = reproduce_command(quick, dim, n_replicas, overrides)
    if dim == 3:
        model = (f"3D (particles are spheres; {'the half model y ≥ 0, y = 0 a symmetry plane' if base.mesh.symmetry else 'the full model'}), "
                 f"mesh size {base.mesh_size:g} mm (quadratic tetrahedra)")
    else:
        model = f"2D plane strain (particles are cylinders), mesh size {base.mesh_size:g} mm (quadratic triangles)"
    L = [f"# hydrojam reproduction of Chen, Schott & Jovanova, Section IV (Figs. 6-11){', in 3D' if dim == 3 else ''}",
         ""]
    if n_replicas <= 1:
        # a single run is one sample of a spread: a newcomer's first verdicts must not read as the answer
        L += [f"**Each point is one run: one sample of a spread.** A column of slippery particles has many "
              f"equilibria and round-off picks one, so one run's trend can reverse between neighbouring points, "
              f"and the verdicts below are those of these samples. `{reproduce_command(quick, dim, 4)} -o {out}` "
              "runs 4 replicas of every point (reusing these runs; `--sweep NAME` for some sweeps only) and decides a "
              "statement only beyond their spread (docs/replicas.md).", ""]
    L += ["## What was run", ""]
    L += [f"- Study: **{'quick' if quick else 'full'}{', 3D' if dim == 3 else ''}** "
          f"(`{command}`), hydrojam {__version__}.",
          f"- Base design: the default (PL {base.particle_layers}, h = {base.strain_limit_thickness:g} mm, "
          f"T = {base.stimulus.temperature:g} K, d = {base.particle_diameter:g} mm, "
          f"{'frictionless' if base.friction == 0 else f'friction {base.friction:g}'}), {model}.",
          ]
    if overrides:
        L.append(f"- Model choices changed from the defaults for every point: {', '.join(f'`{o}`' for o in overrides)} "
                 "(a study of its own, beside the default's: docs/reproduce.md, \"Sensitivity\").")
    if n_replicas > 1:
        L.append(f"- Replicas: {n_replicas} per point (`--replicas {n_replicas}`), each with its particle centres "
                 f"jittered by up to {base.replicas.jitter:g} × the clearance from seed {base.replicas.seed} "
                 "(replica 0 as drawn; docs/replicas.md); the tables and figures give the mean ± standard "
                 "deviation over the replicas that converged, and a statement agrees or disagrees only beyond "
                 "the spread.")
    rerun = f"`{command} -o {out}`"
    runs = (f"{n_points} points" if n_replicas <= 1
            else f"{n_points * n_replicas} runs ({n_points} points x {n_replicas} replicas)")
    for sw in sweeps:
        vals = sorted({v for v in (number(r.get(sw.field)) for r in rows_of(table, sw.name)) if v is not None})
        not_run = "" if vals else f" **Not run**: {rerun} adds it, reusing the finished points."
        vals = vals or (sw.quick_values if quick else sw.values)
        L.append(f"- {sw.label}: {', '.join(f'{v:g}' for v in vals)} {'' if sw.unit == 'layers' else sw.unit}"
                 .rstrip() + f" ({sw.figures}).{not_run}")
    L += [f"- {n_points} distinct points (the base point is shared by the temperature, layer and thickness sweeps): {counts[PointStatus.OK]} converged, "
          f"{counts[PointStatus.NOT_CONVERGED]} not converged, {counts[PointStatus.FAILED]} failed"
          + (f", **{counts[PointStatus.UNFINISHED]} not finished**." if counts[PointStatus.UNFINISHED] else "."),
          (f"- Workers: {_workers_text(workers, scheduler)}; "
           f"wall time {'—' if number(wall_time_s) is None else duration(wall_time_s)}"
           + ("" if computed is None else f" (this run: {computed} of the {runs} computed, the others "
                                          "reused from earlier runs into this folder)")
           if ran else "- Nothing was run for this report (`--report-only`): it is written from the points "
                       "finished in this folder so far")
          + f"; compute time summed over points {duration(compute)} (a resumed run reuses finished points).",
          f"- Claims: {verdicts[Verdict.AGREE]} agree, {verdicts[Verdict.DISAGREE]} disagree, "
          f"{verdicts[Verdict.UNDETERMINED]} undetermined"
          + (f", {verdicts[Verdict.SPREAD]} {Verdict.SPREAD}." if n_replicas > 1 else "."), ""]
    if counts[PointStatus.UNFINISHED]:
        one = counts[PointStatus.UNFINISHED] == 1
        L += [f"**An interim report**: {counts[PointStatus.UNFINISHED]} of the {n_points} points "
              + ("is not finished (its row says where it stands); every statement of its sweeps is undetermined "
                 "until it finishes. " if one else
                 "are not finished (their rows say where each stands); every statement of their sweeps is "
                 "undetermined until they finish. ")
              + f"{rerun} runs {'it' if one else 'them'} on from {'its checkpoint' if one else 'their checkpoints'} "
              "and rewrites this report.", ""]
    for sw in sweeps:
        rows = rows_of(table, sw.name)
        L += [f"## {sw.label[0].upper() + sw.label[1:]} (paper {sw.figures})", ""]
        for name, what in zip(figure_names(sw), ("Deformed shapes", "Trends")):
            if (out / name).is_file():
                L += [f"![{what}: {sw.label}]({name})", ""]
            else:
                L += [f"*{what} figure not written ({name}).*", ""]
        for state in (states or {}) if len(states or {}) > 1 else ():
            name = state_figure_name(sw, state)
            if (out / name).is_file():
                L += [f"![Deformed shapes, one run in the state {state} a point: {sw.label}]({name})", ""]
        L += (_points_table(rows, sw) if rows else [f"*No points of this sweep in the table: not run ({rerun} adds it).*"]) + [""]
    L += ["## The paper's statements and hydrojam", ""]
    L += ["| # | paper (Fig.) | hydrojam computed | verdict | why (for disagree) |", "|---|---|---|---|---|"]
    for c in results:
        reason = explanations.get(c.claim.id, c.claim.reason) if c.verdict == Verdict.DISAGREE else ""
        L.append(f"| {c.claim.id} | {_md(c.claim.paper)} ({c.claim.figure}) | {_md(c.summary)} | "
                 f"**{c.verdict}** | {_md(reason)} |")
    L += ["", "The reasons given for a disagreement are hypotheses from the model differences below, not findings.", ""]
    if states and len(states) > 1:
        L += _states_lines(table, states, sweeps, results)
    L += ["### How each statement is checked", ""]
    L += [f"- **{c.id}**: {c.rule}." for c in paper_claims(dim)]
    L += [""] + _tolerance_text() + [""]
    if dim == 3:
        L += comparison_lines(table, compare_2d, base, quick=quick, out=out, source=compare_source)
    L += ["## Model differences", ""]
    L += [f"- {text}" for text in model_differences(dim)] + [""]
    L += ["## The title question", "",
          "Section IV says how far the actuator bends; whether its particles are good for jamming (how "
          "much stiffer the actuator gets, the force it holds, vacuum jamming of the same chamber, whether "
          "the membrane confines the gel, how fast it actuates) is answered for the default design by "
          f"`{ASSESS_COMMAND}` (docs/assess.md, with the figures measured on it).", ""]
    text = "\n".join(L)
    path = out / "report.md"
    write_text_atomic(path, text)
    return path


#: the command that answers the paper's title question for the default design
ASSESS_COMMAND = "hydrojam init design.toml && hydrojam assess design.toml -o assess"


def _workers_text(workers: int | None, scheduler: str | None) -> str:
    """Who ran the points, in words."""
    if scheduler:
        return f"the dask scheduler at {scheduler}"
    return f"{workers} local" if workers is not None else "local, one per CPU (default)"


