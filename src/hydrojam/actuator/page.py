"""A run's HTML page ``report.html``: its metrics, figures and (3D) an interactive view of its
final state, in one self-contained file that opens offline (:mod:`hydrojam._html`)."""

from __future__ import annotations

import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np

from hydrojam._html import figure_html, page_html, scene_group, scene_html, table_html
from hydrojam._io import write_text_atomic
from hydrojam.actuator.render import (MEMBRANE_OPACITY, MEMBRANE_RGB, OUTLINE_RGB, STRAIN_LIMIT_RGB, SWELLING_CMAP,
                                      state_surfaces, swelling_range)

#: the figures a run's page shows, with their captions, where the folder holds them
FIGURES = [("final.png", "the final state: section and centreline (3D: and a render)"),
           ("angle_time.png", "the bending angle and the free-end displacement against time"),
           ("movie.gif", "the actuation, as prepared to the end (hydrojam animate)")]


def state_view(mesh, key: str, title: str = "") -> str:
    """The interactive 3D view (HTML) of one 3D state as a VTU file holds it: particles coloured
    by swelling ratio, the strain-limit layer, the membrane (translucent) and the undeformed
    outline, each a group with its check box."""
    from matplotlib import colormaps

    surf = state_surfaces(mesh)
    cmap = colormaps[SWELLING_CMAP]
    groups = []
    gel = surf.group("particles")
    scale = None
    if gel.any():
        lo, hi = swelling_range(surf.swelling[gel])
        tris = surf.triangles[gel]
        total = np.zeros(len(surf.points))
        count = np.zeros(len(surf.points))
        np.add.at(total, tris.ravel(), np.repeat(surf.swelling[gel], 3))
        np.add.at(count, tris.ravel(), 1.0)
        value = np.divide(total, count, out=np.full(len(total), lo), where=count > 0)
        rgb = cmap(np.clip((value - lo) / (hi - lo), 0.0, 1.0))[:, :3]
        groups.append(scene_group("particles", "particles", surf.points, tris, vertex_rgb=rgb))
        stops = [f"rgb({', '.join(str(int(255 * c)) for c in cmap(t)[:3])})" for t in np.linspace(0, 1, 6)]
        scale = ("particle swelling ratio J", lo, hi, stops)
    for name, label, rgb, opacity in (("strain_limit", "strain-limit layer", STRAIN_LIMIT_RGB, 1.0),
                                      ("membrane", "membrane", MEMBRANE_RGB, MEMBRANE_OPACITY)):
        mask = surf.group(name)
        if mask.any():
            groups.append(scene_group(name, label, surf.points, surf.triangles[mask], color=rgb, opacity=opacity))
    if len(surf.outline):
        groups.append(scene_group("outline", "outline as prepared", surf.reference, surf.outline, color=OUTLINE_RGB,
                                  opacity=0.45))
    return scene_html(key, groups, title=title, scale=scale)


def final_state(out: str | os.PathLike):
    """The final state a run's folder holds (the last step of results.pvd, else final.vtu), or None."""
    out = Path(out)
    pvd = out / "results.pvd"
    if pvd.is_file():
        files = [ds.get("file") for ds in ET.parse(pvd).getroot().iter("DataSet")]
        if files and (out / files[-1]).is_file():
            return meshio.read(out / files[-1])
    if (out / "final.vtu").is_file():
        return meshio.read(out / "final.vtu")
    return None


def _summary(m: dict) -> str:
    def f(k, fmt):
        v = m.get(k)
        return "n/a" if v is None else format(v, fmt)
    return (f"<p><b>bending angle {f('bending_angle_deg', '.1f')} deg</b>, free end dx {f('tip_dx_mm', '.2f')} mm, "
            f"dz {f('tip_dz_mm', '.2f')} mm at T = {f('temperature_K', '.1f')} K; solver: {m.get('message', 'n/a')} "
            f"(s reached {f('s_reached', '.3g')}, {m.get('newton_iterations', 'n/a')} Newton iterations, "
            f"{f('wall_time_s', '.1f')} s).</p>")


def run_page(out: str | os.PathLike, final=None) -> str:
    """The HTML page of the run in folder ``out`` (metrics.json, design.toml and the figures it
    holds; ``final``: the final state's VTU mesh, default :func:`final_state`)."""
    import html

    out = Path(out)
    parts = [f"<h1>hydrojam run: {html.escape(out.resolve().name)}</h1>"]
    mfile = out / "metrics.json"
    metrics = json.loads(mfile.read_text()) if mfile.is_file() else {}
    if metrics:
        parts.append(_summary(metrics))
    final = final_state(out) if final is None else final
    if final is not None and final.cells[0].type == "tetra10":
        parts.append("<h2>Final state in 3D</h2>")
        parts.append(state_view(final, "hj-final"))
    for name, caption in FIGURES:
        if (out / name).is_file():
            parts.append(f"<h2>{html.escape(name)}</h2>" + figure_html(out / name, caption))
    if metrics:
        rows = [[k, v] for k, v in metrics.items() if not isinstance(v, (dict, list))]
        parts.append("<h2>Metrics</h2>" + table_html(["metric", "value"], rows))
        for k, v in metrics.items():
            if isinstance(v, (dict, list)):
                parts.append(f"<details><summary>{html.escape(k)}</summary><pre>"
                             f"{html.escape(json.dumps(v, indent=2))}</pre></details>")
    if (out / "design.toml").is_file():
        parts.append("<h2>Design</h2><details><summary>design.toml (resolved)</summary><pre>"
                     f"{html.escape((out / 'design.toml').read_text())}</pre></details>")
    return page_html(f"hydrojam run: {out.resolve().name}", "\n".join(parts))


def write_run_page(out: str | os.PathLike, final=None) -> Path:
    """Write ``out/report.html`` (:func:`run_page`), atomically; returns its path."""
    path = Path(out) / "report.html"
    write_text_atomic(path, run_page(out, final))
    return path


__all__ = ["run_page", "write_run_page", "state_view", "final_state", "FIGURES"]
