"""The actuator's figure ``final.png`` (matplotlib, written atomically as PNG).

Figures are drawn on a :class:`matplotlib.figure.Figure` without pyplot, so a notebook user's
backend is never changed."""

from __future__ import annotations

import os

import numpy as np
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure

from hydrojam._io import atomic_path
from hydrojam.actuator.fields import cell_fields
from hydrojam.actuator.metrics import centreline_profile, turned_to_plane
from hydrojam.actuator.model import PARTICLE_BODY
from hydrojam.fem.elements import ELEMENTS, straight_pieces


#: colour maps of each chamber's gel in a multi-chamber design's figures (matplotlib's names),
#: chamber by chamber; a single chamber's gel keeps viridis
CHAMBER_CMAPS = ("Blues", "Oranges", "Greens")


def chamber_cmap(k: int):
    """The colour map of chamber ``k``'s gel: the upper two thirds of :data:`CHAMBER_CMAPS` [k]
    (their pale ends would vanish on the white page)."""
    import matplotlib
    from matplotlib.colors import ListedColormap

    base = matplotlib.colormaps[CHAMBER_CMAPS[k % len(CHAMBER_CMAPS)]]
    return ListedColormap(base(np.linspace(0.35, 1.0, 256)), name=f"chamber{k}")


def _outline_segments(mesh) -> np.ndarray:
    """Boundary facets of a 2D mesh as straight pieces (k, 2) of node indices."""
    return straight_pieces(mesh.boundary_facets(), 1)


def mid_section(X: np.ndarray, cells: np.ndarray, length: float, fields: dict):
    """A 3D actuator's section y = 0 as straight triangles: (triangles (k, 3) of node indices,
    body id and swelling ratio of each, outline segments (m, 2)), from its reference node
    positions X (n, 3) [mm], its tetra10 cells (c, 10), its length [mm] (the scale of the
    tolerance) and the cell fields "body_id" and "swelling_ratio". The faces of the cells on the
    y >= 0 side that lie on the plane y = 0 (the half model's cut faces, the whole model's
    mid-plane), each tri6 split into 4 triangles; the outline is their edges used once."""
    tol = 1e-6 * length
    local = ELEMENTS["tet10"].facets  # (4, 6) tri6 faces of a tetra10
    upper = np.flatnonzero(X[cells[:, :4], 1].mean(axis=1) > 0.0)
    faces = cells[upper][:, local]  # (c, 4, 6)
    flat = np.all(np.abs(X[faces[..., :3], 1]) < tol, axis=2)
    owner = np.repeat(upper[:, None], local.shape[0], axis=1)[flat]
    faces = faces[flat]
    tris = straight_pieces(faces, 2)
    body = np.repeat(fields["body_id"][owner], 4)
    swell = np.repeat(fields["swelling_ratio"][owner], 4)
    edges = straight_pieces(faces[:, ELEMENTS["tri6"].facets].reshape(-1, 3), 1)  # each face's rim
    _, first, counts = np.unique(np.sort(edges, axis=1), axis=0, return_index=True, return_counts=True)
    return tris, body, swell, edges[first[counts == 1]]


def _trimmed(img: np.ndarray) -> np.ndarray:
    """An image without its white margins (a margin of 2 % of its size kept)."""
    ink = np.flatnonzero(np.any(img < 250, axis=(1, 2))), np.flatnonzero(np.any(img < 250, axis=(0, 2)))
    if not len(ink[0]):
        return img
    pad = int(0.02 * max(img.shape[:2]))
    r0, r1 = max(ink[0][0] - pad, 0), min(ink[0][-1] + pad + 1, img.shape[0])
    c0, c1 = max(ink[1][0] - pad, 0), min(ink[1][-1] + pad + 1, img.shape[1])
    return img[r0:r1, c0:c1]


