"""The paper's Section IV study (Chen, Schott & Jovanova, Figs. 6-11): its three sweeps, their
figures, and a report that checks the paper's qualitative statements against hydrojam's numbers.

Three one-parameter sweeps round the default design (PL 5, h 8 mm, 275 K; 2D plane strain):
temperature (Figs. 6-7), particle layers (Figs. 8-9) and strain-limit layer thickness
(Figs. 10-11). :func:`reproduce` runs them with :func:`hydrojam.sweep.run_sweep`, draws the
deformed shapes and the trends of each sweep into ``OUT/figures/`` and writes ``OUT/report.md``.

Each statement of the paper is a :class:`Claim` whose check turns the sweep's rows into a summary
with the numbers and a verdict, "agree", "disagree" or "undetermined" (points missing, failed or
not converged). The trend words are made precise with tolerances relative to the sweep's largest
magnitude of the quantity (module constants, written into the report):

- *rises* (falls) from a to b: v(b) - v(a) > tol (v(a) - v(b) > tol);
- *levels* from a to b: |v(b) - v(a)| <= tol and max - min of v over [a, b] <= 2 tol;

with tol = ANGLE_TOL x max|θ| for the bending angle and DISPLACEMENT_TOL x max|δ| for the tip
displacements, whose path dependence is larger (docs/actuator.md: the tip of the default design is
uncertain by about 10 mm, the angle by a few degrees). Displacements are compared as magnitudes
|δx|, |δz|, as the paper plots them. A range of the paper is checked between the first and last
points run within it (the quick study's h = 4, 8, 12 mm checks "4 to 10 mm" from 4 to 8 mm and
cannot check "10 to 12 mm"). A claim disagrees if any part of its check does, else it is
undetermined if any part is (an end point failed or did not converge, fewer than two points in a
range), else it agrees.

Units: mm, K, degrees.
"""

from __future__ import annotations

import math
import os
import textwrap
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from matplotlib.figure import Figure
import numpy as np  # noqa: E402

from hydrojam._io import atomic_path, write_text_atomic  # noqa: E402
from hydrojam import __version__  # noqa: E402
from hydrojam.actuator.design import Design, apply_overrides, default_design  # noqa: E402
from hydrojam.actuator.plots import _TRI6_SPLIT  # noqa: E402

__all__ = [
    "ANGLE_TOL",
    "CURLING_MARGIN",
    "Claim",
    "ClaimResult",
    "DISAGREEMENT_REASONS",
    "DISPLACEMENT_TOL",
    "LINEAR_R2",
    "PAPER_CLAIMS",
    "PAPER_SWEEPS",
    "PaperSweep",
    "QUICK_MESH_SIZE",
    "check_claims",
    "paper_base",
    "paper_points",
    "paper_study",
    "plot_shapes",
    "plot_trends",
    "reproduce",
    "write_figures",
    "write_report",
]

# ------------------------------------------------------------------------------------------------
# The study

#: mesh size of the quick study [mm]; the design allows at most d/4 = 4 mm
QUICK_MESH_SIZE = 4.0

TEMPERATURES_K = [275.0, 280.0, 285.0, 290.0, 295.0]
PARTICLE_LAYERS = list(range(5, 20))
STRAIN_LIMIT_THICKNESSES_MM = [4.0, 6.0, 8.0, 10.0, 12.0]

QUICK_TEMPERATURES_K = [275.0, 285.0, 295.0]
QUICK_PARTICLE_LAYERS = [5, 7, 9, 11, 15, 19]
QUICK_STRAIN_LIMIT_THICKNESSES_MM = [4.0, 8.0, 12.0]


@dataclass(frozen=True)
class PaperSweep:
    """One sweep of the paper's Section IV: the varied design field and how to label it."""

    name: str  # sweep name, also the figures' file stem
    field: str  # dotted design field varied
    symbol: str  # the paper's symbol
    label: str  # axis label without unit
    unit: str
    figures: str  # the paper's figures
    values: tuple
    quick_values: tuple


PAPER_SWEEPS: tuple[PaperSweep, ...] = (
    PaperSweep("temperature", "stimulus.temperature", "T", "temperature T", "K", "Figs. 6-7",
               tuple(TEMPERATURES_K), tuple(QUICK_TEMPERATURES_K)),
    PaperSweep("particle_layers", "particle_layers", "PL", "particle layers PL", "layers", "Figs. 8-9",
               tuple(PARTICLE_LAYERS), tuple(QUICK_PARTICLE_LAYERS)),
    PaperSweep("strain_limit_thickness", "strain_limit_thickness", "h", "strain-limit layer thickness h", "mm",
               "Figs. 10-11", tuple(STRAIN_LIMIT_THICKNESSES_MM), tuple(QUICK_STRAIN_LIMIT_THICKNESSES_MM)),
)
_BY_NAME = {s.name: s for s in PAPER_SWEEPS}
_BY_FIELD = {s.field: s for s in PAPER_SWEEPS}


def paper_base(quick: bool = False) -> Design:
    """The base design of every sweep: the default (PL 5, h 8 mm, 275 K, 2D); quick: mesh
    size QUICK_MESH_SIZE."""
    base = default_design()
    if quick:
        base = apply_overrides(base, [f"mesh.size={QUICK_MESH_SIZE!r}"])
    return base


def paper_points(quick: bool = False) -> dict[str, dict[str, list]]:
    """Sweep name -> {dotted design field: values}, the paper's points (quick: a subset)."""
    return {s.name: {s.field: list(s.quick_values if quick else s.values)} for s in PAPER_SWEEPS}


def paper_study(quick: bool = False):
    """The Section IV study as a :class:`hydrojam.study.Study` named "paper" ("paper-quick"):
    sweeps "temperature", "particle_layers", "strain_limit_thickness" round :func:`paper_base`.
    The base point (275 K, PL 5, h 8 mm) lies in all three."""
    from hydrojam.study.spec import Study, SweepSpec

    sweeps = [SweepSpec(name=name, vary=vary) for name, vary in paper_points(quick).items()]
    return Study(name="paper-quick" if quick else "paper", base=paper_base(quick), sweeps=sweeps)


# ------------------------------------------------------------------------------------------------
# Reading rows


def _num(v) -> float | None:
    """A finite float or None (None, "", NaN, inf, an unreadable string -> None)."""
    if v is None or isinstance(v, bool):
        return None
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _truthy(v) -> bool | None:
    if v is None or v == "":
        return None
    if isinstance(v, str):
        return v.strip().lower() in ("true", "1", "yes")
    return bool(v)


