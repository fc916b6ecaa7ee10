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
and last points run within it (a study without h = 10 mm would check "4 to 10 mm" from 4 to 8 mm and
could not check "10 to 12 mm"). A claim disagrees if any part of its check does, else it is
undetermined if any part is (an end point failed or did not converge, fewer than two points in a
range), else it agrees. A claim whose sweep has a point not finished yet (a table written from
a study in progress, ``reproduce --report-only``) is undetermined whatever its finished points
read, and its summary says what they read: that point may change any part, and the tolerance.

With replicas (a table whose points carry ``<metric>_std``, :mod:`hydrojam.study.table`) the
values are the replicas' means, and a part agrees or disagrees only when it does beyond the
spread: each comparison's distance from its threshold (e.g. v(b) - v(a) - tol for *rises*) must
exceed the spread of what it compares, u = sqrt(s_a² + s_b²) with s the points' standard
deviations (the spread of one filling against another, not the standard error of the means: a
designer builds one actuator). A part within the spread is "undetermined (spread)", and so is a
claim with such a part and no part that disagrees or is undetermined for want of points. A point
with one run in a study with replicas measures no spread of its own and takes the largest its
sweep measured. A point of a study in progress with some of its replicas finished is used with
those runs, and the claim stays "not final" until it finishes.

Units: mm, K, degrees.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field as _field

import numpy as np

from hydrojam.actuator.metrics import metric
from hydrojam.paper._rows import fmt_param, number, partial_runs, point_status, rows_of
from hydrojam.paper.study import PaperSweep, paper_sweep, paper_sweeps
from hydrojam.study.cache import PointStatus
from hydrojam.study.table import NOT_IN_STATE

__all__ = [
    "ANGLE_TOL",
    "CURLING_MARGIN",
    "Claim",
    "ClaimResult",
    "DISAGREEMENT_REASONS",
    "DISAGREEMENT_REASONS_3D",
    "DISPLACEMENT_TOL",
    "LINEAR_R2",
    "SPREAD_VERDICT",
    "Verdict",
    "PAPER_CLAIMS",
    "Trend",
    "check_claim",
    "check_claims",
    "check_state_claims",
    "paper_claims",
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


class Verdict(enum.StrEnum):
    """A claim's verdict; each member is the text the report writes, and equal to it as a string.

    Attributes
    ----------
    AGREE : str
        "agree": every part of the check agrees.
    DISAGREE : str
        "disagree": a part disagrees.
    UNDETERMINED : str
        "undetermined": a part lacks its points (missing, failed, not converged, not finished).
    SPREAD : str
        "undetermined (spread)": a part is left open by the replicas' spread.
    """

    AGREE = "agree"
    DISAGREE = "disagree"
    UNDETERMINED = "undetermined"
    SPREAD = "undetermined (spread)"


#: the verdict of a claim that the replicas' spread leaves open
SPREAD_VERDICT = Verdict.SPREAD


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
          reason="likely the 2D model: cylinders in plane strain jam differently from spheres, and the nearly "
                 "frictionless column can rearrange into another equilibrium at one temperature (path dependence)."),
    Claim(id="T-displacement", sweep="temperature", figure="Fig. 7",
          paper="the displacements decrease with increasing temperature",
          quantities=_TIP, magnitude=True, tolerance=DISPLACEMENT_TOL,
          trends=(Trend("falls", 275.0, 295.0), Trend("no_step_up")),
          rule="|δx| and |δz| each fall from 275 to 295 K, with no step up beyond the tolerance",
          reason="likely the tip's path dependence with slippery particles, which can exceed the change "
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
    # the paper's h read as the strip's width along y (3D only): the same statements, on that sweep
    Claim(id="hw-angle", sweep="strain_limit_width", figure="Fig. 10",
          paper="the bending angle increases rapidly from h = 4 to 10 mm and remains from 10 to 12 mm "
                "(h read as the strip's width)",
          quantities=_ANGLE, tolerance=ANGLE_TOL, trends=(Trend("rises", 4.0, 10.0), Trend("levels", 10.0, 12.0)),
          rule="θ rises from a strip width of 4 to 10 mm, then levels from 10 to 12 mm",
          reason="likely the strip's thickness, fixed at the base design's 8 mm: a strip that thick restrains "
                 "the face already when narrow, and the elastomer parameters set how much."),
    Claim(id="hw-displacement", sweep="strain_limit_width", figure="Fig. 11",
          paper="the horizontal and vertical displacements increase from h = 4 to 10 mm and decrease from 10 to "
                "12 mm (h read as the strip's width)",
          quantities=_TIP, magnitude=True, tolerance=DISPLACEMENT_TOL,
          trends=(Trend("rises", 4.0, 10.0), Trend("falls", 10.0, 12.0)),
          rule="|δx| and |δz| each rise from a strip width of 4 to 10 mm, then fall from 10 to 12 mm",
          reason="likely the tip's path dependence, which can be comparable to the changes between widths; the "
                 "paper's drop from 10 to 12 mm is one point."),
)

