"""The paper's Section IV statements as rows of data, and the one routine that checks a row
against the sweep table.

Each statement is a :class:`Claim`: which sweep, which quantities (metric columns), which trends
of the paper's words (:class:`Trend`: rises, falls, levels, ...) over which range of the swept
parameter, and the tolerance. :func:`check_claim` turns the sweep's rows into a summary with the
numbers and a verdict, "agree", "disagree" or "undetermined" (points missing, failed or not
converged). The trend words are made precise with a tolerance relative to the sweep's largest
magnitude of the quantity (``Claim.tolerance``, written into the report):

- *rises* (falls) from a to b: v(b) - v(a) > tol (v(a) - v(b) > tol);
- *levels* from a to b: |v(b) - v(a)| <= tol and max - min of v over [a, b] <= 2 tol;

with tol = ANGLE_TOL x max|θ| for the bending angle and DISPLACEMENT_TOL x max|δ| for the tip
displacements, which are more path dependent (docs/reproduce.md). Displacements are compared as
magnitudes |δx|, |δz|, as the paper plots them. A range of the paper is checked between the first
and last points run within it (the quick study's h = 4, 8, 12 mm checks "4 to 10 mm" from 4 to
8 mm and cannot check "10 to 12 mm"). A claim disagrees if any part of its check does, else it is
undetermined if any part is (an end point failed or did not converge, fewer than two points in a
range), else it agrees.

Units: mm, K, degrees.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hydrojam.actuator.metrics import metric
from hydrojam.paper._rows import fmt_param, number, point_status, rows_of
from hydrojam.paper.study import PaperSweep, paper_sweep

__all__ = [
    "ANGLE_TOL",
    "CURLING_MARGIN",
    "Claim",
    "ClaimResult",
    "DISAGREEMENT_REASONS",
    "DISPLACEMENT_TOL",
    "LINEAR_R2",
    "PAPER_CLAIMS",
    "Trend",
    "check_claim",
    "check_claims",
]

#: tolerance of "rises", "falls" and "levels" for the bending angle, as a share of max |θ| in the sweep
ANGLE_TOL = 0.05
#: the same for |δx| and |δz|, as a share of the sweep's largest magnitude (wider: the tip is more
#: path dependent than the angle)
DISPLACEMENT_TOL = 0.10
#: "curling": median curling index of PL >= 10 exceeds that of PL <= 9 by at least this much
CURLING_MARGIN = 0.10
#: "linear trend": coefficient of determination of a straight-line fit at least this
LINEAR_R2 = 0.90


@dataclass(frozen=True)
class Trend:
    """One part of a claim's check: a trend of the paper's words over the swept parameter.

    ``shape`` (a, b: ``start``, ``end`` in the parameter's unit; tol: the claim's tolerance):

    - "rises" / "falls": the change from the first to the last point run within [a, b] is
      beyond +tol / -tol;
    - "levels": over [a, b] the change is within ±tol and the spread (max - min) within 2 tol;
    - "no_step_up": no step between neighbouring usable points rises by more than tol;
    - "linear": a straight-line fit over the usable points (3 or more) has R² >= ``threshold``;
    - "peak": no usable point exceeds the value at a by more than tol;
    - "curls": the median of the points >= ``split[1]`` exceeds that of the points <= ``split[0]``
      by ``threshold`` or more (2 usable points each side);
    - "transition": the largest rise between neighbouring usable points (2 each side of
      ``split``) lies in a step within [a, b];
    - "larger_change": over [a, b] the claim's first quantity changes more in size than its
      second (the only shape that reads two quantities together).
    """

    shape: str
    start: float | None = None
    end: float | None = None
    threshold: float | None = None
    split: tuple[float, float] | None = None


@dataclass(frozen=True)
class Claim:
    """One qualitative statement of the paper's Section IV, as data.

    ``trends`` are checked on each of ``quantities`` (metric columns of sweep ``sweep``'s rows,
    as magnitudes with ``magnitude``) in turn, with tol = ``tolerance`` x the sweep's largest
    magnitude of the quantity. ``paper`` quotes the paper, ``rule`` says in words what is
    checked, ``reason`` is the default "why" of a disagreement (a hypothesis, not a finding).
    ``lists_values``: the summary lists the values of the quantity by parameter.
    """

    id: str
    sweep: str
    figure: str
    paper: str
    rule: str
    quantities: tuple[str, ...]
    trends: tuple[Trend, ...]
    tolerance: float
    reason: str
    magnitude: bool = False
    lists_values: bool = False


_ANGLE = ("bending_angle_deg",)
_TIP = ("tip_dx_mm", "tip_dz_mm")
_TIP_DX, _TIP_DZ = ("tip_dx_mm",), ("tip_dz_mm",)

PAPER_CLAIMS: tuple[Claim, ...] = (
    Claim(id="T-angle", sweep="temperature", figure="Fig. 6",
          paper="the bending angle decreases as the temperature rises from 275 K to 295 K (particles shrink)",
          quantities=_ANGLE, tolerance=ANGLE_TOL, trends=(Trend("falls", 275.0, 295.0), Trend("no_step_up")),
          rule="θ falls from 275 to 295 K, and no step between neighbouring temperatures rises beyond the tolerance",
          reason="likely the 2D model: cylinders in plane strain jam differently from spheres, and the frictionless "
                 "column can rearrange into another equilibrium at one temperature (path dependence)."),
    Claim(id="T-displacement", sweep="temperature", figure="Fig. 7",
          paper="the displacements decrease with increasing temperature",
          quantities=_TIP, magnitude=True, tolerance=DISPLACEMENT_TOL,
          trends=(Trend("falls", 275.0, 295.0), Trend("no_step_up")),
          rule="|δx| and |δz| each fall from 275 to 295 K, with no step up beyond the tolerance",
          reason="likely the tip's path dependence with frictionless particles, which can exceed the change "
                 "between neighbouring temperatures; possibly the 2D membrane without out-of-plane stretch."),
    Claim(id="T-linear", sweep="temperature", figure="Fig. 7",
          paper="the displacements ... show a linear trend (in T)",
          quantities=_TIP, magnitude=True, tolerance=DISPLACEMENT_TOL, trends=(Trend("linear", threshold=LINEAR_R2),),
          rule=f"straight-line fit of |δx| and |δz| against T: R² ≥ {LINEAR_R2:g} each (3 or more points)",
          reason="likely path dependence of the tip and the swelling's non-linearity in T near the volume phase "
                 "transition; the paper's 'linear' is read by eye from five points."),
    Claim(id="T-dx-dominant", sweep="temperature", figure="Fig. 7",
          paper="as the temperature decreases, the change in the horizontal direction is more pronounced",
          quantities=_TIP, magnitude=True, tolerance=DISPLACEMENT_TOL, trends=(Trend("larger_change", 275.0, 295.0),),
          rule="the change of |δx| between 295 and 275 K exceeds that of |δz| in size",
          reason="likely the elongation of the chamber along z in plane strain (the cylinders cannot bulge the "
                 "membrane out of plane, so more swelling goes into length, δz)."),
    Claim(id="PL-angle", sweep="particle_layers", figure="Fig. 8",
          paper="the bending angle increases from 5 to 9 layers and drops gradually from 9 to 19",
          quantities=_ANGLE, tolerance=ANGLE_TOL,
          trends=(Trend("rises", 5, 9), Trend("falls", 9, 19), Trend("peak", 9)),
          rule="θ rises from PL 5 to 9, falls from 9 to 19, and no point exceeds θ(9) by more than the tolerance",
          reason="likely the 2D model: in plane strain a long chamber of swelling cylinders can balloon and shorten "
                 "instead of bending (see the shapes), and the end states of long chambers are path dependent."),
    Claim(id="PL-curling", sweep="particle_layers", figure="Fig. 8",
          paper="over 9 layers the actuator curves near the fixed end: a bending-to-curling transition "
                "between 9 and 10 layers",
          quantities=("curling_index",), tolerance=0.0, lists_values=True,
          trends=(Trend("curls", threshold=CURLING_MARGIN, split=(9, 10)), Trend("transition", 8, 11, split=(9, 10))),
          rule=f"median curling index (share of the rotation in the clamp half) of PL ≥ 10 exceeds that of "
               f"PL ≤ 9 by {CURLING_MARGIN:g} or more, and its largest rise between neighbouring points lies "
               f"within PL 8-11",
          reason="likely the curling index's definition (share of rotation in the clamp half) versus the paper's "
                 "curling judged by eye, and 2D cylinders distributing the swelling along the chamber differently "
                 "from spheres."),
    Claim(id="PL-dx", sweep="particle_layers", figure="Fig. 9",
          paper="the horizontal displacement increases from 5 to 9 layers and remains stable from 9 to 19",
          quantities=_TIP_DX, magnitude=True, tolerance=DISPLACEMENT_TOL,
          trends=(Trend("rises", 5, 9), Trend("levels", 9, 19)),
          rule="|δx| rises from PL 5 to 9, then levels from 9 to 19",
          reason="likely the 2D ballooning of long chambers (the tip can rise and move little sideways) and the path "
                 "dependence of long chambers."),
    Claim(id="PL-dz", sweep="particle_layers", figure="Fig. 9",
          paper="the vertical displacement increases from 5 to 7 layers and then drops from 7 to 19",
          quantities=_TIP_DZ, magnitude=True, tolerance=DISPLACEMENT_TOL,
          trends=(Trend("rises", 5, 7), Trend("falls", 7, 19)),
          rule="|δz| rises from PL 5 to 7, then falls from 7 to 19",
          reason="likely the 2D ballooning: a chamber that shortens instead of bending moves its tip up, not down."),
    Claim(id="h-angle", sweep="strain_limit_thickness", figure="Fig. 10",
          paper="the bending angle increases rapidly from h = 4 to 10 mm and remains from 10 to 12 mm",
          quantities=_ANGLE, tolerance=ANGLE_TOL, trends=(Trend("rises", 4.0, 10.0), Trend("levels", 10.0, 12.0)),
          rule="θ rises from h 4 to 10 mm, then levels from 10 to 12 mm",
          reason="likely the elastomer parameters (a neo-Hookean Ecoflex of G = 0.023 MPa for the layer) and 2D "
                 "plane strain, which set how much a thicker layer resists the particles' push."),
    Claim(id="h-displacement", sweep="strain_limit_thickness", figure="Fig. 11",
          paper="the horizontal and vertical displacements increase from h = 4 to 10 mm and decrease from 10 to 12 mm",
          quantities=_TIP, magnitude=True, tolerance=DISPLACEMENT_TOL,
          trends=(Trend("rises", 4.0, 10.0), Trend("falls", 10.0, 12.0)),
          rule="|δx| and |δz| each rise from h 4 to 10 mm, then fall from 10 to 12 mm",
          reason="likely the tip's path dependence, which can be comparable to the changes between thicknesses, and "
                 "the elastomer parameters; the paper's drop from 10 to 12 mm is one point."),
)

#: claim id -> the default "why" of a disagreement (hypotheses, not findings)
DISAGREEMENT_REASONS: dict[str, str] = {c.id: c.reason for c in PAPER_CLAIMS}


@dataclass(frozen=True)
class ClaimResult:
    """A claim checked: the summary with hydrojam's numbers and the verdict."""

    claim: Claim
    summary: str
    verdict: str  # "agree" | "disagree" | "undetermined"


