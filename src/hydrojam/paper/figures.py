"""The figures of the paper's Section IV study, drawn on :class:`matplotlib.figure.Figure`
without pyplot (a notebook's backend is left alone): per sweep the deformed shapes (like the
paper's Figs. 6, 8, 10) and the trends (Figs. 7, 9, 11), PNG at DPI dots per inch. Lengths mm.
A 3D point's shape is its section y = 0, the one ``final.png`` draws
(:func:`hydrojam.actuator.plots.plot_actuator`).
"""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from hydrojam._io import atomic_path
from hydrojam.actuator.metrics import centreline_points
from hydrojam.actuator.model import MEMBRANE_BODY, STRAIN_LIMIT_BODY, centreline_x
from hydrojam.actuator.plots import mid_section
from hydrojam.fem.elements import straight_pieces
from hydrojam.paper._rows import (drawn_angle, drawn_row, fmt_param, number, partial_runs, point_status, rows_of,
                                  runs_of, sorted_by, without_result)
from hydrojam.paper.study import PAPER_SWEEPS, PaperSweep, sweep_of_field
from hydrojam.study.cache import PointStatus

__all__ = ["DPI", "SHAPES_MAX_COLUMNS", "figure_names", "plot_shapes", "plot_trends", "state_series",
           "write_figures"]

_COLOURS = {"membrane": "0.82", "strain_limit": "0.45", "particle": "#3ba7d6"}
SHAPES_MAX_COLUMNS = 5
DPI = 150


def _sweep_for(param: str, label: str | None = None, unit: str | None = None) -> tuple[str, str, str]:
    """Symbol, label and unit of the swept field ``param`` (given ones win; unknown: the field)."""
    sw = sweep_of_field(param)
    symbol = sw.symbol if sw else param
    return symbol, label or (sw.label if sw else param), unit if unit is not None else (sw.unit if sw else "")


#: (deformed points (n, 2), triangles (k, 3), their body ids, undeformed outline or None, is a 3D section y = 0)
_Drawing = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, bool]


def _read_drawing(point_dir: Path) -> _Drawing:
    """The drawing (:func:`_drawing`) of the point's ``final.vtu``."""
    import meshio

    return _drawing(meshio.read(point_dir / "final.vtu"))