def _status(row: dict) -> str:
    """"ok", "not_converged" or "failed" (a row without status: from ``converged``)."""
    status = row.get("status")
    if status in ("ok", "not_converged", "failed"):
        if status == "ok" and _truthy(row.get("converged")) is False:
            return "not_converged"
        return status
    conv = _truthy(row.get("converged"))
    return "ok" if conv else ("not_converged" if conv is False else "failed")


def _rows_of(table, sweep: str) -> list[dict]:
    """The rows of one sweep from a SweepTable (``select``), or from a plain list of rows."""
    if hasattr(table, "select"):
        selected = table.select(sweep)
        return list(selected.rows if hasattr(selected, "rows") else selected)
    rows = table.rows if hasattr(table, "rows") else table
    return [r for r in rows if r.get("sweep") == sweep]


def _sorted(rows: Sequence[dict], field: str) -> list[dict]:
    return sorted(rows, key=lambda r: (_num(r.get(field)) is None, _num(r.get(field)) or 0.0))


def _fmt_param(value: float | None, unit: str = "") -> str:
    if value is None:
        return "?"
    text = f"{value:g}"
    return f"{text} {unit}" if unit and unit != "layers" else text


# ------------------------------------------------------------------------------------------------
# Claims

#: tolerance of "rises", "falls" and "levels" for the bending angle, as a share of max |θ| in the sweep
ANGLE_TOL = 0.05
#: the same for |δx| and |δz|, as a share of the sweep's largest magnitude (tip path dependence ~10 mm)
DISPLACEMENT_TOL = 0.10
#: "curling": median curling index of PL >= 10 exceeds that of PL <= 9 by at least this much
CURLING_MARGIN = 0.10
#: "linear trend": coefficient of determination of a straight-line fit at least this
LINEAR_R2 = 0.90


class _Undetermined(Exception):
    """A check cannot decide: points missing, failed or not converged."""


#: one part of a check: (True agree | False disagree | None undetermined, text with the numbers)
_Part = tuple[bool | None, str]


@dataclass(frozen=True)
class _Series:
    """One quantity over a sweep: requested parameter values and the usable values among them."""

    name: str  # e.g. "θ", "|δx|"
    unit: str  # "°", "mm" or "" (curling index)
    requested: list[float]  # parameter values present in the rows, sorted
    values: dict[float, float]  # usable points only
    problems: dict[float, str]  # parameter -> why unusable
    tol: float  # tolerance in the quantity's unit
    p_unit: str  # parameter unit

    def at(self, p: float) -> float:
        if p not in self.values:
            raise _Undetermined(f"{self.name} at {_fmt_param(p, self.p_unit)}: {self.problems.get(p, 'not run')}")
        return self.values[p]

    def segment(self, a: float, b: float, notes: list[str]) -> tuple[float, float]:
        """The first and last points run within the paper's range [a, b]; a range not covered
        exactly is noted, fewer than two points in it is undetermined."""
        inside = [p for p in self.requested if a - 1e-9 <= p <= b + 1e-9]
        pa, pb = _fmt_param(a, self.p_unit), _fmt_param(b, self.p_unit)
        if len(inside) < 2:
            raise _Undetermined(f"fewer than 2 points run within {pa} to {pb}")
        lo, hi = inside[0], inside[-1]
        if (lo, hi) != (a, b):
            note = (f"the paper's {pa} to {pb} checked on the points run, "
                    f"{_fmt_param(lo, self.p_unit)} to {_fmt_param(hi, self.p_unit)}")
            if note not in notes:
                notes.append(note)
        return lo, hi

    def usable(self, a: float = -math.inf, b: float = math.inf) -> list[float]:
        return [p for p in self.requested if a <= p <= b and p in self.values]

    def fmt(self, v: float, signed: bool = False) -> str:
        """A value (or a change, ``signed``) with its unit: "74.2°", "+3.0 mm", "0.61"."""
        if not self.unit:
            return f"{v:+.2f}" if signed else f"{v:.2f}"
        text = f"{v:+.1f}" if signed else f"{v:.1f}"
        return text + "°" if self.unit == "°" else f"{text} {self.unit}"


_NAMES = {"bending_angle_deg": "θ", "tip_dx_mm": "δx", "tip_dz_mm": "δz", "curling_index": "curling index"}


def _series(rows: Sequence[dict], sweep: PaperSweep, key: str, magnitude: bool = False) -> _Series:
    requested: list[float] = []
    values: dict[float, float] = {}
    problems: dict[float, str] = {}
    for row in rows:
        p = _num(row.get(sweep.field))
        if p is None:
            continue
        requested.append(p)
        status, v = _status(row), _num(row.get(key))
        if status == "failed":
            problems[p] = "failed"  # its error is in the report's table of points
        elif status == "not_converged":
            problems[p] = "not converged"
        elif v is None:
            problems[p] = f"no {_NAMES.get(key, key)}"
        elif key == "curling_index" and not 0.0 <= v <= 1.0:
            # the rotation reverses along the actuator (an S shape): neither bending nor curling
            problems[p] = f"curling index {v:.2f} outside [0, 1] (the rotation reverses along the actuator)"
        else:
            values[p] = abs(v) if magnitude else v
    share = {"bending_angle_deg": ANGLE_TOL, "tip_dx_mm": DISPLACEMENT_TOL, "tip_dz_mm": DISPLACEMENT_TOL}.get(key, 0.0)
    scale = max((abs(v) for v in values.values()), default=0.0)
    name = _NAMES.get(key, key)
    unit = {"bending_angle_deg": "°", "tip_dx_mm": "mm", "tip_dz_mm": "mm"}.get(key, "")
    return _Series(name=f"|{name}|" if magnitude else name, unit=unit, requested=sorted(set(requested)),
                   values=values, problems=problems, tol=share * scale, p_unit=sweep.unit)


def _part(fn: Callable[..., tuple[bool, str]], *args) -> _Part:
    """A part of a check, undetermined (None) where its points are missing or unusable."""
    try:
        return fn(*args)
    except _Undetermined as err:
        return None, f"cannot decide: {err}"


def _change(s: _Series, a: float, b: float, sense: str, notes: list[str]) -> tuple[bool, str]:
    """"rises"/"falls" over the paper's range [a, b]: the end-to-end change beyond the tolerance."""
    a, b = s.segment(a, b, notes)
    va, vb = s.at(a), s.at(b)
    d = vb - va
    ok = d > s.tol if sense == "rises" else -d > s.tol
    limit = s.fmt(s.tol if sense == "rises" else -s.tol, signed=True)
    return ok, (f"{s.name} {s.fmt(va)} ({_fmt_param(a, s.p_unit)}) -> {s.fmt(vb)} ({_fmt_param(b, s.p_unit)}): "
                f"{s.fmt(d, signed=True)} [{sense} if beyond {limit}]")