def check_claims(table) -> list[ClaimResult]:
    """Every claim of PAPER_CLAIMS checked on ``table`` (a SweepTable or a list of rows)."""
    return [check_claim(claim, table) for claim in PAPER_CLAIMS]


def check_claim(claim: Claim, table) -> ClaimResult:
    """One claim checked on its sweep's rows of ``table`` (a SweepTable or a list of rows).

    Each trend is a part of the check on each quantity in turn ("larger_change": once, on the
    quantities together); a part is undetermined where its points are missing or unusable. The
    verdict: "disagree" if any part disagrees, else "undetermined" if any part is (or there is
    none), else "agree". The summary gives each part's numbers and the rule it applied, the
    ranges checked on other points than the paper's, and the points skipped (why).
    """
    sweep = paper_sweep(claim.sweep)
    rows = rows_of(table, claim.sweep)
    series = [_series(rows, sweep, key, claim.magnitude, claim.tolerance) for key in claim.quantities]
    jointly = any(t.shape in _JOINT_SHAPES for t in claim.trends)
    groups = [series] if jointly else [[s] for s in series]
    notes: list[str] = []
    parts = [_part(_SHAPES[t.shape], t, notes, *group) for group in groups for t in claim.trends]
    text = "; ".join(part_text for _, part_text in parts)
    if notes:
        text += " (" + "; ".join(notes) + ")"
    if claim.lists_values:
        for s in series:
            values = ", ".join(f"{p:g}: {s.fmt(s.values[p])}" for p in s.usable())
            text += f"; {s.name} by {sweep.symbol} {values}" if values else ""
    if not jointly:  # a joint check reads only the range's end points, which it names
        text += _skipped(series)
    oks = [ok for ok, _ in parts]
    if any(ok is False for ok in oks):
        return ClaimResult(claim, text, "disagree")
    return ClaimResult(claim, text, "undetermined" if any(ok is None for ok in oks) or not oks else "agree")