def _drawing(mesh, source: str = "final.vtu") -> _Drawing:
    """Deformed positions (n, 2), triangles (k, 3), their body ids and the undeformed outer outline
    (a closed rectangle (5, 2), or None) from a VTU file's mesh (meshio; ``source`` names it in
    errors), all in (x, z) [mm].

    :func:`hydrojam.actuator.results.write_vtu` writes the reference points and a ``displacement`` field:
    the deformed points are their sum and the outline is the reference points' bounding box
    (the actuator is a rectangle, docs/decisions.md, "Geometry"). Without a displacement field the points
    are taken as deformed and no outline is drawn. A 3D actuator (quadratic tetrahedra, the half
    model mirrored) is drawn as its section y = 0 (:func:`_section_y0`); the last item says so."""
    body_data = mesh.cell_data.get("body_id")
    tets = [i for i, block in enumerate(mesh.cells) if block.type == "tetra10"]
    pts3 = np.asarray(mesh.points, dtype=float)
    disp = mesh.point_data.get("displacement")
    if tets:
        if body_data is None:
            raise ValueError(f"no body_id in {source}")
        cells = np.concatenate([np.asarray(mesh.cells[i].data) for i in tets])
        body = np.concatenate([np.asarray(body_data[i]).reshape(-1) for i in tets])
        tris, bodies = _section_y0(pts3, cells, body)
        if not len(tris):
            raise ValueError(f"no cell faces on the plane y = 0 in {source}")
    pts = pts3[:, [0, 2]]
    outline = None
    if disp is not None:
        (x0, z0), (x1, z1) = pts.min(axis=0), pts.max(axis=0)
        outline = np.array([[x0, z1], [x1, z1], [x1, z0], [x0, z0], [x0, z1]])
        pts = pts + np.asarray(disp, dtype=float)[:, [0, 2]]
    if tets:
        return pts, tris, bodies, outline, True
    tris, bodies = [], []
    for i, block in enumerate(mesh.cells):
        if block.type not in ("triangle6", "triangle"):
            continue
        cells = np.asarray(block.data)
        body = (np.asarray(body_data[i]).reshape(-1) if body_data is not None
                else np.full(len(cells), MEMBRANE_BODY))
        pieces = straight_pieces(cells, 2)
        tris.append(pieces)
        bodies.append(np.repeat(body, len(pieces) // max(len(cells), 1)))
    if not tris:
        raise ValueError(f"no triangles in {source}")
    return pts, np.concatenate(tris), np.concatenate(bodies), outline, False


def _section_y0(points: np.ndarray, cells: np.ndarray, body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The section y = 0 of a 3D actuator's quadratic tetrahedra in reference ``points`` (n, 3)
    [mm]: straight triangles (k, 3) of node indices and their body ids, as ``final.png`` draws it
    (:func:`hydrojam.actuator.plots.mid_section`, given the file's mesh)."""
    fields = {"body_id": body, "swelling_ratio": np.zeros(len(body))}
    tris, bodies, _, _ = mid_section(points, cells, float(np.ptp(points[:, 2])) or 1.0, fields)
    return tris, bodies


def _body_outlines(tris: np.ndarray, body: np.ndarray) -> np.ndarray:
    """Edges (k, 2) on the boundary of each body: triangle edges that only one triangle of that
    body has. Membrane and strain-limit layer count as one body (bonded)."""
    group = np.where(np.isin(body, (MEMBRANE_BODY, STRAIN_LIMIT_BODY)), MEMBRANE_BODY, body)
    edges = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    keyed = np.column_stack([np.repeat(group, 3), edges])
    uniq, counts = np.unique(keyed, axis=0, return_counts=True)
    return uniq[counts == 1, 1:]


def _centreline_drawing(point_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """The strain-limit layer's mid-line of a finished point whose final.vtu is not kept (a record
    put back into a study folder): (deformed (m, 2), as made (2, 2)) in (x, z) [mm], rebuilt
    from its centreline.csv (arc length and rotation at the nodes) by
    :func:`hydrojam.actuator.metrics.centreline_points`, starting at the clamp, (x of the mid-line
    from its design.toml, 0). ValueError or OSError where either file is missing or unreadable."""
    import csv

    from hydrojam.actuator.design import load_design

    x0 = centreline_x(load_design(point_dir / "design.toml"))
    with open(point_dir / "centreline.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    if len(rows) < 2:
        raise ValueError(f"{point_dir / 'centreline.csv'}: fewer than 2 rows")
    column = lambda name: np.array([float(r[name]) for r in rows])  # noqa: E731
    line = centreline_points(column("arc_length_mm"), np.radians(column("rotation_deg")), start=(x0, 0.0))
    return line, np.array([[x0, 0.0], [x0, -column("reference_arc_length_mm")[-1]]])


def _current_drawing(point_dir: Path):
    """(drawing as :func:`_drawing` returns it, title line) of the unfinished run in
    ``point_dir`` as it stands now (:func:`hydrojam.study.status.current_state`: its checkpoint
    on the model of its design.toml, not an equilibrium), or None where it has no checkpoint."""
    from hydrojam.actuator.results import vtu_mesh
    from hydrojam.study.status import current_state

    got = current_state(point_dir)
    if got is None:
        return None
    model, state, releasing = got
    drawing = _drawing(vtu_mesh(model, state), "its checkpoint's state")
    where = "releasing" if releasing else f"s = {state.s:.2f}"
    return drawing, f"not finished: {where}, θ now {state.metrics['bending_angle_deg']:.1f}°"


def _angle_lines(row: dict, out: Path) -> str:
    """A panel title's bending angle: the row's; for a row of several runs, their mean and, where
    the run drawn (its ``point_dir``) ended at another angle, that run's, so the title matches
    the picture."""
    angle = number(row.get("bending_angle_deg"))
    if angle is None:
        return "\nθ: —"
    part = partial_runs(row)  # "1 of 3 runs" for a point not finished
    if runs_of(row) == 1:
        return f"\nθ = {angle:.1f}°" + (f" ({part})" if part else "")
    text = f"\nθ = {angle:.1f}° (mean of {part or f'{runs_of(row)} runs'})"
    drawn = drawn_angle(out, row)
    if drawn is not None and abs(drawn - angle) >= 0.05:
        text += f"\ndrawn: run with θ = {drawn:.1f}°"
    return text


def _not_in_state(row: dict) -> bool:
    """Whether a row of a state's table is empty because none of its replicas ended in that state
    (:func:`hydrojam.study.table.build_table`): not a failure."""
    return str(row.get("error") or "").startswith("no replica in state")


def _failure_text(row: dict, reason: str | None = None) -> str:
    """Why a panel is empty, wrapped to fit it."""
    if reason is None and (point_status(row) == PointStatus.UNFINISHED or _not_in_state(row)):
        return "\n".join(textwrap.wrap(str(row.get("error") or "not finished"), 28)[:6])
    err = reason or str(row.get("error") or "no result")
    return "\n".join(textwrap.wrap(f"failed: {err}", 28)[:6])


def _failure_colour(row: dict) -> str:
    """An empty panel's text colour: grey where nothing failed (not finished, or no replica in the
    state drawn), red otherwise."""
    return "0.3" if point_status(row) == PointStatus.UNFINISHED or _not_in_state(row) else "tab:red"


def plot_shapes(out: str | os.PathLike, rows: Sequence[dict], param: str, path: str | os.PathLike, *,
                label: str | None = None, unit: str | None = None) -> None:
    """Draw the deformed actuators of one sweep side by side (the paper's Figs. 6, 8, 10).

    One panel per point, sorted by ``param``, all at the same scale (shared limits, equal aspect):
    membrane light grey, strain-limit layer dark grey, particles blue, read from
    ``OUT/<point_dir>/final.vtu``; the undeformed outer outline dashed (from the point's
    design.toml); the title gives the parameter and the bending angle. A finished point without
    final.vtu (a kept record put back) is drawn as its strain-limit layer's mid-line, rebuilt from
    its centreline.csv (:func:`_centreline_drawing`), the line as made dashed; a failed point (or
    one with neither file) gets an empty panel saying why. An unfinished one (a table written
    without running) is drawn as it stands now, from its checkpoint (its title in grey says so:
    not an equilibrium), or where it has none, gets a panel saying so. A 3D point is drawn as its
    section y = 0 (the symmetry plane: half of every particle, the walls and the strain-limit
    layer cut through the middle), seen along -y, as in its ``final.png``; where PyVista is
    available (:func:`hydrojam.actuator.renders_available`), no point of a 3D sweep is unfinished
    and every point with a result has its final.vtu, each panel is instead a render of the whole
    actuator, all at one scale and on one swelling range under one colour bar (a point without a
    result: its panel says why). Lengths in mm.

    Parameters
    ----------
    out : str or os.PathLike
        The study's output folder OUT.
    rows : sequence of dict
        The sweep's rows of the results table.
    param : str
        The dotted design field varied (a column of ``rows``).
    path : str or os.PathLike
        The PNG file to write (atomically).
    label : str, optional
        The parameter's axis label without unit.
    unit : str, optional
        The parameter's unit.
    """
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    out = Path(out)
    symbol, _, unit = _sweep_for(param, label, unit)
    rows = sorted_by(rows, param)
    if _plot_renders(out, rows, param, path, symbol, unit, label):
        return
    panels = []
    for row in rows:
        pdir = out / str(row.get("point_dir") or "")
        panel = {"row": row, "shape": None, "outline": None, "failed": None, "section": False, "now": None,
                 "line": None}
        if point_status(row) == PointStatus.UNFINISHED and not partial_runs(row) and row.get("point_dir"):
            try:
                current = _current_drawing(pdir)
            except Exception:  # noqa: BLE001 - a checkpoint being rewritten: the text panel instead
                current = None
            if current is None:
                panel["failed"] = _failure_text(row)
            else:
                (pts, tris, body, panel["outline"], panel["section"]), panel["now"] = current
                panel["shape"] = (pts, tris, body)
        elif without_result(row) or not row.get("point_dir"):
            panel["failed"] = _failure_text(row)
        else:
            try:
                pts, tris, body, panel["outline"], panel["section"] = _read_drawing(pdir)
                panel["shape"] = (pts, tris, body)
            except Exception as err:  # noqa: BLE001 - a figure must survive one bad file
                try:
                    panel["line"] = _centreline_drawing(pdir)
                except Exception:  # noqa: BLE001 - no centreline either: say why the mesh is missing
                    panel["failed"] = _failure_text(row, f"cannot read final.vtu ({type(err).__name__}: {err})")
        panels.append(panel)
    section = any(p["section"] for p in panels)
    n = max(len(panels), 1)
    ncols = min(n, SHAPES_MAX_COLUMNS)
    nrows = math.ceil(n / ncols)
    allp = [p["shape"][0] for p in panels if p["shape"] is not None]
    allp += [p["outline"] for p in panels if p["outline"] is not None]
    allp += [np.vstack(p["line"]) for p in panels if p["line"] is not None]
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
    colours = {MEMBRANE_BODY: _COLOURS["membrane"], STRAIN_LIMIT_BODY: _COLOURS["strain_limit"]}
    for ax, panel in zip(axes.flat, panels):
        row = panel["row"]
        value = number(row.get(param))
        head = f"{symbol} = {fmt_param(value, unit)}"
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
                    color=_failure_colour(row))
            continue
        title = head + _angle_lines(row, out)
        if panel["line"] is not None:
            line, made = panel["line"]
            ax.plot(made[:, 0], made[:, 1], "--", color="0.4", lw=0.8, zorder=3)
            ax.plot(line[:, 0], line[:, 1], "-", color=_COLOURS["strain_limit"], lw=2.0, zorder=4)
            ax.plot(line[-1, 0], line[-1, 1], "o", color=_COLOURS["strain_limit"], ms=3, zorder=5)
            ax.set_title(title + "\n(mid-line only)", fontsize=9)
            continue
        pts, tris, body = panel["shape"]
        order = np.argsort(body, kind="stable")  # particles drawn last, over the walls
        tris, body = tris[order], body[order]
        face = [colours.get(int(b), _COLOURS["particle"]) for b in body]
        ax.add_collection(PolyCollection(pts[tris], facecolors=face, edgecolors="face", linewidths=0.3))
        ax.add_collection(LineCollection(pts[_body_outlines(tris, body)], colors="0.2", linewidths=0.4))
        if panel["now"] is not None:
            ax.set_title(f"{head}\n{panel['now']}", fontsize=9, color="0.4")
            continue
        if point_status(row) == PointStatus.NOT_CONVERGED:
            title += " (not converged)"
        ax.set_title(title, fontsize=9, color="tab:red" if point_status(row) == PointStatus.NOT_CONVERGED else "k")
    has_lines = any(p["line"] is not None for p in panels)
    lines_only = has_lines and all(p["shape"] is None for p in panels)
    handles = [] if lines_only else [Patch(color=_COLOURS["membrane"], label="membrane"),
                                     Patch(color=_COLOURS["strain_limit"], label="strain-limit layer"),
                                     Patch(color=_COLOURS["particle"], label="hydrogel particles")]
    handles.append(Line2D([], [], ls="--", color="0.5",
                          label="mid-line as made" if lines_only else "undeformed outline"))
    if has_lines:
        handles.append(Line2D([], [], color=_COLOURS["strain_limit"], lw=2.0,
                              label="strain-limit layer mid-line (centreline.csv; no final.vtu)"))
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 2 if ncols < 3 else 3),
               fontsize=8, frameon=False)
    where = "3D, section y = 0; " if section else ""
    now = "; grey titles: not finished, drawn as they stand (not equilibria)" if any(p["now"] for p in panels) else ""
    fig.suptitle(f"Deformed actuators, final states ({_sweep_for(param, label, unit)[1]}); "
                 f"{where}strain-limit layer on the -x side{now}", fontsize=10)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")


def _plot_renders(out: Path, rows: Sequence[dict], param: str, path, symbol: str, unit: str | None,
                  label: str | None) -> bool:
    """The shapes figure of a 3D sweep as renders (:class:`hydrojam.actuator.Renderer`), one
    panel per point, all framed by one box, cropped alike (one scale) and coloured on one
    swelling range under one colour bar; a failed point (or one with no replica in the state
    drawn) gets a panel saying why. Where PyVista is available, no point is unfinished and every
    other point has a 3D final.vtu. False (nothing written) otherwise."""
    import meshio
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    from hydrojam.actuator import SWELLING_CMAP, Renderer, renders_available, state_surfaces, swelling_range

    drawn = [r for r in rows if not without_result(r)]
    files = [out / str(r.get("point_dir") or "") / "final.vtu" for r in drawn]
    if (not drawn or any(point_status(r) == PointStatus.UNFINISHED for r in rows)
            or any(not r.get("point_dir") or not f.is_file() for r, f in zip(drawn, files))):
        return False
    meshes = [meshio.read(f) for f in files]
    if any(m.cells[0].type != "tetra10" for m in meshes) or not renders_available(say=False):
        return False
    try:
        surfs = [state_surfaces(m) for m in meshes]
    except (KeyError, ValueError):  # a final.vtu without results.write_vtu's fields: the sections
        return False
    both = np.vstack([np.vstack([s.points, s.reference]) for s in surfs])
    gel = np.concatenate([s.swelling[s.group("particles")] for s in surfs])
    clim = swelling_range(gel) if len(gel) else None
    with Renderer((640, 600), bounds=[both.min(axis=0), both.max(axis=0)], clim=clim) as renderer:
        images = {id(r): renderer.draw(surf, scale_bar=False) for r, surf in zip(drawn, surfs)}
    # one crop for all: the box of every image's ink, so the panels keep one scale
    ink = np.zeros(next(iter(images.values())).shape[:2], dtype=bool)
    for im in images.values():
        ink |= (im < 250).any(axis=2)
    ys, xs = np.nonzero(ink)
    if len(ys):
        m = 8
        crop = (slice(max(ys.min() - m, 0), ys.max() + m + 1), slice(max(xs.min() - m, 0), xs.max() + m + 1))
        images = {k: im[crop] for k, im in images.items()}
    h, w = next(iter(images.values())).shape[:2]
    n = len(rows)
    ncols = min(n, SHAPES_MAX_COLUMNS)
    nrows = math.ceil(n / ncols)
    panel_w = 3.0
    fig = Figure(figsize=(panel_w * ncols + 0.4, (panel_w * h / w + 0.55) * nrows + 1.3), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    for ax in axes.flat:
        ax.set_axis_off()
    for ax, row in zip(axes.flat, rows):
        head = f"{symbol} = {fmt_param(number(row.get(param)), unit)}"
        if id(row) not in images:
            ax.imshow(np.full((h, w, 3), 255, dtype=np.uint8))
            ax.set_title(head, fontsize=9)
            ax.text(0.5, 0.5, _failure_text(row), transform=ax.transAxes, ha="center", va="center", fontsize=7,
                    color=_failure_colour(row))
            continue
        ax.imshow(images[id(row)])
        title = head + _angle_lines(row, out)
        bad = point_status(row) == PointStatus.NOT_CONVERGED
        ax.set_title(title + (" (not converged)" if bad else ""), fontsize=9, color="tab:red" if bad else "k")
    if clim is not None:
        bar = fig.colorbar(ScalarMappable(Normalize(*clim), colormaps[SWELLING_CMAP]), ax=axes, location="bottom",
                           shrink=min(0.6, 2.4 / ncols + 0.2), aspect=40, pad=0.02)
        bar.set_label("particle swelling ratio J (one range for every panel)", fontsize=8)
        bar.ax.tick_params(labelsize=7)
    fig.suptitle(f"Deformed actuators, final states ({_sweep_for(param, label, unit)[1]}); 3D renders at one scale\n"
                 "membrane translucent, strain-limit layer orange, undeformed outline grey", fontsize=10)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")
    return True


def state_series(states: dict | None, param: str) -> dict[str, tuple[list, list, list]]:
    """Each state's θ against the parameter, where a sweep's runs reach two states or more.

    Parameters
    ----------
    states : dict of str to sequence of dict, or None
        State -> the sweep's rows of that state's runs alone
        (:func:`hydrojam.study.table.state_tables`, selected to the sweep).
    param : str
        The dotted design field varied.

    Returns
    -------
    dict of str to (list, list, list)
        State -> the parameter values, the state's mean θ [deg] and its standard deviation [deg]
        (0 for one run) at the points with a run in it; empty where fewer than two states occur.
    """
    series = {}
    for state, rows in (states or {}).items():
        xs, ys, err = [], [], []
        for r in sorted_by(rows, param):
            p, v = number(r.get(param)), number(r.get("bending_angle_deg"))
            if p is None or v is None or without_result(r):
                continue
            xs.append(p)
            ys.append(v)
            err.append(number(r.get("bending_angle_deg_std")) or 0.0)
        if xs:
            series[state] = (xs, ys, err)
    return series if len(series) > 1 else {}


def plot_trends(rows: Sequence[dict], param: str, path: str | os.PathLike, label: str, unit: str, *,
                curling: bool | None = None, states: dict | None = None) -> None:
    """Plot the bending angle and free-end displacement magnitudes |δx|, |δz| against the parameter
    (the paper's Figs. 7, 9, 11), and optionally the curling index.

    Markers and lines; a non-converged point is drawn hollow, a failed one (or one not finished,
    in a table written without running) is left out and named under the figure. Rows of
    replicated points (``<metric>_std``, ``_min``, ``_max`` columns) are drawn at their mean with
    error bars of ± one standard deviation and a band over the replicas' range (of magnitudes, for
    |δx| and |δz|).

    Parameters
    ----------
    rows : sequence of dict
        The sweep's rows of the results table: angles [deg], displacements [mm].
    param : str
        The dotted design field varied (a column of ``rows``).
    path : str or os.PathLike
        The PNG file to write (atomically).
    label : str
        The parameter's axis label without unit.
    unit : str
        The parameter's unit.
    curling : bool, optional
        Also the curling index [-] (default: for ``particle_layers``).
    states : dict of str to sequence of dict, optional
        State -> the sweep's rows of that state's runs alone: where the runs reach two states or
        more, each state's mean θ (± its standard deviation) is drawn too, dashed
        (:func:`state_series`), since the mean over all runs describes neither.
    """
    from matplotlib.lines import Line2D

    rows = sorted_by(rows, param)
    if curling is None:
        curling = param == "particle_layers"
    quantities = [("bending_angle_deg", False, "bending angle θ [deg]\n(> 0: toward the strain-limit layer)")]
    n_ax = 3 if curling else 2
    fig = Figure(figsize=(4.4 * n_ax, 4.4), layout="constrained")
    axes = fig.subplots(1, n_ax)
    xlabel = f"{label} [{unit}]" if unit else label

    replicas = [number(r.get("replicas")) for r in rows if number(r.get("replicas"))]

    def draw(ax, key, magnitude, colour, marker, name):
        xs, ys, hollow, err, lo, hi = [], [], [], [], [], []
        for r in rows:
            p, v = number(r.get(param)), number(r.get(key))
            if p is None or v is None or without_result(r):
                continue
            xs.append(p)
            ys.append(abs(v) if magnitude else v)
            hollow.append(point_status(r) == PointStatus.NOT_CONVERGED)
            err.append(number(r.get(f"{key}_std")) or 0.0)
            ends = [number(r.get(f"{key}_min")), number(r.get(f"{key}_max"))]
            ends = [ys[-1] if e is None else (abs(e) if magnitude else e) for e in ends]
            if magnitude and ends[0] * ends[1] < 0:  # the replicas' signs differ: the range reaches 0
                ends = [0.0, max(ends)]
            lo.append(min(ends))
            hi.append(max(ends))
        xs, ys, hollow = np.array(xs), np.array(ys), np.array(hollow, dtype=bool)
        ax.plot(xs, ys, "-", color=colour, lw=1.2, label=name)
        if any(err):
            ax.fill_between(xs, lo, hi, color=colour, alpha=0.15, lw=0)
            ax.errorbar(xs, ys, yerr=err, fmt="none", ecolor=colour, elinewidth=1.0, capsize=3)
        ax.plot(xs[~hollow], ys[~hollow], marker, color=colour, ms=6, ls="none")
        ax.plot(xs[hollow], ys[hollow], marker, ms=6, ls="none", mfc="white", mec=colour, mew=1.5)
        return bool(hollow.any())

    any_hollow = draw(axes[0], *quantities[0][:2], "C0", "o", "θ")
    axes[0].set_ylabel(quantities[0][2])
    by_state = state_series(states, param)
    for k, (state, (xs, ys, err)) in enumerate(by_state.items()):
        colour, marker = ("0.25", "0.55", "C5", "C6")[k % 4], ("v", "P", "X", "h")[k % 4]
        axes[0].errorbar(xs, ys, yerr=err, color=colour, ls="--", lw=1.0, marker=marker, ms=5, capsize=2,
                         label=f"{state} runs")
    if by_state:
        axes[0].legend(fontsize=8)
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
        handles, _ = axes[0].get_legend_handles_labels()
        axes[0].legend(handles=handles + notes, fontsize=8)
    caption = ("|δx|, |δz|: magnitudes of the free-end displacement, as the paper plots them "
               "(signed in the report: δx < 0 toward the strain-limit layer, δz < 0 downward)")
    if replicas and max(replicas) > 1:
        caption += (f"\nmeans of {max(replicas):.0f} replicas per point; error bars ± one standard deviation, "
                    "bands the replicas' range")
    if by_state:
        caption += "\ndashed: θ of each state's runs alone (mean ± standard deviation), where the runs reach several"
    failed = [r for r in rows if point_status(r) == PointStatus.FAILED]
    sym, _, u = _sweep_for(param, label, unit)
    partial = [r for r in rows if partial_runs(r)]
    if partial:
        caption += "\nnot finished, drawn with the runs finished: " + ", ".join(
            f"{sym} = {fmt_param(number(r.get(param)), u)} ({partial_runs(r)})" for r in partial)
    unfinished = [r for r in rows if point_status(r) == PointStatus.UNFINISHED and not partial_runs(r)]
    for what, left in (("failed", failed), ("not finished", unfinished)):
        if left:
            caption += f"\n{what} (not drawn): " + ", ".join(f"{sym} = {fmt_param(number(r.get(param)), u)}"
                                                           for r in left)
    fig.supxlabel(caption, fontsize=8, color="tab:red" if failed else "0.3")
    fig.suptitle(f"Bending angle and free-end displacement against {label}", fontsize=10)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")


def figure_names(sweep: PaperSweep) -> tuple[str, str]:
    """The sweep's shapes and trends figures, relative to OUT."""
    return f"figures/{sweep.name}_shapes.png", f"figures/{sweep.name}_trends.png"


def state_figure_name(sweep: PaperSweep, state: str) -> str:
    """The sweep's shapes figure of one state's runs ("figures/temperature_shapes_folded.png")."""
    return f"figures/{sweep.name}_shapes_{state}.png"


def write_figures(out: str | os.PathLike, table, states: dict | None = None) -> list[Path]:
    """Write both figures of every sweep into ``OUT/figures/``.

    The figures are ``<sweep>_shapes.png`` (:func:`plot_shapes`) and ``<sweep>_trends.png``
    (:func:`plot_trends`); a sweep without rows is skipped. Where a sweep's runs reach two states
    or more, each state they reached also gets ``<sweep>_shapes_<state>.png``: every point drawn
    as one replica in that state (a point with none says so), and the trends figure draws each
    state's θ beside the mean over all runs; a state none reached, or a sweep's only state, gets
    none (an earlier one is removed).

    Parameters
    ----------
    out : str or os.PathLike
        The study's output folder OUT.
    table : SweepTable or list of dict
        The study's results.
    states : dict of str to SweepTable, optional
        State -> the table of its runs alone (:func:`hydrojam.study.table.state_tables`).

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(out)
    written = []
    for sw in PAPER_SWEEPS:  # a sweep not in the table (another dimension's, or not run) draws nothing
        rows = rows_of(table, sw.name)
        if not rows:
            continue
        shapes, trends = (out / name for name in figure_names(sw))
        by_state = {state: rows_of(t, sw.name) for state, t in (states or {}).items()}
        plot_shapes(out, [drawn_row(out, r) for r in rows], sw.field, shapes)
        plot_trends(rows, sw.field, trends, sw.label, sw.unit, states=by_state)
        written += [shapes, trends]
        reached = [state for state, r in by_state.items() if not all(without_result(x) for x in r)]
        for state, state_rows in by_state.items():
            path = out / state_figure_name(sw, state)
            if len(reached) < 2 or state not in reached:  # the sweep's shapes figure shows its one state
                path.unlink(missing_ok=True)
                continue
            plot_shapes(out, state_rows, sw.field, path, label=f"{sw.label} ({state})", unit=sw.unit)
            written.append(path)
    return written