def _levels(s: _Series, a: float, b: float, notes: list[str]) -> tuple[bool, str]:
    """"levels" over [a, b]: end-to-end change within tol and spread (max - min) within 2 tol."""
    a, b = s.segment(a, b, notes)
    va, vb = s.at(a), s.at(b)
    vals = [s.values[p] for p in s.usable(a, b)]
    spread = max(vals) - min(vals)
    d = vb - va
    ok = abs(d) <= s.tol and spread <= 2.0 * s.tol
    return ok, (f"{s.name} {s.fmt(va)} ({_fmt_param(a, s.p_unit)}) -> {s.fmt(vb)} ({_fmt_param(b, s.p_unit)}): "
                f"{s.fmt(d, signed=True)}, spread {s.fmt(spread)} over {len(vals)} points "
                f"[levels if change within ±{s.fmt(s.tol)} and spread within {s.fmt(2 * s.tol)}]")


def _no_step_up(s: _Series) -> tuple[bool, str]:
    """No step between neighbouring usable points rises by more than tol."""
    pts = s.usable()
    if len(pts) < 2:
        raise _Undetermined(f"{s.name}: fewer than 2 usable points")
    ups = [(a, b, s.values[b] - s.values[a]) for a, b in zip(pts, pts[1:]) if s.values[b] - s.values[a] > s.tol]
    if not ups:
        return True, f"{s.name}: no step up beyond {s.fmt(s.tol)} between neighbouring points ({len(pts)} points)"
    return False, f"{s.name} steps up beyond {s.fmt(s.tol)}: " + ", ".join(
        f"{_fmt_param(a, s.p_unit)} -> {_fmt_param(b, s.p_unit)} {s.fmt(d, signed=True)}" for a, b, d in ups)


def _skipped(*series: _Series) -> str:
    """"; skipped <point> (<why>), ..." for the unusable points of the series, or ""."""
    probs: dict[float, str] = {}
    for s in series:
        probs.update(s.problems)
    if not probs:
        return ""
    unit = series[0].p_unit
    return "; skipped " + ", ".join(f"{_fmt_param(p, unit)} ({why})" for p, why in sorted(probs.items()))


def _verdict(parts: list[_Part], notes: list[str], extra: str = "") -> tuple[str, str]:
    """Summary and verdict: disagree if any part disagrees, else undetermined if any part is, else agree."""
    text = "; ".join(t for _, t in parts)
    if notes:
        text += " (" + "; ".join(notes) + ")"
    text += extra
    oks = [ok for ok, _ in parts]
    if any(ok is False for ok in oks):
        return text, "disagree"
    return text, "undetermined" if any(ok is None for ok in oks) or not oks else "agree"


def _check_t_angle(rows):
    """θ falls from 275 to 295 K, and no step between neighbouring temperatures rises by more than tol."""
    s = _series(rows, _BY_NAME["temperature"], "bending_angle_deg")
    notes: list[str] = []
    return _verdict([_part(_change, s, 275.0, 295.0, "falls", notes), _part(_no_step_up, s)], notes, _skipped(s))


def _check_t_displacement(rows):
    """|δx| and |δz| each fall from 275 to 295 K, with no step up by more than tol."""
    notes: list[str] = []
    parts: list[_Part] = []
    series = [_series(rows, _BY_NAME["temperature"], k, magnitude=True) for k in ("tip_dx_mm", "tip_dz_mm")]
    for s in series:
        parts += [_part(_change, s, 275.0, 295.0, "falls", notes), _part(_no_step_up, s)]
    return _verdict(parts, notes, _skipped(*series))


def _linear(s: _Series) -> tuple[bool, str]:
    pts = s.usable()
    if len(pts) < 3:
        raise _Undetermined(f"{s.name}: {len(pts)} usable temperatures, need 3")
    x = np.array(pts)
    y = np.array([s.values[p] for p in pts])
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    if ss_tot <= (1e-9 * max(1.0, float(np.abs(y).max()))) ** 2:
        return False, f"{s.name} constant over T: no trend"
    slope, icpt = np.polyfit(x, y, 1)
    r2 = 1.0 - float(np.sum((y - (slope * x + icpt)) ** 2)) / ss_tot
    return r2 >= LINEAR_R2, (f"{s.name}: slope {slope:+.2f} mm/K, R² {r2:.2f} over {len(pts)} points "
                             f"[linear if R² ≥ {LINEAR_R2:g}]")


def _check_t_linear(rows):
    """For |δx| and |δz| over the usable temperatures (3 or more): R² of a straight-line fit >= LINEAR_R2."""
    series = [_series(rows, _BY_NAME["temperature"], k, magnitude=True) for k in ("tip_dx_mm", "tip_dz_mm")]
    return _verdict([_part(_linear, s) for s in series], [], _skipped(*series))


def _dx_dominant(sx: _Series, sz: _Series, notes: list[str]) -> tuple[bool, str]:
    lo, hi = sx.segment(275.0, 295.0, notes)
    ddx, ddz = sx.at(lo) - sx.at(hi), sz.at(lo) - sz.at(hi)
    return abs(ddx) > abs(ddz), (f"from {_fmt_param(hi, 'K')} to {_fmt_param(lo, 'K')}: |δx| changes by "
                                 f"{ddx:+.1f} mm, |δz| by {ddz:+.1f} mm [agree if |Δ|δx|| > |Δ|δz||]")


def _check_t_dx_dominant(rows):
    """The change of |δx| between 295 and 275 K exceeds that of |δz| in size."""
    sx, sz = (_series(rows, _BY_NAME["temperature"], k, magnitude=True) for k in ("tip_dx_mm", "tip_dz_mm"))
    notes: list[str] = []
    return _verdict([_part(_dx_dominant, sx, sz, notes)], notes)


def _peak_at(s: _Series, p: float) -> tuple[bool, str]:
    """No usable point exceeds the value at p by more than tol."""
    vp = s.at(p)
    top = max(s.usable(), key=s.values.get)
    gap = s.values[top] - vp
    return gap <= s.tol, (f"largest {s.name} {s.fmt(s.values[top])} at {_fmt_param(top, s.p_unit)}, "
                          f"{s.fmt(gap)} above {_fmt_param(p, s.p_unit)} [peak at {_fmt_param(p, s.p_unit)} "
                          f"if within {s.fmt(s.tol)}]")