#: claim id -> the default "why" of a disagreement (hypotheses, not findings)
DISAGREEMENT_REASONS: dict[str, str] = {c.id: c.reason for c in PAPER_CLAIMS}

#: the same for the 3D study (spheres): measured reasons where the quick 3D study and its model
#: choices (docs/reproduce.md, "Sensitivity") found one, else hypotheses worded as such
DISAGREEMENT_REASONS_3D: dict[str, str] = {
    **DISAGREEMENT_REASONS,
    "T-angle": "measured: the most swollen column folds (every run at 275 K) and a folded column bends less than "
               "an arc (every run at 295 K); within each state θ falls as T rises. With friction 0.1 or 0.3 no run "
               "folds and the statement agrees; the elastomer's stiffness and the clearance (0.05, 0.2 mm) only move "
               "the temperature where the fold sets in (docs/reproduce.md, Sensitivity).",
    "T-displacement": "measured: no model choice tried (friction 0, 0.01, 0.1, 0.3; the elastomer 0.5x and 2x as "
                      "stiff; the clearance 0.05 and 0.2 mm) reproduces it; a column bent past 90° turns its tip back "
                      "up, so |δx| and |δz| do not follow θ.",
    "T-linear": "measured: no model choice tried (friction 0, 0.01, 0.1, 0.3; the elastomer 0.5x and 2x as stiff; "
                "the clearance 0.05 and 0.2 mm) reproduces it; the change of state between temperatures (fold or arc) "
                "makes the tip's path non-linear in T.",
    "T-dx-dominant": "measured: it agrees with the elastomer 2x stiffer and disagrees at 0.5x, at friction 0, 0.01, "
                     "0.1 and 0.3 and at a clearance of 0.05 and 0.2 mm: how much of the spheres' swelling goes into "
                     "the chamber's length (δz) is set by the membrane's stiffness.",
    "PL-angle": "measured (the layer runs finished so far): the column folds once to five times and keeps curling as "
                "layers are added, past a full turn at 19 layers, so θ still rises past 9 layers instead of peaking "
                "there.",
    "PL-curling": "measured (the layer runs finished so far): the curl spreads along the whole chamber at every length "
                  "(curling index 0.50-0.64, no rise past 9 layers), so there is no transition to curling near the "
                  "clamp.",
    "PL-dx": "measured (the layer runs finished so far): a column curled past three quarters of a turn brings its tip "
             "back toward the clamp and past it, so |δx| falls past 9 layers instead of levelling off.",
    "PL-dz": "measured (the layer runs finished so far): the curl keeps lifting the tip as layers are added, so |δz| "
             "still rises past 7 layers.",
    "h-angle": "measured: read as a thickness, a thicker layer resists the folded column's push more and θ falls "
               "(every run folded); read as the strip's width, θ rises from 4 to 10 mm as the paper's does.",
    "h-displacement": "measured: read as a thickness the tip's |δx| and |δz| fall from 4 to 10 mm with the angle; "
                      "read as a width they rise from 4 to 10 mm and do not fall from 10 to 12 mm.",
}