def plot_actuator(model, state, path: str | os.PathLike, render: np.ndarray | None = None,
                  render_title: str = "") -> None:
    """Draw the actuator at a state over its undeformed outline (left) and the centreline curvature
    profile (right); with ``render``, that 3D picture first.

    Particles coloured by swelling ratio (gel volume / dry volume), each chamber's gel in its own
    colour map where there are several (:data:`CHAMBER_CMAPS`); membrane light grey,
    strain-limit layer dark grey. Lengths in mm. A 3D actuator is drawn as its section y = 0 (the
    symmetry plane: half of every particle, the walls and the strain-limit layer cut through the
    middle), seen along -y.

    Parameters
    ----------
    model : ActuatorModel
        The model.
    state : StepState
        The state drawn (positions [mm]).
    path : str or os.PathLike
        The PNG file to write.
    render : ndarray, shape (h, w, 3), optional
        A 3D render of the state (:mod:`hydrojam.actuator.render`), drawn left of the section.
    render_title : str
        The render's title.
    """
    mesh, X, x = model.mesh, model.mesh.points, state.x
    fields = cell_fields(model, x, state.s)
    if mesh.dim == 3:
        tris, body, swell, seg = mid_section(X, mesh.cells, model.design.length, fields)
        X, x = X[:, [0, 2]], x[:, [0, 2]]
    else:
        cells = mesh.cells
        tris = straight_pieces(cells, 2)
        rep = len(tris) // len(cells)
        body = np.repeat(fields["body_id"], rep)
        swell = np.repeat(fields["swelling_ratio"], rep)
        seg = _outline_segments(mesh)
    if render is None:
        fig = Figure(figsize=(11, 6.5))
        ax, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.25, 1]})
    else:
        fig = Figure(figsize=(18, 6.5))
        ax0, ax, ax2 = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.3, 1.25, 1]})
        ax0.imshow(_trimmed(render))
        ax0.set_axis_off()
        ax0.set_title("3D, the whole actuator (membrane translucent, outline as prepared)\n" + render_title, fontsize=10)
    ax.add_collection(LineCollection(X[seg], colors="0.55", linewidths=0.7, linestyles="--"))
    gel = body >= PARTICLE_BODY
    polys = PolyCollection(x[tris[~gel]], facecolors=np.where(body[~gel, None] == 0, [[0.82] * 3], [[0.45] * 3]),
                           edgecolors="face", linewidths=0.2)
    ax.add_collection(polys)
    lo, hi = float(swell[gel].min()), float(swell[gel].max())
    if hi - lo < 1e-3 * hi:  # uniform (e.g. as prepared): a readable range around it
        lo, hi = 0.95 * lo, 1.05 * hi
    chambers = model.design.resolved_chambers
    if chambers is None:
        pc = PolyCollection(x[tris[gel]], array=swell[gel], cmap="viridis", edgecolors="face", linewidths=0.2)
        pc.set_clim(lo, hi)
        ax.add_collection(pc)
        bars = [(pc, "particle swelling ratio J (volume / dry volume)")]
    else:  # each chamber's gel in its own colours, one swelling scale
        counts = [ch.particle_layers * ch.particles_per_layer for ch in chambers]
        owner = np.repeat(np.arange(len(chambers)), counts)[np.maximum(body - PARTICLE_BODY, 0)]
        bars = []
        for k, ch in enumerate(chambers):
            mine = gel & (owner == k)
            pc = PolyCollection(x[tris[mine]], array=swell[mine], cmap=chamber_cmap(k), edgecolors="face",
                                linewidths=0.2)
            pc.set_clim(lo, hi)
            ax.add_collection(pc)
            bars.append((pc, f"chamber {k} ({ch.temperature:g} K): J"))
    ax.add_collection(LineCollection(x[seg], colors="k", linewidths=0.5))
    allp = np.vstack([X, x])
    pad = 0.05 * np.ptp(allp, axis=0).max()
    ax.set_xlim(allp[:, 0].min() - pad, allp[:, 0].max() + pad)
    ax.set_ylim(allp[:, 1].min() - pad, allp[:, 1].max() + pad)
    ax.set_aspect("equal")
    layout = "  (strain-limit layer on the -x side)"
    if chambers is not None:
        layout = "  (chamber 0 on +x; 1, 2 at 120, 240 deg)" if model.design.round_axis else "  (chambers side by side)"
    ax.set_xlabel("x [mm]" + layout)
    ax.set_ylabel("z [mm]")
    if len(bars) == 1:
        fig.colorbar(bars[0][0], ax=ax, shrink=0.8, label=bars[0][1])
    for k, (pc, label) in reversed(list(enumerate(bars if len(bars) > 1 else ()))):
        # one thin bar a chamber, stacked below, chamber 0 on top (each bar is placed right under
        # the axes, pushing the ones before it down): the top one clears the axis label
        fig.colorbar(pc, ax=ax, orientation="horizontal", shrink=0.8, label=label, fraction=0.04,
                     pad=0.14 if k == 0 else 0.07, aspect=40)
    m = state.metrics
    where = "3D, section y = 0; " if mesh.dim == 3 else ""
    ax.set_title(f"{where}T = {state.T:.1f} K, mu = {state.mu:.3g} kT, s = {state.s:.3g}\n"
                 f"bending angle {m['bending_angle_deg']:.1f} deg, tip dx {m['tip_dx_mm']:.1f} mm, "
                 f"dz {m['tip_dz_mm']:.1f} mm", fontsize=10)
    cl = model.centreline_nodes
    if model.design.round_axis:  # the profile in the bending plane, as the metrics read it
        plane = m.get("bending_plane_deg")
        P, p = (turned_to_plane(q, 180.0 if plane is None else plane)[:, [0, 2]] for q in (mesh.points, state.x))
        prof = centreline_profile(P[cl], p[cl])
    else:
        prof = centreline_profile(X[cl], x[cl])
    ax2.plot(prof.reference_arc_length, prof.curvature * 1e3, "-", color="C0")
    ax2.axhline(0.0, color="0.6", lw=0.7)
    k_max = float(np.max(np.abs(prof.curvature))) * 1e3
    if k_max < 1e-6:  # straight: no scale to show round-off at
        ax2.set_ylim(-1.0, 1.0)
    ax2.set_xlabel("arc length from the clamp, as prepared [mm]")
    toward = "the strain-limit layer)" if chambers is None else "-x)"
    line = "strain-limit layer mid-line" if chambers is None else "shared wall's mid-line"
    if model.design.round_axis:
        toward, line = "the bending plane)", "axis, in the bending plane"
    ax2.set_ylabel("centreline curvature [1/m]  (> 0: toward " + toward)
    ci = m.get("curling_index")
    ax2.set_title(line + ("" if ci is None else f", curling index {ci:.2f}"), fontsize=10)
    ax3 = ax2.twinx()
    ax3.plot(prof.reference_arc_length, np.degrees(prof.rotation), "--", color="C1")
    ax3.set_ylabel("rotation [deg] (dashed)", color="C1")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")