def _check_pl_angle(rows):
    """θ rises from PL 5 to 9, falls from 9 to 19, and no point exceeds θ(9) by more than tol."""
    s = _series(rows, _BY_NAME["particle_layers"], "bending_angle_deg")
    notes: list[str] = []
    parts = [_part(_change, s, 5, 9, "rises", notes), _part(_change, s, 9, 19, "falls", notes), _part(_peak_at, s, 9)]
    return _verdict(parts, notes, _skipped(s))


def _sides(s: _Series) -> tuple[list[float], list[float]]:
    """Usable points with PL <= 9 and PL >= 10, at least 2 each."""
    pts = s.usable()
    low, high = [p for p in pts if p <= 9], [p for p in pts if p >= 10]
    if len(low) < 2 or len(high) < 2:
        raise _Undetermined(f"need 2 usable points on each side of 9-10 layers, have {len(low)} (≤ 9) and "
                            f"{len(high)} (≥ 10)")
    return low, high


def _curling(s: _Series) -> tuple[bool, str]:
    low, high = _sides(s)
    m_low = float(np.median([s.values[p] for p in low]))
    m_high = float(np.median([s.values[p] for p in high]))
    return m_high - m_low >= CURLING_MARGIN, (
        f"median curling index {m_low:.2f} (PL ≤ 9, {len(low)} points) -> {m_high:.2f} (PL ≥ 10, "
        f"{len(high)} points) [curling if +{CURLING_MARGIN:g} or more]")


def _curling_step(s: _Series) -> tuple[bool, str]:
    low, high = _sides(s)
    pts = low + high
    d, a, b = max((s.values[b] - s.values[a], a, b) for a, b in zip(pts, pts[1:]))
    return d > 0 and a >= 8 and b <= 11, f"largest rise {d:+.2f} from PL {a:g} to {b:g} [transition if within PL 8-11]"


def _check_pl_curling(rows):
    """Median curling index of PL >= 10 minus that of PL <= 9 >= CURLING_MARGIN, and the largest
    rise of the curling index between neighbouring usable points lies in a step within PL 8-11."""
    s = _series(rows, _BY_NAME["particle_layers"], "curling_index")
    values = ", ".join(f"{p:g}: {s.values[p]:.2f}" for p in s.usable())
    return _verdict([_part(_curling, s), _part(_curling_step, s)], [],
                    (f"; curling index by PL {values}" if values else "") + _skipped(s))


def _check_pl_dx(rows):
    """|δx| rises from PL 5 to 9, then levels from 9 to 19."""
    s = _series(rows, _BY_NAME["particle_layers"], "tip_dx_mm", magnitude=True)
    notes: list[str] = []
    return _verdict([_part(_change, s, 5, 9, "rises", notes), _part(_levels, s, 9, 19, notes)], notes, _skipped(s))


def _check_pl_dz(rows):
    """|δz| rises from PL 5 to 7, then falls from 7 to 19."""
    s = _series(rows, _BY_NAME["particle_layers"], "tip_dz_mm", magnitude=True)
    notes: list[str] = []
    return _verdict([_part(_change, s, 5, 7, "rises", notes), _part(_change, s, 7, 19, "falls", notes)], notes,
                    _skipped(s))


def _check_h_angle(rows):
    """θ rises from h 4 to 10 mm, then levels from 10 to 12 mm."""
    s = _series(rows, _BY_NAME["strain_limit_thickness"], "bending_angle_deg")
    notes: list[str] = []
    return _verdict([_part(_change, s, 4.0, 10.0, "rises", notes), _part(_levels, s, 10.0, 12.0, notes)], notes,
                    _skipped(s))


def _check_h_displacement(rows):
    """|δx| and |δz| each rise from h 4 to 10 mm, then fall from 10 to 12 mm."""
    notes: list[str] = []
    parts: list[_Part] = []
    series = [_series(rows, _BY_NAME["strain_limit_thickness"], k, magnitude=True) for k in ("tip_dx_mm", "tip_dz_mm")]
    for s in series:
        parts += [_part(_change, s, 4.0, 10.0, "rises", notes), _part(_change, s, 10.0, 12.0, "falls", notes)]
    return _verdict(parts, notes, _skipped(*series))


@dataclass(frozen=True)
class Claim:
    """One qualitative statement of the paper's Section IV and its check.

    ``check(rows)`` takes the rows of sweep ``sweep`` and returns (summary with the computed
    numbers, verdict "agree" | "disagree" | "undetermined"); ``rule`` says what it tests.
    """

    id: str
    sweep: str
    figure: str
    paper: str
    rule: str
    check: Callable[[Sequence[dict]], tuple[str, str]]


PAPER_CLAIMS: list[Claim] = [
    Claim("T-angle", "temperature", "Fig. 6",
          "the bending angle decreases as the temperature rises from 275 K to 295 K (particles shrink)",
          "θ falls from 275 to 295 K, and no step between neighbouring temperatures rises beyond the tolerance",
          _check_t_angle),
    Claim("T-displacement", "temperature", "Fig. 7",
          "the displacements decrease with increasing temperature",
          "|δx| and |δz| each fall from 275 to 295 K, with no step up beyond the tolerance",
          _check_t_displacement),
    Claim("T-linear", "temperature", "Fig. 7",
          "the displacements ... show a linear trend (in T)",
          f"straight-line fit of |δx| and |δz| against T: R² ≥ {LINEAR_R2:g} each (3 or more points)",
          _check_t_linear),
    Claim("T-dx-dominant", "temperature", "Fig. 7",
          "as the temperature decreases, the change in the horizontal direction is more pronounced",
          "the change of |δx| between 295 and 275 K exceeds that of |δz| in size",
          _check_t_dx_dominant),
    Claim("PL-angle", "particle_layers", "Fig. 8",
          "the bending angle increases from 5 to 9 layers and drops gradually from 9 to 19",
          "θ rises from PL 5 to 9, falls from 9 to 19, and no point exceeds θ(9) by more than the tolerance",
          _check_pl_angle),
    Claim("PL-curling", "particle_layers", "Fig. 8",
          "over 9 layers the actuator curves near the fixed end: a bending-to-curling transition "
          "between 9 and 10 layers",
          f"median curling index (share of the rotation in the clamp half) of PL ≥ 10 exceeds that of "
          f"PL ≤ 9 by {CURLING_MARGIN:g} or more, and its largest rise between neighbouring points lies "
          f"within PL 8-11",
          _check_pl_curling),
    Claim("PL-dx", "particle_layers", "Fig. 9",
          "the horizontal displacement increases from 5 to 9 layers and remains stable from 9 to 19",
          "|δx| rises from PL 5 to 9, then levels from 9 to 19", _check_pl_dx),
    Claim("PL-dz", "particle_layers", "Fig. 9",
          "the vertical displacement increases from 5 to 7 layers and then drops from 7 to 19",
          "|δz| rises from PL 5 to 7, then falls from 7 to 19", _check_pl_dz),
    Claim("h-angle", "strain_limit_thickness", "Fig. 10",
          "the bending angle increases rapidly from h = 4 to 10 mm and remains from 10 to 12 mm",
          "θ rises from h 4 to 10 mm, then levels from 10 to 12 mm",
          _check_h_angle),
    Claim("h-displacement", "strain_limit_thickness", "Fig. 11",
          "the horizontal and vertical displacements increase from h = 4 to 10 mm and decrease from 10 to 12 mm",
          "|δx| and |δz| each rise from h 4 to 10 mm, then fall from 10 to 12 mm",
          _check_h_displacement),
]