@dataclass(frozen=True)
class ClaimResult:
    """A claim checked: the summary with hydrojam's numbers and the verdict.

    Parameters
    ----------
    claim : Claim
        The claim.
    summary : str
        Each part's numbers and the rule it applied.
    verdict : Verdict
        "agree", "disagree", "undetermined" or "undetermined (spread)".
    """

    claim: Claim
    summary: str
    verdict: Verdict


def paper_claims(dimension: int = 2) -> tuple[Claim, ...]:
    """The claims of PAPER_CLAIMS whose sweep runs in a study of ``dimension`` (the strip-width
    reading of h: 3D only), in order."""
    names = {s.name for s in paper_sweeps(dimension)}
    return tuple(c for c in PAPER_CLAIMS if c.sweep in names)


def check_claims(table, dimension: int = 2) -> list[ClaimResult]:
    """Every claim of a study of ``dimension`` (:func:`paper_claims`) checked on a table.

    Parameters
    ----------
    table : SweepTable or list of dict
        The study's results (or its rows).
    dimension : {2, 3}, optional
        The study's dimension.

    Returns
    -------
    list of ClaimResult
        In the order of PAPER_CLAIMS.
    """
    return [check_claim(claim, table) for claim in paper_claims(dimension)]


def check_state_claims(table, dimension: int = 2) -> list[ClaimResult]:
    """Every claim checked on one state's runs alone (a table of
    :func:`hydrojam.study.table.state_tables`): the points none of whose runs reached the state
    are left out, not counted as failed, so a range of the paper is checked over the part of it
    where the state occurs ("checked on the points run, 285 K to 295 K" in the summary), as for
    any point not run.

    Parameters
    ----------
    table : SweepTable or list of dict
        One state's table.
    dimension : {2, 3}, optional
        The study's dimension.

    Returns
    -------
    list of ClaimResult
    """
    rows = table if isinstance(table, Sequence) else table.rows
    return check_claims([r for r in rows if not str(r.get("error") or "").startswith(NOT_IN_STATE)], dimension)


