"""Figures (matplotlib, Agg backend), written atomically as PNG."""

from __future__ import annotations

import os
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ._io import atomic_path  # noqa: E402
from .materials import HydrogelParams  # noqa: E402
from .swelling import SwellingState, Transition, swelling_curve  # noqa: E402


def plot_swelling_curve(
    params: HydrogelParams,
    mu: float,
    points: Sequence[SwellingState],
    transition: Transition,
    path: str | os.PathLike,
) -> None:
    """Free-swelling stretch (from the as-prepared state) against temperature [K] at one mu [k_B T].

    A dense curve over the plotted range, the requested points as markers, the transition
    temperature marked, and the as-prepared state (stretch 1 at T0) for orientation.
    """
    Ts = np.array([p.T for p in points])
    lo, hi = min(Ts.min(), transition.T) - 2.0, max(Ts.max(), transition.T) + 2.0
    lo, hi = max(lo, 273.15), min(hi, 373.15)
    dense = np.linspace(lo, hi, 241)
    _, curve = swelling_curve(params, mu, dense)
    fig, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
    for branch, colour in (("swollen", "tab:blue"), ("collapsed", "tab:red")):
        sel = np.array([c.branch == branch for c in curve])
        if sel.any():
            ax.plot(dense[sel], [c.stretch_rel for c, s in zip(curve, sel) if s], "-", color=colour,
                    label=f"{branch} branch")
    ax.plot(Ts, [p.stretch_rel for p in points], "ko", ms=4, label="requested temperatures")
    kind = "discontinuous" if transition.discontinuous else "continuous"
    ax.axvline(transition.T, color="0.4", ls="--", lw=1)
    ax.annotate(f"transition {transition.T:.1f} K ({kind})", (transition.T, ax.get_ylim()[1]),
                xytext=(-4, -14), textcoords="offset points", ha="right", fontsize=8, color="0.3")
    ax.axhline(1.0, color="0.7", lw=0.8)
    ax.set_xlabel("temperature T [K]")
    ax.set_ylabel("free-swelling stretch from as-prepared state, λ/λ0 [-]")
    ax.set_title(f"PNIPAM free swelling at μ = {mu:g} kT (Nν = {params.n:g}, λ0 = {params.lambda0:g})", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=150, format="png")
    plt.close(fig)


_TRI6_SPLIT = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])


def _outline_segments(mesh) -> np.ndarray:
    """Boundary facets of a mesh as straight pieces (k, 2) of node indices."""
    f = mesh.boundary_facets()
    return f[:, [0, 2, 2, 1]].reshape(-1, 2) if f.shape[1] == 3 else f


def plot_actuator(model, state, path: str | os.PathLike) -> None:
    """The actuator at ``state`` over its undeformed outline (left) and the centreline curvature
    profile (right). Particles coloured by swelling ratio (gel volume / dry volume); membrane
    light grey, strain-limit layer dark grey. Lengths in mm."""
    from matplotlib.collections import LineCollection, PolyCollection

    from .metrics import centreline_profile
    from .model import PARTICLE_BODY
    from .results import cell_fields

    mesh, X, x = model.mesh, model.mesh.points, state.x
    fields = cell_fields(model, x, state.s)
    cells = mesh.cells
    tris = cells[:, _TRI6_SPLIT].reshape(-1, 3) if cells.shape[1] == 6 else cells
    rep = 4 if cells.shape[1] == 6 else 1
    body = np.repeat(fields["body_id"], rep)
    swell = np.repeat(fields["swelling_ratio"], rep)
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 6.5), gridspec_kw={"width_ratios": [1.25, 1]})
    seg = _outline_segments(mesh)
    ax.add_collection(LineCollection(X[seg], colors="0.55", linewidths=0.7, linestyles="--"))
    gel = body >= PARTICLE_BODY
    polys = PolyCollection(x[tris[~gel]], facecolors=np.where(body[~gel, None] == 0, [[0.82] * 3], [[0.45] * 3]),
                           edgecolors="face", linewidths=0.2)
    ax.add_collection(polys)
    lo, hi = float(swell[gel].min()), float(swell[gel].max())
    if hi - lo < 1e-3 * hi:  # uniform (e.g. as prepared): a readable range around it
        lo, hi = 0.95 * lo, 1.05 * hi
    pc = PolyCollection(x[tris[gel]], array=swell[gel], cmap="viridis", edgecolors="face", linewidths=0.2)
    pc.set_clim(lo, hi)
    ax.add_collection(pc)
    ax.add_collection(LineCollection(x[seg], colors="k", linewidths=0.5))
    allp = np.vstack([X, x])
    pad = 0.05 * np.ptp(allp, axis=0).max()
    ax.set_xlim(allp[:, 0].min() - pad, allp[:, 0].max() + pad)
    ax.set_ylim(allp[:, 1].min() - pad, allp[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]  (strain-limit layer on the -x side)")
    ax.set_ylabel("z [mm]")
    fig.colorbar(pc, ax=ax, shrink=0.8, label="particle swelling ratio J (volume / dry volume)")
    m = state.metrics
    ax.set_title(f"T = {state.T:.1f} K, mu = {state.mu:.3g} kT, s = {state.s:.3g}\n"
                 f"bending angle {m['bending_angle_deg']:.1f} deg, tip dx {m['tip_dx_mm']:.1f} mm, "
                 f"dz {m['tip_dz_mm']:.1f} mm", fontsize=10)
    cl = model.centreline_nodes
    prof = centreline_profile(X[cl], x[cl])
    ax2.plot(prof.reference_arc_length, prof.curvature * 1e3, "-", color="C0")
    ax2.axhline(0.0, color="0.6", lw=0.7)
    k_max = float(np.max(np.abs(prof.curvature))) * 1e3
    if k_max < 1e-6:  # straight: no scale to show round-off at
        ax2.set_ylim(-1.0, 1.0)
    ax2.set_xlabel("arc length from the clamp, as prepared [mm]")
    ax2.set_ylabel("centreline curvature [1/m]  (> 0: toward the strain-limit layer)")
    ci = m.get("curling_index")
    ax2.set_title("strain-limit layer mid-line" + ("" if ci is None else f", curling index {ci:.2f}"), fontsize=10)
    ax3 = ax2.twinx()
    ax3.plot(prof.reference_arc_length, np.degrees(prof.rotation), "--", color="C1")
    ax3.set_ylabel("rotation [deg] (dashed)", color="C1")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