_MODEL_DIFFERENCES = {
    "2d": "hydrojam is 2D plane strain: its particles are infinitely long cylinders, the paper's (ABAQUS, "
          "3D) are spheres. In plane strain all of a particle's swelling goes into the plane: its diameter "
          "grows 2.6x at 275 K, where a free sphere grows 2.16x, and the membrane (10x softer than the gel, "
          "with no out-of-plane hoop stretch to resist it) balloons round the particles. A long chamber "
          "then does not stay a column: the particles pack into a round cluster and the actuator shortens "
          "(the tip rises) instead of bending or curling (see the particle-layer shapes).",
    "friction": "Contact is frictionless (IPC barrier), the paper's is ABAQUS contact (its friction is "
                "not stated). Frictionless particles slide past each other: a column rearranges "
                "(zig-zags) instead of pushing along its axis.",
    "material": "Our membrane and strain-limit layer are compressible neo-Hookean Ecoflex 00-30 "
                "(G = 0.023 MPa, ν = 0.45); the paper does not give its elastomer parameters.",
    "path": "Our load path is quasi-static with viscous stabilisation, released at the end; a column of "
            "frictionless particles has many equilibria and round-off selects one. For the default design "
            "(PL 5) round-off variants agree on θ within a few degrees (71-75°) and on the tip within about "
            "10 mm (docs/actuator.md); for longer chambers the end state is not robust (two round-off variants "
            "of PL 7 ended at 9.7° and 19.5°), and releasing the stabilisation at s = 1 moved PL 15 and 19 "
            "by 20-50° into a bulged, shortened shape.",
    "paper": "The paper's trends are read from its figures and words (curling judged by eye; the text puts "
             "the strain-limit layer on the left yet says the actuator bends to the right in Sec. IV-A and "
             "to the left in IV-C); one run per point, no uncertainty given.",
}

#: default "why" for a claim hydrojam disagrees with (hypotheses, not findings)
DISAGREEMENT_REASONS: dict[str, str] = {
    "T-angle": "likely the 2D model: cylinders in plane strain jam differently from spheres, and the "
               "frictionless column can rearrange into another equilibrium at one temperature (path dependence).",
    "T-displacement": "likely the tip's path dependence (about 10 mm) with frictionless particles, which can "
                      "exceed the change between neighbouring temperatures; possibly the 2D membrane without "
                      "out-of-plane stretch.",
    "T-linear": "likely path dependence of the tip (about 10 mm) and the swelling's non-linearity in T near "
                "the volume phase transition; the paper's 'linear' is read by eye from five points.",
    "T-dx-dominant": "likely the elongation of the chamber along z in plane strain (the cylinders cannot "
                     "bulge the membrane out of plane, so more swelling goes into length, δz).",
    "PL-angle": "likely the 2D model: in plane strain a long chamber of swelling cylinders balloons into a round "
                "cluster and shortens instead of bending (see the shapes), so θ falls from 5 layers on; the end "
                "states of PL ≥ 7 are also path dependent (round-off moved PL 7 by 10°).",
    "PL-curling": "likely the curling index's definition (share of rotation in the clamp half) versus the "
                  "paper's curling judged by eye, and 2D cylinders distributing the swelling along the "
                  "chamber differently from spheres.",
    "PL-dx": "likely the 2D ballooning of long chambers (the tip rises and moves little sideways) and the path "
             "dependence of PL ≥ 7.",
    "PL-dz": "likely the 2D ballooning: long chambers shorten, so δz changes sign (the tip rises) and |δz| grows "
             "with PL instead of falling.",
    "h-angle": "likely the elastomer parameters (a neo-Hookean Ecoflex of G = 0.023 MPa for the layer) and "
               "2D plane strain, which set how much a thicker layer resists the particles' push.",
    "h-displacement": "likely the tip's path dependence (about 10 mm) which is comparable to the changes "
                      "between thicknesses, and the elastomer parameters; the paper's drop from 10 to 12 mm "
                      "is one point.",
}


@dataclass(frozen=True)
class ClaimResult:
    claim: Claim
    summary: str
    verdict: str  # "agree" | "disagree" | "undetermined"


def check_claims(table) -> list[ClaimResult]:
    """Every claim of PAPER_CLAIMS checked on its sweep's rows of ``table`` (a SweepTable or a list of rows)."""
    out = []
    for claim in PAPER_CLAIMS:
        summary, verdict = claim.check(_rows_of(table, claim.sweep))
        out.append(ClaimResult(claim, summary, verdict))
    return out


# ------------------------------------------------------------------------------------------------
# Figures

_COLOURS = {"membrane": "0.82", "strain_limit": "0.45", "particle": "#3ba7d6"}
SHAPES_MAX_COLUMNS = 5
DPI = 150


def _sweep_for(param: str, label: str | None = None, unit: str | None = None) -> tuple[str, str, str]:
    sw = _BY_FIELD.get(param)
    symbol = sw.symbol if sw else param
    return symbol, label or (sw.label if sw else param), unit if unit is not None else (sw.unit if sw else "")