# ------------------------------------------------------------------------------------------------
# A quantity over a sweep


class _Undetermined(Exception):
    """A check cannot decide: points missing, failed or not converged."""


#: one part of a check: (True agree | False disagree | None undetermined, text with the numbers)
_Part = tuple[bool | None, str]

#: registry units as written in the summaries
_UNIT_TEXT = {"deg": "°", "-": ""}


def _quantity(key: str) -> tuple[str, str]:
    """(symbol, unit) of metric column ``key`` in the summaries, from the metric registry."""
    m = metric(key)
    return m.symbol or key, _UNIT_TEXT.get(m.unit, m.unit)


@dataclass(frozen=True)
class _Series:
    """One quantity over a sweep: requested parameter values and the usable values among them."""

    name: str  # e.g. "θ", "|δx|"
    unit: str  # "°", "mm" or "" (curling index)
    requested: list[float]  # parameter values present in the rows, sorted
    values: dict[float, float]  # usable points only
    problems: dict[float, str]  # parameter -> why unusable
    tol: float  # tolerance in the quantity's unit
    sweep: PaperSweep

    @property
    def p_unit(self) -> str:
        return self.sweep.unit

    def at(self, p: float) -> float:
        if p not in self.values:
            raise _Undetermined(f"{self.name} at {fmt_param(p, self.p_unit)}: {self.problems.get(p, 'not run')}")
        return self.values[p]

    def segment(self, a: float, b: float, notes: list[str]) -> tuple[float, float]:
        """The first and last points run within the paper's range [a, b]; a range not covered
        exactly is noted, fewer than two points in it is undetermined."""
        inside = [p for p in self.requested if a - 1e-9 <= p <= b + 1e-9]
        pa, pb = fmt_param(a, self.p_unit), fmt_param(b, self.p_unit)
        if len(inside) < 2:
            raise _Undetermined(f"fewer than 2 points run within {pa} to {pb}")
        lo, hi = inside[0], inside[-1]
        if (lo, hi) != (a, b):
            note = (f"the paper's {pa} to {pb} checked on the points run, "
                    f"{fmt_param(lo, self.p_unit)} to {fmt_param(hi, self.p_unit)}")
            if note not in notes:
                notes.append(note)
        return lo, hi

    def usable(self, a: float = -math.inf, b: float = math.inf) -> list[float]:
        return [p for p in self.requested if a <= p <= b and p in self.values]

    def sides(self, split: tuple[float, float]) -> tuple[list[float], list[float]]:
        """Usable points with p <= split[0] and p >= split[1], at least 2 each."""
        below, above = split
        pts = self.usable()
        low, high = [p for p in pts if p <= below], [p for p in pts if p >= above]
        if len(low) < 2 or len(high) < 2:
            raise _Undetermined(f"need 2 usable points on each side of {below:g}-{above:g} {self.p_unit}, have "
                                f"{len(low)} (≤ {below:g}) and {len(high)} (≥ {above:g})")
        return low, high

    def fmt(self, v: float, signed: bool = False) -> str:
        """A value (or a change, ``signed``) with its unit: "74.2°", "+3.0 mm", "0.61"."""
        if not self.unit:
            return f"{v:+.2f}" if signed else f"{v:.2f}"
        text = f"{v:+.1f}" if signed else f"{v:.1f}"
        return text + "°" if self.unit == "°" else f"{text} {self.unit}"


