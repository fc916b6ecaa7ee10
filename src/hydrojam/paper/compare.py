"""The 2D-against-3D table of the paper's Section IV study: the same designs run in 2D plane
strain (particles are cylinders) and in 3D (spheres, the half model), per point θ, δx and δz side
by side, and what changes and why in words.

The 2D results are a 2D reproduce folder of the same kind (quick or full), read with
:func:`read_2d_results` (``hydrojam reproduce --dimension 3 --compare-2d OUT2D``). The "why" is a
hypothesis from the two models' differences, with the free-swelling stretches of a sphere and of
a plane-strain cylinder at the point's temperature computed from the design's gel
(:mod:`hydrojam.materials.swelling`). Units: mm, K, degrees.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from hydrojam._io import read_toml
from hydrojam.actuator.design import Design
from hydrojam.paper._rows import cell_pm, fmt_param, number, partial_runs, point_status, rows_of, without_result
from hydrojam.paper.study import paper_sweeps, reproduce_command, study_name
from hydrojam.study.cache import PointStatus
from hydrojam.study.table import SweepTable

__all__ = [
    "COMPARE_OPTION",
    "CompareError",
    "Change",
    "PointComparison",
    "REASONS",
    "SAME_ANGLE_TOL",
    "compare_points",
    "comparison_lines",
    "free_swelling_stretches",
    "read_2d_results",
]

#: the reproduce command's option naming the 2D results
COMPARE_OPTION = "--compare-2d"
#: "bends about as much": |θ3D − θ2D| within this share of the larger |θ| (the claims' ANGLE_TOL)
SAME_ANGLE_TOL = 0.05
#: below this |θ| [deg] in both models the actuator counts as straight
STRAIGHT_DEG = 2.0

_BASE = {"stimulus.temperature": 275.0, "particle_layers": 5.0, "strain_limit_thickness": 8.0}


class CompareError(ValueError):
    """The 2D results cannot be used: one line naming the folder and what is wrong."""


def read_2d_results(path: str | os.PathLike, quick: bool) -> SweepTable:
    """The results table of the 2D study of the same kind (quick or full) in folder ``path``
    (``OUT2D/results.csv`` of ``hydrojam reproduce [--quick] -o OUT2D``). CompareError, one line,
    when the folder is missing, holds another study (a 3D one, the other kind) or has no table."""
    path = Path(path)
    want = study_name(quick, 2)
    rerun = f"`{reproduce_command(quick)} -o {path}`"
    if not path.is_dir():
        raise CompareError(f"{path}: no such folder (the 2D results: {rerun})")
    if not (path / "study.toml").is_file():
        raise CompareError(f"{path}: no study.toml, not a reproduce output folder (the 2D results: {rerun})")
    name = read_toml(path / "study.toml", "study", CompareError).get("name")
    if name != want:
        raise CompareError(f"{path}: holds the study {name!r}, not {want!r} (the 2D study of the same "
                           f"{'quick' if quick else 'full'} kind: {rerun})")
    if not (path / "results.csv").is_file():
        raise CompareError(f"{path}: no results.csv yet (finish the 2D run: {rerun})")
    try:
        return SweepTable.read(path)
    except (OSError, ValueError, StopIteration) as err:
        raise CompareError(f"{path / 'results.csv'}: cannot read the table ({type(err).__name__}: {err})") from None


def free_swelling_stretches(base: Design, temperature: float) -> tuple[float, float]:
    """(cylinder, sphere): the free-swelling stretch from the as-prepared state at ``temperature``
    [K] and the base design's chemical potential, of a plane-strain cylinder (its axis held at the
    as-prepared length) and of a free sphere; the diameter grows by these factors."""
    from hydrojam.materials.swelling import constrained_swelling, free_swelling

    params, mu = base.hydrogel.params(), base.stimulus.mu
    cylinder = constrained_swelling(params, mu, temperature, (params.lambda0,)).stretch_rel
    sphere = free_swelling(params, mu, temperature).stretch_rel
    return float(cylinder), float(sphere)


@dataclass(frozen=True)
class Change:
    """One part of what changes from 2D to 3D at a point: ``short``, what the numbers show (for
    the table's cell); ``reason``, the key of its hypothesis in :data:`REASONS` (None: none);
    ``text``, the two in one sentence."""

    short: str
    reason: str | None
    text: str


@dataclass(frozen=True)
class PointComparison:
    """One design in both models, 2D and 3D.

    Parameters
    ----------
    label : str
        The point's label.
    temperature : float or None
        Its temperature [K].
    row_2d, row_3d : dict or None
        Its rows of the 2D and the 3D table (None: not run).
    stretches : tuple of float or None
        The free-swelling stretches (cylinder, sphere) from the as-prepared state at its
        temperature [-].
    change : str
        The change from 2D to 3D in words (whole sentences).
    parts : tuple of Change, optional
        Its parts: what shows, and the reason's key.
    """

    label: str
    temperature: float | None
    row_2d: dict | None
    row_3d: dict | None
    stretches: tuple[float, float] | None
    change: str
    parts: tuple[Change, ...] = ()


def _field(design: Design, path: str):
    value = design
    for name in path.split("."):
        value = getattr(value, name)
    return value


def _point(r: dict, base: Design) -> tuple:
    """The design's swept values (T, PL, h), rounded against representation noise; a field the
    row's table has no column for (its study varied it nowhere) is the base design's."""
    values = (number(r.get(f)) if f in r else number(_field(base, f)) for f in _BASE)
    return tuple(None if v is None else round(v, 9) for v in values)


def _length(base: Design, point: tuple) -> float:
    """The actuator length L [mm] of the point's design (the base design with its swept values)."""
    layers = dict(zip(_BASE, point)).get("particle_layers")
    update = {} if layers is None else {"particle_layers": int(layers)}
    return float(base.model_copy(update=update).length)


def _label(sweep, point: tuple) -> str:
    values = dict(zip(_BASE, point))
    if all(values[f] == v for f, v in _BASE.items()):
        return "base: " + ", ".join(f"{sw.symbol} {fmt_param(values[sw.field], sw.unit)}" for sw in paper_sweeps(2))
    return f"{sweep.symbol} = {fmt_param(values[sweep.field], sweep.unit)}"


def _usable(r: dict | None) -> bool:
    return r is not None and not without_result(r) and number(r.get("bending_angle_deg")) is not None


#: the hypotheses behind the parts of a change (:class:`Change`), each said once below the table
REASONS = {
    "more": "the spheres, held across y by the chamber's depth and the membrane's hoop stretch, stay a column "
            "and push along its axis, where the cylinders (no out-of-plane stretch to resist them) balloon the "
            "membrane and pack into a cluster",
    "less": "less swelling to push with (a sphere's volume change goes into three directions, a plane-strain "
            "cylinder's into two), and the membrane's hoop stretch round each sphere resists it",
    **{f"lift {up}": "an actuator of length L bent into a circular arc through θ lifts its free end by "
                     f"L (1 − sin θ/θ): the {up} tip rises within that lift, so the bend outruns the {up} "
                     f"chamber's lengthening, where the {down} chamber lengthens more than its bend lifts it"
       for up, down in (("3D", "2D"), ("2D", "3D"))},
}


def _tip_up(up: str, down: str, theta: float, dz: float, length: float | None) -> Change:
    """Why the ``up`` model's tip rises (δz [mm] > 0) where the ``down`` one's falls. Bending
    alone lifts the free end of an actuator of length L [mm] bent by θ [deg] into a circular arc
    by L (1 - sin θ / θ); a rise within that lift is the bend outrunning the chamber's
    lengthening, a rise beyond it a chamber that shortens."""
    if length is not None and theta:
        rad = math.radians(abs(theta))
        lift = length * (1.0 - math.sin(rad) / rad)
        if dz <= lift:
            return Change(f"the {up} tip rises (δz > 0) within its bend's lift ({lift:.0f} mm at {abs(theta):.0f}°)",
                          f"lift {up}",
                          f"the {up} tip rises (δz > 0): bent by {abs(theta):.0f}°, an arc of the actuator's length "
                          f"lifts its end by {lift:.0f} mm, more than the {up} chamber lengthens, where the {down} "
                          "chamber lengthens more than its bend lifts it")
    text = f"the {up} chamber shortens (tip up) where the {down} one bends down"
    return Change(text, None, text)


def _plain(text: str) -> tuple[Change, ...]:
    return (Change(text, None, text),)


def _change(r2: dict | None, r3: dict | None, temperature: float | None,
            stretches: tuple[float, float] | None, length: float | None = None) -> tuple[Change, ...]:
    """What changes from 2D to 3D at one point and why (a hypothesis), as its parts; ``length``:
    the point's actuator length L [mm] (None: unknown)."""
    if r3 is None:
        return _plain("not run in 3D")
    if r2 is None:
        return _plain("not run in 2D")
    for r, dim in ((r2, "2D"), (r3, "3D")):
        if point_status(r) != PointStatus.UNFINISHED and not _usable(r):
            return _plain(f"no comparison: the {dim} point failed ({r.get('error') or 'no result'})")
    for r, dim in ((r2, "2D"), (r3, "3D")):
        if point_status(r) == PointStatus.UNFINISHED and partial_runs(r) is None:
            err = str(r.get("error") or "")
            where = err if err.startswith(("not finished", "not started")) else f"not finished ({err or '?'})"
            return _plain(f"no comparison yet: the {dim} point is {where}")
    t2, t3 = number(r2["bending_angle_deg"]), number(r3["bending_angle_deg"])
    swell = ("" if stretches is None else
             f"a free sphere swells {stretches[1]:.2f}x in diameter at {temperature:g} K, a plane-strain "
             f"cylinder {stretches[0]:.2f}x")
    scale = max(abs(t2), abs(t3))
    if scale < STRAIGHT_DEG:
        text = "both nearly straight" + (f": the gel barely swells ({swell})" if swell else "")
        parts = [Change(text, None, text)]
    else:
        d = t3 - t2
        if abs(d) <= SAME_ANGLE_TOL * scale:
            text = f"bends about as much in 3D (θ {d:+.1f}°)"
            full = text + (f"; the spheres' smaller swelling ({swell}) shows little here" if swell else "")
            parts = [Change(text, None, full)]
        elif abs(t3) < abs(t2):
            short = f"bends less in 3D (θ {d:+.1f}°, {100 * d / abs(t2):+.0f} %" + (f"; {swell})" if swell else ")")
            full = (f"bends less in 3D (θ {d:+.1f}°, {100 * d / abs(t2):+.0f} %): less swelling to push with"
                    + (f" ({swell})" if swell else "") + ", and the membrane's hoop stretch round each sphere resists it")
            parts = [Change(short, "less", full)]
        else:
            short = f"bends more in 3D (θ {d:+.1f}°)"
            parts = [Change(short, "more", f"{short}: {REASONS['more']}")]
    z2, z3 = number(r2.get("tip_dz_mm")), number(r3.get("tip_dz_mm"))
    if z2 is not None and z3 is not None and scale >= STRAIGHT_DEG:
        if z2 > 0 > z3:
            parts.append(_tip_up("2D", "3D", t2, z2, length))
        elif z3 > 0 > z2:
            parts.append(_tip_up("3D", "2D", t3, z3, length))
    for r, dim in ((r2, "2D"), (r3, "3D")):
        if partial_runs(r):
            parts.append(_plain(f"{dim}: {partial_runs(r)} so far")[0])
    late = [dim for r, dim in ((r2, "2D"), (r3, "3D")) if point_status(r) == PointStatus.NOT_CONVERGED]
    if late:
        note = f" ({' and '.join(late)} not converged: an intermediate state)"
        last = parts[-1]
        parts[-1] = Change(last.short + note, last.reason, last.text + note)
    return tuple(parts)


def compare_points(table_3d, table_2d, base: Design) -> list[PointComparison]:
    """The designs of either table with their 2D and 3D rows and the change in words.

    Each design appears once (the base point is shared by the three sweeps), in the sweeps' order
    and by parameter.

    Parameters
    ----------
    table_3d, table_2d : SweepTable or list of dict
        The 3D and the 2D study's results.
    base : Design
        The study's base design (its gel and chemical potential set the swelling stretches).

    Returns
    -------
    list of PointComparison
    """
    rows = []
    for table in (table_2d, table_3d):
        by_point = {}
        for sw in paper_sweeps(2):
            for r in rows_of(table, sw.name):
                by_point.setdefault(_point(r, base), r)
        rows.append(by_point)
    rows2, rows3 = rows
    seen, out, stretch_at = set(), [], {}
    for sw in paper_sweeps(2):
        at = list(_BASE).index(sw.field)
        own = {_point(r, base) for table in (table_3d, table_2d) for r in rows_of(table, sw.name)}
        for point in sorted(own, key=lambda p: (p[at] is None, p[at] or 0.0, [(v is None, v or 0.0) for v in p])):
            if point in seen:
                continue
            seen.add(point)
            r3, r2 = rows3.get(point), rows2.get(point)
            T = point[0]
            if T is not None and T not in stretch_at:
                try:
                    stretch_at[T] = free_swelling_stretches(base, T)
                except (ValueError, ArithmeticError):  # no equilibrium: the text does without
                    stretch_at[T] = None
            st = stretch_at.get(T)
            parts = _change(r2, r3, T, st, _length(base, point))
            out.append(PointComparison(_label(sw, point), T, r2, r3, st, "; ".join(c.text for c in parts), parts))
    return out


def _md(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def comparison_lines(table_3d, table_2d, base: Design, *, quick: bool, out: str | os.PathLike,
                     source: str | os.PathLike | None = None) -> list[str]:
    """The report's section "2D against 3D" as Markdown lines: with ``table_2d`` (a 2D study's
    table, from folder ``source``) the table of :func:`compare_points`; without, how to get it."""
    L = ["## 2D against 3D (the same designs)", ""]
    if table_2d is None:
        return L + [f"*No 2D results given.* To compare, run the 2D study of the same kind "
                    f"(`{reproduce_command(quick)} -o OUT2D`) and rerun this one with `{COMPARE_OPTION} OUT2D` "
                    f"(`{reproduce_command(quick, 3)} -o {out} {COMPARE_OPTION} OUT2D`): its finished points "
                    "are reused, only the report is rewritten.", ""]
    points = compare_points(table_3d, table_2d, base)
    L += [f"The same designs in 2D plane strain (particles are cylinders; the 2D study in `{source}`) and in 3D "
          "(spheres, the half model). δx < 0: toward the strain-limit layer, δz < 0: downward. "
          "The swelling's free stretches are computed from the gel at each point's temperature: a cylinder in "
          "plane strain (its axis held) puts its volume change into two directions, a sphere into three; round a "
          "sphere the membrane is stretched in hoop as well, which a plane-strain membrane is not; and spheres "
          "in a chamber as deep as one particle stay in a column where cylinders can pack into a cluster. "
          "The \"why\" is a hypothesis from these differences, not a finding.", "",
          "| point | θ 2D [deg] | θ 3D [deg] | δx 2D [mm] | δx 3D [mm] | δz 2D [mm] | δz 3D [mm] | "
          "what changes (why: [a], [b], ... below) |",
          "|:---|---:|---:|---:|---:|---:|---:|:---|"]
    mark: dict[str, str] = {}  # reason key -> its letter, in order of first use
    for p in points:
        cells = []
        for key in ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm"):
            for r in (p.row_2d, p.row_3d):
                cells.append("—" if r is None or without_result(r) else cell_pm(r, key))
        said = []
        for c in p.parts or (Change(p.change, None, p.change),):
            if c.reason is not None:
                mark.setdefault(c.reason, "abcdefghijklmnopqrstuvwxyz"[len(mark)])
            said.append(c.short + ("" if c.reason is None else f" [{mark[c.reason]}]"))
        L.append(f"| {_md(p.label)} | " + " | ".join(cells) + f" | {_md('; '.join(said))} |")
    usable = [p for p in points if _usable(p.row_2d) and _usable(p.row_3d)]
    if usable:
        d = [number(p.row_3d["bending_angle_deg"]) - number(p.row_2d["bending_angle_deg"]) for p in usable]
        if len(usable) == 1:
            L += ["", f"At the one point run in both, θ changes by {d[0]:+.1f}° from 2D to 3D."]
        else:
            L += ["", f"Over the {len(usable)} points run in both, θ changes by {min(d):+.1f}° to {max(d):+.1f}° "
                      f"from 2D to 3D (mean {sum(d) / len(d):+.1f}°)."]
    if mark:
        L += ["", "Why (hypotheses):"] + [f"- [{letter}] {REASONS[key]}." for key, letter in mark.items()]
    return L + [""]
