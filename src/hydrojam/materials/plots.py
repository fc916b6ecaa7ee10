"""The gel's free-swelling curve as a figure (matplotlib, written atomically as PNG).

Figures are drawn on a :class:`matplotlib.figure.Figure` without pyplot, so a notebook user's
backend is never changed."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from hydrojam._io import atomic_path
from hydrojam.materials.energies import WATER_RANGE_K, HydrogelParams
from hydrojam.materials.swelling import SwellingState, Transition, swelling_curve


def plot_swelling_curve(
    params: HydrogelParams,
    mu: float,
    points: Sequence[SwellingState],
    transition: Transition,
    path: str | os.PathLike,
) -> None:
    """Plot the free-swelling stretch (from the as-prepared state) against temperature at one mu.

    A dense curve over the plotted range, the requested points as markers, the transition
    temperature marked, and the as-prepared state (stretch 1 at T0) for orientation.

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mu : float
        Chemical potential of the solvent [k_B T].
    points : sequence of SwellingState
        The requested states, plotted as markers.
    transition : Transition
        The volume phase transition at ``mu``.
    path : str or os.PathLike
        The PNG file to write (atomically).
    """
    Ts = np.array([p.T for p in points])
    lo, hi = min(Ts.min(), transition.T) - 2.0, max(Ts.max(), transition.T) + 2.0
    lo, hi = max(lo, WATER_RANGE_K[0]), min(hi, WATER_RANGE_K[1])
    dense = np.linspace(lo, hi, 241)
    _, curve = swelling_curve(params, mu, dense)
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
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