def _series(rows: Sequence[dict], sweep: PaperSweep, key: str, magnitude: bool, share: float) -> _Series:
    """Metric ``key`` over the rows of ``sweep``; tol = ``share`` x its largest magnitude."""
    requested: list[float] = []
    values: dict[float, float] = {}
    problems: dict[float, str] = {}
    name, unit = _quantity(key)
    for row in rows:
        p = number(row.get(sweep.field))
        if p is None:
            continue
        requested.append(p)
        status, v = point_status(row), number(row.get(key))
        if status == "failed":
            problems[p] = "failed"  # its error is in the report's table of points
        elif status == "not_converged":
            problems[p] = "not converged"
        elif v is None:
            problems[p] = f"no {name}"
        elif key == "curling_index" and not 0.0 <= v <= 1.0:
            # the rotation reverses along the actuator (an S shape): neither bending nor curling
            problems[p] = f"curling index {v:.2f} outside [0, 1] (the rotation reverses along the actuator)"
        else:
            values[p] = abs(v) if magnitude else v
    scale = max((abs(v) for v in values.values()), default=0.0)
    return _Series(name=f"|{name}|" if magnitude else name, unit=unit, requested=sorted(set(requested)),
                   values=values, problems=problems, tol=share * scale, sweep=sweep)