def check_claim(claim: Claim, table) -> ClaimResult:
    """One claim checked on its sweep's rows of a table.

    Each trend is a part of the check on each quantity in turn ("larger_change": once, on the
    quantities together); a part is undetermined where its points are missing or unusable, and
    undetermined (spread) where the replicas' spread covers its margin (module docstring). The
    verdict: "disagree" if any part disagrees, else "undetermined" if any part is (or there is
    none), else "undetermined (spread)" if any part is, else "agree"; "undetermined" whatever
    the parts say where a point of the sweep is not finished (a table written without running),
    the summary then beginning with what they say.

    Parameters
    ----------
    claim : Claim
        The claim.
    table : SweepTable or list of dict
        The study's results (or its rows).

    Returns
    -------
    ClaimResult
        The verdict, and a summary giving each part's numbers (mean ± standard deviation with
        replicas) and the rule it applied, the ranges checked on other points than the paper's,
        and the points skipped (why).
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
            values = ", ".join(f"{p:g}: {s.at_text(p)}" for p in s.usable())
            text += f"; {s.name} by {sweep.symbol} {values}" if values else ""
    if not jointly:  # a joint check reads only the range's end points, which it names
        text += _skipped(series)
    oks = [ok for ok, _ in parts]
    if any(ok is False for ok in oks):
        verdict = Verdict.DISAGREE
    elif any(ok is None for ok in oks) or not oks:
        verdict = Verdict.UNDETERMINED
    else:
        verdict = Verdict.SPREAD if any(ok == _SPREAD for ok in oks) else Verdict.AGREE
    pending = sorted({p for s in series for p, why in s.problems.items() if why == _NOT_FINISHED}
                     | {p for s in series for p in s.partial})
    if pending and verdict != Verdict.UNDETERMINED:
        # a point still running may change any part (and the tolerance, from the sweep's largest value)
        partial = {p: why for s in series for p, why in s.partial.items()}
        at = f"{sweep.symbol} " + ", ".join(fmt_param(p, sweep.unit) + (f" ({partial[p]})" if p in partial else "")
                                            for p in pending)
        return ClaimResult(claim, f"not final, {at} not finished; the finished points alone read {verdict}: "
                                  + text, Verdict.UNDETERMINED)
    return ClaimResult(claim, text, verdict)


# ------------------------------------------------------------------------------------------------
# A quantity over a sweep


#: why a point of a table written without running (a study in progress) is not used
_NOT_FINISHED = "not finished"


class _Undetermined(Exception):
    """A check cannot decide: points missing, failed or not converged."""


#: a part of a check that the spread leaves open
_SPREAD = "spread"
#: one part of a check: (True agree | False disagree | None undetermined | _SPREAD, text with the numbers)
_Part = tuple[bool | str | None, str]

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
    spreads: dict[float, float]  # usable points' standard deviation over replicas (0: one run)
    partial: dict[float, str] = _field(default_factory=dict)  # point -> "k of n runs" (some still running)
    single: frozenset[float] = frozenset()  # points with one run in a study with replicas (spread taken)

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

    def u(self, *ps: float) -> float:
        """The spread of a comparison of the points ``ps``: sqrt of the sum of their variances."""
        return math.sqrt(math.fsum(self.spreads.get(p, 0.0) ** 2 for p in ps))

    def at_text(self, p: float) -> str:
        """The value at p with its spread: "74.2°" or, with replicas, "74.2 ± 3.1°"."""
        v, sd = self.values[p], self.spreads.get(p, 0.0)
        if p in self.single:
            return f"{self.fmt(v)} (one run)"
        if not sd:
            return self.fmt(v)
        text = self.fmt(v)
        unit = "°" if self.unit == "°" else (f" {self.unit}" if self.unit else "")
        return f"{text.removesuffix(unit)} ± {self.fmt(sd).removesuffix(unit)}{unit}"

    def pm(self, u: float) -> str:
        """" ± u" with the unit where there is a spread, else ""."""
        return f" ± {self.fmt(u)}" if u > 0 else ""

    def fmt(self, v: float, signed: bool = False) -> str:
        """A value (or a change, ``signed``) with its unit: "74.2°", "+3.0 mm", "0.61"."""
        if not self.unit:
            return f"{v:+.2f}" if signed else f"{v:.2f}"
        text = f"{v:+.1f}" if signed else f"{v:.1f}"
        return text + "°" if self.unit == "°" else f"{text} {self.unit}"


def _series(rows: Sequence[dict], sweep: PaperSweep, key: str, magnitude: bool, share: float) -> _Series:
    """Metric ``key`` over the rows of ``sweep``; tol = ``share`` x its largest magnitude.

    A point of a study with replicas some of whose replicas have finished (a study in progress)
    is used with its finished runs and listed in ``partial``; a point with one run there has no
    spread of its own and takes the largest its sweep measured (``single``)."""
    requested: list[float] = []
    values: dict[float, float] = {}
    spreads: dict[float, float] = {}
    problems: dict[float, str] = {}
    partial: dict[float, str] = {}
    single: set[float] = set()
    name, unit = _quantity(key)
    for row in rows:
        p = number(row.get(sweep.field))
        if p is None:
            continue
        requested.append(p)
        status, v = point_status(row), number(row.get(key))
        used, part = number(row.get("replicas_used")), partial_runs(row)
        if part and v is not None:
            partial[p] = part
            status = PointStatus.OK
        if status == PointStatus.FAILED:
            problems[p] = "failed"  # its error is in the report's table of points
        elif status == PointStatus.UNFINISHED:
            problems[p] = _NOT_FINISHED
        elif status == PointStatus.NOT_CONVERGED:
            problems[p] = "not converged"
        elif v is None:
            problems[p] = f"no {name}"
        elif key == "curling_index" and not 0.0 <= v <= 1.0:
            # the rotation reverses along the actuator (an S shape): neither bending nor curling
            problems[p] = f"curling index {v:.2f} outside [0, 1] (the rotation reverses along the actuator)"
        elif key == "curling_index" and not 0.0 <= (number(row.get(f"{key}_min")) or 0.0) <= (
                number(row.get(f"{key}_max")) or 0.0) <= 1.0 and number(row.get(f"{key}_max")) is not None:
            # a replica's S shape: a mean over it would mix curling with reversal
            problems[p] = (f"curling index of a replica outside [0, 1] ({number(row.get(f'{key}_min')):.2f} to "
                           f"{number(row.get(f'{key}_max')):.2f}: the rotation reverses along the actuator)")
        else:
            values[p] = abs(v) if magnitude else v
            spreads[p] = number(row.get(f"{key}_std")) or 0.0
            if used is not None and used < 2:
                single.add(p)
    # one run measures no spread: a replica's spread is its filling's, taken as the largest the sweep measured
    measured = max((sd for p, sd in spreads.items() if p not in single), default=0.0)
    spreads.update(dict.fromkeys(single, measured))
    scale = max((abs(v) for v in values.values()), default=0.0)
    return _Series(name=f"|{name}|" if magnitude else name, unit=unit, requested=sorted(set(requested)),
                   values=values, problems=problems, tol=share * scale, sweep=sweep, spreads=spreads,
                   partial=partial, single=frozenset(single))


def _beyond(ok: bool, checks: Sequence[tuple[float, float]]) -> bool | str:
    """A part's outcome given its comparisons, each (margin, u): margin > 0 where the rule holds,
    u the spread of what it compares. Without spread: ``ok`` (the rule as it reads). With it:
    False if a margin is below -u, True if every margin is above +u, else _SPREAD."""
    if all(u <= 0.0 for _, u in checks):
        return ok
    if any(m < -u for m, u in checks):
        return False
    return True if all(m > u for m, u in checks) else _SPREAD


def _spread_note(outcome: bool | str, s: _Series, margin: float, u: float) -> str:
    """The text of a part the spread leaves open: how far from its threshold, against the spread."""
    if outcome != _SPREAD:
        return ""
    return (f"; {SPREAD_VERDICT}: {s.fmt(margin, signed=True)} from the threshold, within the spread "
            f"±{s.fmt(u)}")


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
    margin, u = (d if t.shape == "rises" else -d) - s.tol, s.u(a, b)
    outcome = _beyond(ok, [(margin, u)])
    limit = s.fmt(s.tol if t.shape == "rises" else -s.tol, signed=True)
    return outcome, (f"{s.name} {s.at_text(a)} ({fmt_param(a, s.p_unit)}) -> {s.at_text(b)} "
                     f"({fmt_param(b, s.p_unit)}): {s.fmt(d, signed=True)}{s.pm(u)} [{t.shape} if beyond {limit}]"
                     + _spread_note(outcome, s, margin, u))


def _levels(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """"levels": end-to-end change within tol and spread (max - min) within 2 tol."""
    a, b = s.segment(t.start, t.end, notes)
    va, vb = s.at(a), s.at(b)
    pts = s.usable(a, b)
    hi_p, lo_p = max(pts, key=s.values.get), min(pts, key=s.values.get)
    spread = s.values[hi_p] - s.values[lo_p]
    d = vb - va
    ok = abs(d) <= s.tol and spread <= 2.0 * s.tol
    checks = [(s.tol - abs(d), s.u(a, b)), (2.0 * s.tol - spread, s.u(hi_p, lo_p))]
    outcome = _beyond(ok, checks)
    note = ""
    if outcome == _SPREAD:
        m, u = min(checks, key=lambda c: abs(c[0]) - c[1])
        note = _spread_note(outcome, s, m, u)
    return outcome, (f"{s.name} {s.at_text(a)} ({fmt_param(a, s.p_unit)}) -> {s.at_text(b)} "
                     f"({fmt_param(b, s.p_unit)}): {s.fmt(d, signed=True)}{s.pm(checks[0][1])}, range "
                     f"{s.fmt(spread)}{s.pm(checks[1][1])} over {len(pts)} points "
                     f"[levels if change within ±{s.fmt(s.tol)} and range within {s.fmt(2 * s.tol)}]" + note)


def _no_step_up(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """No step between neighbouring usable points rises by more than tol."""
    pts = s.usable()
    if len(pts) < 2:
        raise _Undetermined(f"{s.name}: fewer than 2 usable points")
    steps = [(a, b, s.values[b] - s.values[a], s.u(a, b)) for a, b in zip(pts, pts[1:])]
    ups = [(a, b, d, u) for a, b, d, u in steps if d > s.tol]
    outcome = _beyond(not ups, [(s.tol - d, u) for _, _, d, u in steps])
    if outcome is True:
        return True, f"{s.name}: no step up beyond {s.fmt(s.tol)} between neighbouring points ({len(pts)} points)"
    if outcome is False:
        shown = [st for st in steps if s.tol - st[2] < -st[3]] or ups
        return False, f"{s.name} steps up beyond {s.fmt(s.tol)}: " + ", ".join(
            f"{fmt_param(a, s.p_unit)} -> {fmt_param(b, s.p_unit)} {s.fmt(d, signed=True)}{s.pm(u)}"
            for a, b, d, u in shown)
    open_ = [st for st in steps if abs(s.tol - st[2]) <= st[3]]
    return _SPREAD, (f"{s.name}: {SPREAD_VERDICT}: steps within the spread of the limit {s.fmt(s.tol)}: " + ", ".join(
        f"{fmt_param(a, s.p_unit)} -> {fmt_param(b, s.p_unit)} {s.fmt(d, signed=True)}{s.pm(u)}" for a, b, d, u in open_))


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
    resid = y - (slope * x + icpt)
    r2 = 1.0 - float(np.sum(resid**2)) / ss_tot
    ok = r2 >= t.threshold
    text = f"{s.name}: slope {slope:+.2f} {s.unit}/{s.p_unit}, R² {r2:.2f} over {len(pts)} points [linear if R² ≥ {t.threshold:g}]"
    sd = np.array([s.spreads.get(p, 0.0) for p in pts])
    if not sd.any():
        return ok, text
    # with replicas: a line needs a change over the range beyond the spread, and a curve (R² short
    # of the threshold) needs a point off the line by more than its own spread
    change, typical = abs(slope) * float(x.max() - x.min()), float(np.sqrt(np.mean(sd**2)))
    if ok and change <= typical:
        return _SPREAD, text + (f"; {SPREAD_VERDICT}: the fitted change {s.fmt(change)} is within the replicas' "
                                f"spread ±{s.fmt(typical)}")
    if not ok and not np.any(np.abs(resid) > sd):
        return _SPREAD, text + f"; {SPREAD_VERDICT}: every point lies within its spread of the line"
    return ok, text


def _peak(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """No usable point exceeds the value at ``t.start`` by more than tol."""
    p = t.start
    vp = s.at(p)
    top = max(s.usable(), key=s.values.get)
    gap = s.values[top] - vp
    checks = {q: (s.tol - (s.values[q] - vp), s.u(q, p)) for q in s.usable() if q != p}
    outcome = _beyond(gap <= s.tol, list(checks.values()) or [(s.tol, 0.0)])
    note = ""
    if outcome == _SPREAD:
        q = min(checks, key=lambda q: abs(checks[q][0]) - checks[q][1])
        note = _spread_note(outcome, s, *checks[q]) + f" ({fmt_param(q, s.p_unit)})"
    return outcome, (f"largest {s.name} {s.at_text(top)} at {fmt_param(top, s.p_unit)}, "
                     f"{s.fmt(gap)} above {fmt_param(p, s.p_unit)} [peak at {fmt_param(p, s.p_unit)} "
                     f"if within {s.fmt(s.tol)}]" + note)


def _curls(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """The median above the split exceeds the median below it by ``t.threshold`` or more."""
    low, high = s.sides(t.split)
    m_low = float(np.median([s.values[p] for p in low]))
    m_high = float(np.median([s.values[p] for p in high]))
    sym = s.sweep.symbol
    margin = m_high - m_low - t.threshold
    u = math.sqrt(float(np.mean([s.spreads.get(p, 0.0) ** 2 for p in low]))
                  + float(np.mean([s.spreads.get(p, 0.0) ** 2 for p in high])))
    outcome = _beyond(m_high - m_low >= t.threshold, [(margin, u)])
    return outcome, (
        f"median {s.name} {s.fmt(m_low)} ({sym} ≤ {t.split[0]:g}, {len(low)} points) -> {s.fmt(m_high)} "
        f"({sym} ≥ {t.split[1]:g}, {len(high)} points){s.pm(u)} [curling if +{t.threshold:g} or more]"
        + _spread_note(outcome, s, margin, u))


def _transition(t: Trend, notes: list[str], s: _Series) -> tuple[bool, str]:
    """The largest rise between neighbouring usable points lies in a step within [start, end]."""
    low, high = s.sides(t.split)
    pts = low + high
    steps = [(s.values[b] - s.values[a], a, b) for a, b in zip(pts, pts[1:])]
    d, a, b = max(steps)
    sym = s.sweep.symbol
    ok = d > 0 and a >= t.start and b <= t.end
    inside = [st for st in steps if st[1] >= t.start and st[2] <= t.end]
    outside = [st for st in steps if st not in inside]
    outcome: bool | str = ok
    note = ""
    if inside:  # the best step inside the window against the best outside it (or no rise at all)
        d_in, a_in, b_in = max(inside)
        d_out, a_out, b_out = max(outside) if outside else (0.0, a_in, a_in)
        margin = d_in - max(d_out, 0.0)
        u = math.sqrt(s.u(a_in, b_in) ** 2 + (s.u(a_out, b_out) ** 2 if d_out > 0 else 0.0))
        outcome = _beyond(ok, [(margin, u)])
        note = _spread_note(outcome, s, margin, u)
    return outcome, (f"largest rise {s.fmt(d, signed=True)}{s.pm(s.u(a, b))} from {sym} {a:g} to {b:g} "
                     f"[transition if within {sym} {t.start:g}-{t.end:g}]" + note)


def _larger_change(t: Trend, notes: list[str], first: _Series, second: _Series) -> tuple[bool, str]:
    """Between the ends of the range, ``first`` changes more in size than ``second``."""
    lo, hi = first.segment(t.start, t.end, notes)
    d1, d2 = first.at(lo) - first.at(hi), second.at(lo) - second.at(hi)
    u1, u2 = first.u(lo, hi), second.u(lo, hi)
    margin, u = abs(d1) - abs(d2), math.sqrt(u1**2 + u2**2)
    outcome = _beyond(abs(d1) > abs(d2), [(margin, u)])
    return outcome, (
        f"from {fmt_param(hi, first.p_unit)} to {fmt_param(lo, first.p_unit)}: {first.name} changes by "
        f"{first.fmt(d1, signed=True)}{first.pm(u1)}, {second.name} by {second.fmt(d2, signed=True)}{second.pm(u2)} "
        f"[agree if |Δ{first.name}| > |Δ{second.name}|]" + _spread_note(outcome, first, margin, u))


_SHAPES: dict[str, Callable[..., tuple[bool, str]]] = {
    "rises": _change, "falls": _change, "levels": _levels, "no_step_up": _no_step_up, "linear": _linear,
    "peak": _peak, "curls": _curls, "transition": _transition, "larger_change": _larger_change,
}
#: shapes that read all of a claim's quantities together
_JOINT_SHAPES = frozenset({"larger_change"})
