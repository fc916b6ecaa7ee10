"""``OUT/report.html`` of the paper's study: ``report.md`` as one self-contained page (its
figures inlined, :mod:`hydrojam._html`) and, for a 3D study, an interactive 3D view of each
point's final state (its replica 0's ``final.vtu``)."""

from __future__ import annotations

import html
import os
from pathlib import Path

import meshio

from hydrojam._html import markdown_html, page_html
from hydrojam._io import write_text_atomic
from hydrojam.actuator import state_view
from hydrojam.paper._rows import drawn_angle, drawn_row, number, runs_of
from hydrojam.study.table import SweepTable

__all__ = ["write_report_page"]


def _final_views(out: Path, table: SweepTable) -> list[str]:
    """One 3D view per point folder of ``table`` whose ``final.vtu`` holds a 3D (tetra10) state,
    in table order; points without one (unfinished, failed, restored records) are left out."""
    views, seen = [], set()
    for row in (drawn_row(out, r) for r in table.rows):
        pdir = row.get("point_dir")
        if not pdir or pdir in seen or not (out / pdir / "final.vtu").is_file():
            continue
        seen.add(pdir)
        mesh = meshio.read(out / pdir / "final.vtu")
        if mesh.cells[0].type != "tetra10":
            continue
        angle = drawn_angle(out, row) if runs_of(row) > 1 else number(row.get("bending_angle_deg"))
        title = f"{row['sweep']} point {row['point']} ({pdir})" + ("" if angle is None else f": θ = {angle:.1f}°")
        try:
            views.append(state_view(mesh, f"hj-point-{len(views)}", title=title))
        except (KeyError, ValueError) as err:  # a final.vtu without the fields of results.write_vtu
            views.append(f"<h3>{html.escape(title)}</h3><p>no 3D view: {html.escape(str(err))}</p>")
    return views


def write_report_page(out: str | os.PathLike, table: SweepTable, report: str | os.PathLike) -> Path:
    """Write ``OUT/report.html`` (atomically): the Markdown ``report`` with its figures inlined
    and, where ``table``'s points hold a 3D final state, the section "Final states in 3D" with an
    interactive view of each (drag to rotate, wheel to zoom). Returns its path."""
    out = Path(out)
    body = markdown_html(Path(report).read_text(encoding="utf-8"), out)
    views = _final_views(out, table)
    if views:
        body += ("<h2>Final states in 3D</h2><p>Each point's final state (its replica 0, and that run's bending "
                 f"angle), as {html.escape('final.vtu')} holds it: particles coloured by swelling ratio. A view is "
                 "built as it comes into sight.</p>" + "\n".join(views))
    path = out / "report.html"
    write_text_atomic(path, page_html("hydrojam reproduce", body))
    return path