def _part(fn: Callable[..., tuple[bool, str]], *args) -> _Part:
    """A part of a check, undetermined (None) where its points are missing or unusable."""
    try:
        return fn(*args)
    except _Undetermined as err:
        return None, f"cannot decide: {err}"


def _skipped(series: Sequence[_Series]) -> str:
    """"; skipped <point> (<why>), ..." for the unusable points of the series, or ""."""
    probs: dict[float, str] = {}
    for s in series:
        probs.update(s.problems)
    if not probs:
        return ""
    unit = series[0].p_unit
    return "; skipped " + ", ".join(f"{fmt_param(p, unit)} ({why})" for p, why in sorted(probs.items()))


# ------------------------------------------------------------------------------------------------
# The trend shapes: (trend, notes, series...) -> (agrees, text with the numbers)


def _change(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """"rises"/"falls" over the paper's range: the end-to-end change beyond the tolerance."""
    a, b = s.segment(t.start, t.end, notes)
    va, vb = s.at(a), s.at(b)
    d = vb - va
    ok = d > s.tol if t.shape == "rises" else -d > s.tol
    limit = s.fmt(s.tol if t.shape == "rises" else -s.tol, signed=True)
    return ok, (f"{s.name} {s.fmt(va)} ({fmt_param(a, s.p_unit)}) -> {s.fmt(vb)} ({fmt_param(b, s.p_unit)}): "
                f"{s.fmt(d, signed=True)} [{t.shape} if beyond {limit}]")


def _levels(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """"levels": end-to-end change within tol and spread (max - min) within 2 tol."""
    a, b = s.segment(t.start, t.end, notes)
    va, vb = s.at(a), s.at(b)
    vals = [s.values[p] for p in s.usable(a, b)]
    spread = max(vals) - min(vals)
    d = vb - va
    ok = abs(d) <= s.tol and spread <= 2.0 * s.tol
    return ok, (f"{s.name} {s.fmt(va)} ({fmt_param(a, s.p_unit)}) -> {s.fmt(vb)} ({fmt_param(b, s.p_unit)}): "
                f"{s.fmt(d, signed=True)}, spread {s.fmt(spread)} over {len(vals)} points "
                f"[levels if change within ±{s.fmt(s.tol)} and spread within {s.fmt(2 * s.tol)}]")


def _no_step_up(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """No step between neighbouring usable points rises by more than tol."""
    pts = s.usable()
    if len(pts) < 2:
        raise _Undetermined(f"{s.name}: fewer than 2 usable points")
    ups = [(a, b, s.values[b] - s.values[a]) for a, b in zip(pts, pts[1:]) if s.values[b] - s.values[a] > s.tol]
    if not ups:
        return True, f"{s.name}: no step up beyond {s.fmt(s.tol)} between neighbouring points ({len(pts)} points)"
    return False, f"{s.name} steps up beyond {s.fmt(s.tol)}: " + ", ".join(
        f"{fmt_param(a, s.p_unit)} -> {fmt_param(b, s.p_unit)} {s.fmt(d, signed=True)}" for a, b, d in ups)


def _linear(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """R² of a straight-line fit over the usable points (3 or more) at least ``t.threshold``."""
    pts = s.usable()
    if len(pts) < 3:
        raise _Undetermined(f"{s.name}: {len(pts)} usable {s.sweep.points_noun}, need 3")
    x = np.array(pts)
    y = np.array([s.values[p] for p in pts])
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    if ss_tot <= (1e-9 * max(1.0, float(np.abs(y).max()))) ** 2:
        return False, f"{s.name} constant over {s.sweep.symbol}: no trend"
    slope, icpt = np.polyfit(x, y, 1)
    r2 = 1.0 - float(np.sum((y - (slope * x + icpt)) ** 2)) / ss_tot
    return r2 >= t.threshold, (f"{s.name}: slope {slope:+.2f} {s.unit}/{s.p_unit}, R² {r2:.2f} over {len(pts)} "
                               f"points [linear if R² ≥ {t.threshold:g}]")


def _peak(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """No usable point exceeds the value at ``t.start`` by more than tol."""
    p = t.start
    vp = s.at(p)
    top = max(s.usable(), key=s.values.get)
    gap = s.values[top] - vp
    return gap <= s.tol, (f"largest {s.name} {s.fmt(s.values[top])} at {fmt_param(top, s.p_unit)}, "
                          f"{s.fmt(gap)} above {fmt_param(p, s.p_unit)} [peak at {fmt_param(p, s.p_unit)} "
                          f"if within {s.fmt(s.tol)}]")


def _curls(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """The median above the split exceeds the median below it by ``t.threshold`` or more."""
    low, high = s.sides(t.split)
    m_low = float(np.median([s.values[p] for p in low]))
    m_high = float(np.median([s.values[p] for p in high]))
    sym = s.sweep.symbol
    return m_high - m_low >= t.threshold, (
        f"median {s.name} {s.fmt(m_low)} ({sym} ≤ {t.split[0]:g}, {len(low)} points) -> {s.fmt(m_high)} "
        f"({sym} ≥ {t.split[1]:g}, {len(high)} points) [curling if +{t.threshold:g} or more]")


def _transition(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """The largest rise between neighbouring usable points lies in a step within [start, end]."""
    low, high = s.sides(t.split)
    pts = low + high
    d, a, b = max((s.values[b] - s.values[a], a, b) for a, b in zip(pts, pts[1:]))
    sym = s.sweep.symbol
    return d > 0 and a >= t.start and b <= t.end, (
        f"largest rise {s.fmt(d, signed=True)} from {sym} {a:g} to {b:g} "
        f"[transition if within {sym} {t.start:g}-{t.end:g}]")


def _larger_change(t: Trend, notes: list[str], first: _Series, second: _Series) -> tuple[bool, str]:
    """Between the ends of the range, ``first`` changes more in size than ``second``."""
    lo, hi = first.segment(t.start, t.end, notes)
    d1, d2 = first.at(lo) - first.at(hi), second.at(lo) - second.at(hi)
    return abs(d1) > abs(d2), (
        f"from {fmt_param(hi, first.p_unit)} to {fmt_param(lo, first.p_unit)}: {first.name} changes by "
        f"{first.fmt(d1, signed=True)}, {second.name} by {second.fmt(d2, signed=True)} "
        f"[agree if |Δ{first.name}| > |Δ{second.name}|]")


_SHAPES: dict[str, Callable[..., tuple[bool, str]]] = {
    "rises": _change, "falls": _change, "levels": _levels, "no_step_up": _no_step_up, "linear": _linear,
    "peak": _peak, "curls": _curls, "transition": _transition, "larger_change": _larger_change,
}
#: shapes that read all of a claim's quantities together
_JOINT_SHAPES = frozenset({"larger_change"})
