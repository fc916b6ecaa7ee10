"""Figures of a study's table (``hydrojam sweep --plot``): per sweep, chosen metrics against the
field the sweep varies, drawn on :class:`matplotlib.figure.Figure` without pyplot (a notebook's
backend is left alone), PNG at DPI dots per inch; e.g. the bilateral design's bending angle
against temperature and the helical strip's twist against its angle (docs/chambers.md).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from hydrojam._io import atomic_path
from hydrojam.actuator.metrics import metric
from hydrojam.study.cache import PointStatus
from hydrojam.study.spec import Study
from hydrojam.study.table import METRIC_COLUMNS, SweepTable

__all__ = ["DPI", "PLOT_METRICS", "check_plot_metrics", "plot_sweep", "write_sweep_figures"]

DPI = 150
#: the metrics that are directions [deg], drawn unwrapped (no jump of 360 deg between neighbours)
ANGLE_METRICS = ("bending_plane_deg",)
#: the metrics ``--plot`` can draw: the table's numeric metric columns
PLOT_METRICS: tuple[str, ...] = tuple(k for k, kind in METRIC_COLUMNS.items() if kind in (int, float))


def check_plot_metrics(names: Sequence[str]) -> None:
    """Raise ValueError (one line naming ``--plot``) for a name not in :data:`PLOT_METRICS`."""
    if not names:
        raise ValueError(f"--plot: give one or more metrics, comma-separated, of: {', '.join(PLOT_METRICS)}")
    for name in names:
        if name not in PLOT_METRICS:
            raise ValueError(f"--plot: unknown metric {name!r} (allowed: {', '.join(PLOT_METRICS)})")


def _number(value) -> float | None:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def plot_sweep(rows: Sequence[dict], field: str, metrics: Sequence[str], path: str | os.PathLike,
               title: str) -> None:
    """Plot each of ``metrics`` against ``field`` (one panel each) from a sweep's table rows.

    Points in the field's order, joined by a line (a direction of :data:`ANGLE_METRICS` unwrapped,
    its mean within (-180, 180]); a not-converged point hollow, a failed or
    unfinished one left out and named under the figure. Rows of replicated points (with
    ``<metric>_std``, ``_min``, ``_max``) are drawn at their mean with error bars of ± one
    standard deviation and a band over the replicas' range.

    Parameters
    ----------
    rows : sequence of dict
        The sweep's rows of the results table (:class:`~hydrojam.study.table.SweepTable`).
    field : str
        The dotted design field the sweep varies (a column of ``rows``), numeric.
    metrics : sequence of str
        Metric columns to draw, of :data:`PLOT_METRICS`.
    path : str or os.PathLike
        The PNG file to write (atomically).
    title : str
        The figure's title.
    """
    rows = sorted((r for r in rows if _number(r.get(field)) is not None), key=lambda r: _number(r.get(field)))
    fig = Figure(figsize=(4.4 * len(metrics), 4.0), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(metrics)))
    left_out, replicated = [], False
    for r in rows:
        if r.get("status") not in (PointStatus.OK, PointStatus.NOT_CONVERGED):
            left_out.append(f"{field} = {_number(r.get(field)):g} ({r.get('status')})")
    for k, (ax, name) in enumerate(zip(axes, metrics)):
        xs, ys, hollow, err, lo, hi = [], [], [], [], [], []
        for r in rows:
            v = _number(r.get(name))
            if v is None or r.get("status") not in (PointStatus.OK, PointStatus.NOT_CONVERGED):
                continue
            xs.append(_number(r.get(field)))
            ys.append(v)
            hollow.append(r.get("status") == PointStatus.NOT_CONVERGED)
            err.append(_number(r.get(f"{name}_std")) or 0.0)
            lo.append(_number(r.get(f"{name}_min")) if _number(r.get(f"{name}_min")) is not None else v)
            hi.append(_number(r.get(f"{name}_max")) if _number(r.get(f"{name}_max")) is not None else v)
        xs, ys, hollow = np.array(xs), np.array(ys), np.array(hollow, dtype=bool)
        if name in ANGLE_METRICS and len(ys):  # a direction: no jump of 360 deg between neighbours
            shift = np.degrees(np.unwrap(np.radians(ys))) - ys
            shift -= 360.0 * np.round((ys + shift).mean() / 360.0)
            ys, lo, hi = ys + shift, np.add(lo, shift), np.add(hi, shift)
        colour = f"C{k}"
        ax.plot(xs, ys, "-", color=colour, lw=1.2)
        if any(err):
            replicated = True
            ax.fill_between(xs, lo, hi, color=colour, alpha=0.15, lw=0)
            ax.errorbar(xs, ys, yerr=err, fmt="none", ecolor=colour, elinewidth=1.0, capsize=3)
        ax.plot(xs[~hollow], ys[~hollow], "o", color=colour, ms=6, ls="none")
        ax.plot(xs[hollow], ys[hollow], "o", ms=6, ls="none", mfc="white", mec=colour, mew=1.5)
        ax.axhline(0.0, color="0.6", lw=0.8, ls=":")
        ax.set_xlabel(field)
        ax.set_ylabel(metric(name).label)
        ax.grid(alpha=0.3)
    notes = []
    if replicated:
        notes.append("means of the replicas; error bars ± one standard deviation, bands the replicas' range")
    if any(r.get("status") == PointStatus.NOT_CONVERGED for r in rows):
        notes.append("hollow: not converged")
    if left_out:
        notes.append("not drawn: " + ", ".join(left_out))
    if notes:
        fig.supxlabel("\n".join(notes), fontsize=8, color="0.3")
    fig.suptitle(title, fontsize=10)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")


def write_sweep_figures(study: Study, table: SweepTable, out: str | os.PathLike, metrics: Sequence[str]) -> list[Path]:
    """``out``/figures/<sweep>.png for every sweep of ``study`` that varies a numeric field: the
    ``metrics`` against the sweep's first numeric field (:func:`plot_sweep`). Returns the files
    written."""
    written = []
    for sweep in study.sweeps:
        field = next((f for f, values in sweep.vary.items()
                      if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)), None)
        if field is None:
            continue
        path = Path(out) / "figures" / f"{sweep.name}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        plot_sweep(table.select(sweep.name).rows, field, metrics, path,
                   f"{study.name}: {', '.join(metrics)} against {field} (sweep {sweep.name})")
        written.append(path)
    return written