def _read_shape(point_dir: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Deformed positions (n, 2), triangles (k, 3), their body ids and the undeformed outer outline
    (a closed rectangle (5, 2), or None) from ``final.vtu``, all in (x, z) [mm].

    :func:`hydrojam.results.write_vtu` writes the reference points and a ``displacement`` field:
    the deformed points are their sum and the outline is the reference points' bounding box
    (the actuator is a rectangle, DESIGN.md section 6). Without a displacement field the points
    are taken as deformed and no outline is drawn."""
    import meshio

    mesh = meshio.read(point_dir / "final.vtu")
    pts = np.asarray(mesh.points, dtype=float)[:, [0, 2]]
    disp = mesh.point_data.get("displacement")
    outline = None
    if disp is not None:
        (x0, z0), (x1, z1) = pts.min(axis=0), pts.max(axis=0)
        outline = np.array([[x0, z1], [x1, z1], [x1, z0], [x0, z0], [x0, z1]])
        pts = pts + np.asarray(disp, dtype=float)[:, [0, 2]]
    tris, bodies = [], []
    body_data = mesh.cell_data.get("body_id")
    for i, block in enumerate(mesh.cells):
        if block.type not in ("triangle6", "triangle"):
            continue
        cells = np.asarray(block.data)
        body = (np.asarray(body_data[i]).reshape(-1) if body_data is not None
                else np.zeros(len(cells), dtype=int))
        if block.type == "triangle6":
            tris.append(cells[:, _TRI6_SPLIT].reshape(-1, 3))
            bodies.append(np.repeat(body, 4))
        else:
            tris.append(cells)
            bodies.append(body)
    if not tris:
        raise ValueError("no triangles in final.vtu")
    return pts, np.concatenate(tris), np.concatenate(bodies), outline


def _body_outlines(tris: np.ndarray, body: np.ndarray) -> np.ndarray:
    """Edges (k, 2) on the boundary of each body: triangle edges that only one triangle of that
    body has. Membrane and strain-limit layer count as one body (bonded)."""
    group = np.where(body <= 1, 0, body)
    edges = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    keyed = np.column_stack([np.repeat(group, 3), edges])
    uniq, counts = np.unique(keyed, axis=0, return_counts=True)
    return uniq[counts == 1, 1:]


def _failure_text(row: dict, reason: str | None = None) -> str:
    err = reason or str(row.get("error") or "no result")
    return "\n".join(textwrap.wrap(f"failed: {err}", 28)[:6])


def plot_shapes(out: str | os.PathLike, rows: Sequence[dict], param: str, path: str | os.PathLike, *,
                label: str | None = None, unit: str | None = None) -> None:
    """The deformed actuators of one sweep side by side (the paper's Figs. 6, 8, 10).

    One panel per point, sorted by ``param`` (a dotted design field, a column of ``rows``), all
    at the same scale (shared limits, equal aspect): membrane light grey, strain-limit layer dark
    grey, particles blue, read from ``OUT/<point_dir>/final.vtu``; the undeformed outer outline
    dashed (from the point's design.toml); the title gives the parameter and the bending angle.
    A failed point (or one without final.vtu) gets an empty panel saying why. Lengths in mm.
    """
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    out = Path(out)
    symbol, _, unit = _sweep_for(param, label, unit)
    rows = _sorted(rows, param)
    panels = []
    for row in rows:
        pdir = out / str(row.get("point_dir") or "")
        panel = {"row": row, "shape": None, "outline": None, "failed": None}
        if _status(row) == "failed" or not row.get("point_dir"):
            panel["failed"] = _failure_text(row)
        else:
            try:
                pts, tris, body, panel["outline"] = _read_shape(pdir)
                panel["shape"] = (pts, tris, body)
            except Exception as err:  # noqa: BLE001 - a figure must survive one bad file
                panel["failed"] = _failure_text(row, f"cannot read final.vtu ({type(err).__name__}: {err})")
        panels.append(panel)
    n = max(len(panels), 1)
    ncols = min(n, SHAPES_MAX_COLUMNS)
    nrows = math.ceil(n / ncols)
    allp = [p["shape"][0] for p in panels if p["shape"] is not None]
    allp += [p["outline"] for p in panels if p["outline"] is not None]
    if allp:
        pts = np.vstack(allp)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
    else:
        lo, hi = np.array([-30.0, -100.0]), np.array([30.0, 0.0])
    pad = 0.04 * float(max(hi - lo))
    lo, hi = lo - pad, hi + pad
    aspect = float((hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-9))
    panel_w = 2.6
    panel_h = min(max(panel_w * aspect, 2.0), 7.0) + 0.7
    fig = Figure(figsize=(panel_w * ncols + 0.6, panel_h * nrows + 0.9), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    colours = {0: _COLOURS["membrane"], 1: _COLOURS["strain_limit"]}
    for ax, panel in zip(axes.flat, panels):
        row = panel["row"]
        value = _num(row.get(param))
        head = f"{symbol} = {_fmt_param(value, unit)}"
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]", fontsize=8)
        ax.set_ylabel("z [mm]", fontsize=8)
        ax.tick_params(labelsize=7)
        if panel["outline"] is not None:
            ax.plot(panel["outline"][:, 0], panel["outline"][:, 1], "--", color="0.4", lw=0.8, zorder=3)
        if panel["failed"] is not None:
            ax.set_title(head, fontsize=9)
            ax.text(0.5, 0.5, panel["failed"], transform=ax.transAxes, ha="center", va="center", fontsize=7,
                    color="tab:red")
            continue
        pts, tris, body = panel["shape"]
        order = np.argsort(body, kind="stable")  # particles drawn last, over the walls
        tris, body = tris[order], body[order]
        face = [colours.get(int(b), _COLOURS["particle"]) for b in body]
        ax.add_collection(PolyCollection(pts[tris], facecolors=face, edgecolors="face", linewidths=0.3))
        ax.add_collection(LineCollection(pts[_body_outlines(tris, body)], colors="0.2", linewidths=0.4))
        angle = _num(row.get("bending_angle_deg"))
        title = head + (f"\nθ = {angle:.1f}°" if angle is not None else "\nθ: —")
        if _status(row) == "not_converged":
            title += " (not converged)"
        ax.set_title(title, fontsize=9, color="tab:red" if _status(row) == "not_converged" else "k")
    handles = [Patch(color=_COLOURS["membrane"], label="membrane"),
               Patch(color=_COLOURS["strain_limit"], label="strain-limit layer"),
               Patch(color=_COLOURS["particle"], label="hydrogel particles"),
               Line2D([], [], ls="--", color="0.5", label="undeformed outline")]
    fig.legend(handles=handles, loc="outside lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle(f"Deformed actuators, final states ({_sweep_for(param, label, unit)[1]}); "
                 "strain-limit layer on the -x side", fontsize=10)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")


def plot_trends(rows: Sequence[dict], param: str, path: str | os.PathLike, label: str, unit: str, *,
                curling: bool | None = None) -> None:
    """Bending angle and free-end displacement magnitudes |δx|, |δz| against the parameter (the
    paper's Figs. 7, 9, 11), and with ``curling`` (default: for ``particle_layers``) the curling
    index. Markers and lines; a non-converged point is drawn hollow, a failed one is left out
    and named under the figure."""
    from matplotlib.lines import Line2D

    rows = _sorted(rows, param)
    if curling is None:
        curling = param == "particle_layers"
    quantities = [("bending_angle_deg", False, "bending angle θ [deg]\n(> 0: toward the strain-limit layer)")]
    n_ax = 3 if curling else 2
    fig = Figure(figsize=(4.4 * n_ax, 4.4), layout="constrained")
    axes = fig.subplots(1, n_ax)
    xlabel = f"{label} [{unit}]" if unit else label

    def draw(ax, key, magnitude, colour, marker, name):
        xs, ys, hollow = [], [], []
        for r in rows:
            p, v = _num(r.get(param)), _num(r.get(key))
            if p is None or v is None or _status(r) == "failed":
                continue
            xs.append(p)
            ys.append(abs(v) if magnitude else v)
            hollow.append(_status(r) == "not_converged")
        xs, ys, hollow = np.array(xs), np.array(ys), np.array(hollow, dtype=bool)
        ax.plot(xs, ys, "-", color=colour, lw=1.2, label=name)
        ax.plot(xs[~hollow], ys[~hollow], marker, color=colour, ms=6, ls="none")
        ax.plot(xs[hollow], ys[hollow], marker, ms=6, ls="none", mfc="white", mec=colour, mew=1.5)
        return bool(hollow.any())

    any_hollow = draw(axes[0], *quantities[0][:2], "C0", "o", "θ")
    axes[0].set_ylabel(quantities[0][2])
    any_hollow |= draw(axes[1], "tip_dx_mm", True, "C1", "s", "|δx| horizontal")
    any_hollow |= draw(axes[1], "tip_dz_mm", True, "C2", "^", "|δz| vertical")
    axes[1].set_ylabel("free-end displacement magnitude |δ| [mm]")
    if curling:
        any_hollow |= draw(axes[2], "curling_index", False, "C3", "D", "curling index")
        axes[2].axhline(0.5, color="0.6", lw=0.8, ls=":")
        axes[2].set_ylabel("curling index [-]\n(share of rotation in the clamp half; 0.5 uniform)")
    for ax in axes:
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    notes = [Line2D([], [], color="0.3", marker="o", ls="none", mfc="white", label="hollow: not converged")]
    handles, _ = axes[1].get_legend_handles_labels()
    axes[1].legend(handles=handles + (notes if any_hollow else []), fontsize=8)
    if any_hollow and not curling:
        axes[0].legend(handles=notes, fontsize=8)
    caption = ("|δx|, |δz|: magnitudes of the free-end displacement, as the paper plots them "
               "(signed in the report: δx < 0 toward the strain-limit layer, δz < 0 downward)")
    failed = [r for r in rows if _status(r) == "failed"]
    if failed:
        sym, _, u = _sweep_for(param, label, unit)
        caption += "\nfailed (not drawn): " + ", ".join(f"{sym} = {_fmt_param(_num(r.get(param)), u)}" for r in failed)
    fig.supxlabel(caption, fontsize=8, color="tab:red" if failed else "0.3")
    fig.suptitle(f"Bending angle and free-end displacement against {label}", fontsize=10)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")


def _figure_names(sweep: PaperSweep) -> tuple[str, str]:
    return f"figures/{sweep.name}_shapes.png", f"figures/{sweep.name}_trends.png"


def write_figures(out: str | os.PathLike, table) -> list[Path]:
    """Both figures of every sweep into ``OUT/figures/`` (``<sweep>_shapes.png``,
    ``<sweep>_trends.png``); a sweep without rows is skipped. Returns the paths written."""
    out = Path(out)
    written = []
    for sw in PAPER_SWEEPS:
        rows = _rows_of(table, sw.name)
        if not rows:
            continue
        shapes, trends = (out / name for name in _figure_names(sw))
        plot_shapes(out, rows, sw.field, shapes)
        plot_trends(rows, sw.field, trends, sw.label, sw.unit)
        written += [shapes, trends]
    return written


# ------------------------------------------------------------------------------------------------
# Report


def _cell(v, fmt: str = "{:.1f}") -> str:
    f = _num(v)
    return "—" if f is None else fmt.format(f)


def _md(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _points_table(rows: list[dict], sw: PaperSweep) -> list[str]:
    head = f"{sw.symbol} [{sw.unit}]" if sw.unit != "layers" else sw.symbol
    lines = [f"| {head} | θ [deg] | δx [mm] | δz [mm] | curling index | converged | Newton iterations | "
             "wall time [s] | status |",
             "|---:|---:|---:|---:|---:|:---:|---:|---:|:---|"]
    for r in _sorted(rows, sw.field):
        status = _status(r)
        conv = _truthy(r.get("converged"))
        note = status if status != "failed" else f"failed: {r.get('error') or 'no result'}"
        if status == "ok" and _truthy(r.get("stabilization_released")) is False:
            note += " (stabilisation not released)"
        lines.append(
            f"| {_fmt_param(_num(r.get(sw.field)))} | {_cell(r.get('bending_angle_deg'))} | "
            f"{_cell(r.get('tip_dx_mm'))} | {_cell(r.get('tip_dz_mm'))} | {_cell(r.get('curling_index'), '{:.2f}')} | "
            f"{'—' if conv is None else ('yes' if conv else 'no')} | {_cell(r.get('newton_iterations'), '{:.0f}')} | "
            f"{_cell(r.get('wall_time_s'), '{:.0f}')} | {_md(note)} |")
    return lines


def _tolerance_text() -> list[str]:
    return [
        f"- *rises* (*falls*) from a to b: v(b) − v(a) > tol (v(a) − v(b) > tol); *levels* from a to b: "
        f"|v(b) − v(a)| ≤ tol and the spread (max − min) over the points in [a, b] ≤ 2 tol.",
        f"- tol = {ANGLE_TOL:g} × the sweep's largest |θ| for the bending angle, and {DISPLACEMENT_TOL:g} × the "
        f"sweep's largest magnitude for |δx| and |δz| (for the default design the tip is path dependent by about "
        f"10 mm, the angle by a few degrees; docs/actuator.md).",
        f"- Displacements are compared as magnitudes |δx|, |δz|, as the paper plots them; the signed values are "
        f"in the tables (δx < 0: toward the strain-limit layer, δz < 0: downward).",
        f"- Curling index: share of the strain-limit layer mid-line's rotation accumulated in the half nearest "
        f"the clamp (0.5 uniform bending, toward 1 curling); the transition check needs the median of PL ≥ 10 "
        f"to exceed that of PL ≤ 9 by {CURLING_MARGIN:g} and the largest rise between neighbouring points "
        f"within PL 8-11.",
        "- A range of the paper (e.g. h from 4 to 10 mm) is checked between the first and the last point run "
        "within it, and the summary says so where they are not the paper's end points (the quick study runs "
        "h = 4, 8, 12 mm: 4 to 10 mm is checked from 4 to 8 mm, and 10 to 12 mm, with one point, cannot be). "
        "A part of a check is *undetermined* where such an end point failed or did not converge, or fewer "
        "than two points lie in the range; other unusable points are skipped and named.",
        "- A claim *disagrees* if any part of its check does, else it is *undetermined* if any part is, else "
        "it *agrees*.",
    ]


def write_report(out: str | os.PathLike, table, quick: bool, wall_time_s: float | None,
                 explanations: dict[str, str] | None = None, *, workers: int | None = None,
                 scheduler: str | None = None, base: Design | None = None) -> Path:
    """Write ``OUT/report.md`` (atomically) and return its path.

    What was run (quick or full, mesh size, points, workers, wall time, hydrojam version); per
    sweep its figures (``figures/<sweep>_shapes.png``, ``_trends.png``, when written) and a table
    of the points; the claims of PAPER_CLAIMS with hydrojam's numbers and verdicts, the "why" of a
    disagreement from ``explanations`` (claim id -> text) or DISAGREEMENT_REASONS; the tolerances
    and the model differences. ``base``: the study's base design (default :func:`paper_base`).
    """
    out = Path(out)
    base = base if base is not None else paper_base(quick)
    results = check_claims(table)
    why = {**DISAGREEMENT_REASONS, **(explanations or {})}
    all_rows = [r for sw in PAPER_SWEEPS for r in _rows_of(table, sw.name)]
    by_key = {}
    for r in all_rows:
        by_key.setdefault(r.get("key") or id(r), r)
    n_points = len(by_key)
    compute = sum(_num(r.get("wall_time_s")) or 0.0 for r in by_key.values())
    counts = {s: sum(1 for r in by_key.values() if _status(r) == s) for s in ("ok", "not_converged", "failed")}
    verdicts = {v: sum(1 for c in results if c.verdict == v) for v in ("agree", "disagree", "undetermined")}

    L = ["# hydrojam reproduction of Chen, Schott & Jovanova, Section IV (Figs. 6-11)", ""]
    L += ["## What was run", ""]
    L += [f"- Study: **{'quick' if quick else 'full'}** (`hydrojam reproduce{' --quick' if quick else ''}`), "
          f"hydrojam {__version__}.",
          f"- Base design: the default (PL {base.particle_layers}, h = {base.strain_limit_thickness:g} mm, "
          f"T = {base.stimulus.temperature:g} K, d = {base.particle_diameter:g} mm, frictionless), "
          f"2D plane strain (particles are cylinders), mesh size {base.mesh.size:g} mm (quadratic triangles).",
          ]
    for sw in PAPER_SWEEPS:
        vals = sorted({v for v in (_num(r.get(sw.field)) for r in _rows_of(table, sw.name)) if v is not None})
        vals = vals or (sw.quick_values if quick else sw.values)
        L.append(f"- {sw.label}: {', '.join(f'{v:g}' for v in vals)} {'' if sw.unit == 'layers' else sw.unit}"
                 .rstrip() + f" ({sw.figures}).")
    L += [f"- {n_points} distinct points (the base point is shared by the three sweeps): {counts['ok']} converged, "
          f"{counts['not_converged']} not converged, {counts['failed']} failed.",
          f"- Workers: {_workers_text(workers, scheduler)}; "
          f"wall time {'—' if _num(wall_time_s) is None else _duration(wall_time_s)}; "
          f"compute time summed over points {_duration(compute)} (a resumed run reuses finished points).",
          f"- Claims: {verdicts['agree']} agree, {verdicts['disagree']} disagree, "
          f"{verdicts['undetermined']} undetermined.", ""]
    for sw in PAPER_SWEEPS:
        rows = _rows_of(table, sw.name)
        L += [f"## {sw.label[0].upper() + sw.label[1:]} (paper {sw.figures})", ""]
        for name, what in zip(_figure_names(sw), ("Deformed shapes", "Trends")):
            if (out / name).is_file():
                L += [f"![{what}: {sw.label}]({name})", ""]
            else:
                L += [f"*{what} figure not written ({name}).*", ""]
        L += (_points_table(rows, sw) if rows else ["*No points of this sweep in the table.*"]) + [""]
    L += ["## The paper's statements and hydrojam", ""]
    L += ["| # | paper (Fig.) | hydrojam computed | verdict | why (for disagree) |", "|---|---|---|---|---|"]
    for c in results:
        reason = why.get(c.claim.id, "") if c.verdict == "disagree" else ""
        L.append(f"| {c.claim.id} | {_md(c.claim.paper)} ({c.claim.figure}) | {_md(c.summary)} | "
                 f"**{c.verdict}** | {_md(reason)} |")
    L += ["", "The reasons given for a disagreement are hypotheses from the model differences below, not findings.",
          "", "### How each statement is checked", ""]
    L += [f"- **{c.id}**: {c.rule}." for c in PAPER_CLAIMS]
    L += [""] + _tolerance_text() + [""]
    L += ["## Model differences", ""]
    L += [f"- {text}" for text in _MODEL_DIFFERENCES.values()] + [""]
    text = "\n".join(L)
    path = out / "report.md"
    write_text_atomic(path, text)
    return path


def _workers_text(workers: int | None, scheduler: str | None) -> str:
    if scheduler:
        return f"the dask scheduler at {scheduler}"
    return f"{workers} local" if workers is not None else "local, one per CPU (default)"


def _duration(seconds: float | None) -> str:
    s = _num(seconds)
    if s is None:
        return "—"
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.1f} min"
    return f"{s / 3600:.2f} h"


# ------------------------------------------------------------------------------------------------
# The whole thing


def reproduce(out: str | os.PathLike, *, quick: bool = False, workers: int | None = None,
              scheduler: str | None = None, on_point=None):
    """Run the Section IV study into ``out`` (:func:`hydrojam.sweep.run_sweep`), write the
    figures into ``OUT/figures/`` and ``OUT/report.md``; returns (SweepTable, report path)."""
    from hydrojam.study.sweep import run_sweep

    out = Path(out)
    t0 = time.perf_counter()
    study = paper_study(quick)
    table = run_sweep(study, out, workers=workers, scheduler=scheduler, on_point=on_point)
    write_figures(out, table)
    report = write_report(out, table, quick, time.perf_counter() - t0, workers=workers, scheduler=scheduler,
                          base=study.base)
    return table, report