def _time_unit(t_end: float) -> tuple[float, str]:
    """A readable unit for times up to ``t_end`` [s]: (seconds per unit, name)."""
    for scale, name in ((86400.0, "d"), (3600.0, "h"), (60.0, "min")):
        if t_end >= 3.0 * scale:
            return scale, name
    return 1.0, "s"


def plot_angle_time(states, schedule, path: str | os.PathLike) -> None:
    """Draw ``angle_time.png`` of a time-resolved run.

    The bending angle against time with the temperature schedule on a twin axis (top), and the
    free-end displacement against time (bottom).

    Parameters
    ----------
    states : sequence of StepState
        The accepted states, each with ``time_s`` [s].
    schedule : sequence of (float, float)
        The ((t_s [s], T_K [K]), ...) points.
    path : str or os.PathLike
        The PNG file to write.
    """
    t = np.array([st.time_s for st in states], dtype=float)
    pts = np.asarray(schedule, dtype=float)
    scale, unit = _time_unit(max(float(pts[-1, 0]), float(t.max())))
    theta = np.array([st.metrics["bending_angle_deg"] for st in states], dtype=float)
    dx = np.array([st.metrics["tip_dx_mm"] for st in states], dtype=float)
    dz = np.array([st.metrics["tip_dz_mm"] for st in states], dtype=float)
    fig = Figure(figsize=(8, 6.5))
    ax, ax2 = fig.subplots(2, 1, sharex=True)
    ax.plot(t / scale, theta, "o-", color="C0", ms=3)
    ax.set_ylabel("bending angle θ [deg]", color="C0")
    ax.set_title("actuation in time (each particle: free-swelling kinetics)", fontsize=10)
    axT = ax.twinx()
    axT.plot(pts[:, 0] / scale, pts[:, 1], "-", color="C3", lw=1.0)
    axT.set_ylabel("temperature T [K]", color="C3")
    ax2.plot(t / scale, dx, "o-", color="C0", ms=3, label="δx (bending direction)")
    ax2.plot(t / scale, dz, "s-", color="C1", ms=3, label="δz (axis)")
    ax2.axhline(0.0, color="0.6", lw=0.7)
    ax2.set_ylabel("free-end displacement [mm]")
    ax2.set_xlabel(f"time since the particles met the solvent [{unit}]")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
