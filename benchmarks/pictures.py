"""What the pictures of a run cost: the 3D render (final.png's), the actuation movie and the HTML
page, drawn from a finished run's folder after the run (never inside the solve).

    python benchmarks/pictures.py OUT [OUT ...] [--markdown docs/benchmarks.md]

OUT: folders of finished runs of ``hydrojam run`` (2D or 3D, with their steps/*.vtu). A 3D final
state's render is timed twice in one process: the first of the process includes importing PyVista
and opening the off-screen OpenGL context. ``--markdown PAGE``
writes the table into PAGE's section between ``<!-- pictures.py: costs -->`` and
``<!-- /pictures.py: costs -->``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import _version, print_environment

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True,
                              cwd=Path(__file__).parent).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


_cpu: list[float] = []


def _timed(fn):
    """(wall time [s], result) of ``fn()``; its CPU time [s] (this process, all its threads:
    llvmpipe's included) appended to ``_cpu``."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    _cpu.append(time.process_time() - c0)
    return time.perf_counter() - t0, out


def _label(out: Path) -> str:
    """The design of a run's folder in words: dimension and particle layers."""
    import tomllib

    d = tomllib.loads((out / "design.toml").read_text())
    n = d.get("particle_layers", 5)
    return f"{d.get('dimension', 2)}D, {n} layer{'s' if n != 1 else ''}"


def measure(outs: list[Path]) -> list[list[str]]:
    """Rows (what, conditions, wall time, CPU time) of the costs, for each finished run's folder."""
    from hydrojam.actuator.movie import write_movie, written_states
    from hydrojam.actuator.page import final_state, write_run_page
    from hydrojam.actuator.render import render_state

    rows = []
    size = (900, 800)
    first = True
    with tempfile.TemporaryDirectory() as tmp:
        for out in outs:
            label = _label(out)
            mesh = final_state(out)
            is3d = mesh.cells[0].type == "tetra10"
            if is3d:
                t_first, _ = _timed(lambda: render_state(mesh, size=size))
                t_again, _ = _timed(lambda: render_state(mesh, size=size))
                cells = f"{len(mesh.cells[0].data)} tetra10 (whole actuator), {size[0]} x {size[1]} px"
                if first:
                    rows.append([f"{label}: render of the final state (final.png's), first in a process",
                                 cells + "; PyVista import and OpenGL context included", f"{t_first:.1f} s",
                                 f"{_cpu[-2]:.1f} s"])
                    first = False
                rows.append([f"{label}: render of the final state", cells, f"{t_again:.1f} s", f"{_cpu[-1]:.1f} s"])
            n = len(written_states(out))
            gif = Path(tmp) / "movie.gif"
            t, _ = _timed(lambda: write_movie(out, gif))
            rows.append([f"{label}: movie (`hydrojam animate`)", f"{n} states, 800 x 700 px, GIF {gif.stat().st_size / 1e6:.1f} MB",
                         f"{t:.1f} s ({t / n:.2f} s a frame)", f"{_cpu[-1]:.1f} s"])
            if is3d:
                page = Path(tmp) / "page"
                page.mkdir(exist_ok=True)
                for name in ("metrics.json", "design.toml", "final.png"):
                    if (out / name).is_file():
                        (page / name).write_bytes((out / name).read_bytes())
                t, path = _timed(lambda: write_run_page(page, mesh))
                rows.append([f"{label}: report.html", f"final.png and the 3D view inlined: {path.stat().st_size / 1e6:.1f} MB",
                             f"{t:.2f} s", f"{_cpu[-1]:.2f} s"])
    return rows


def markdown(rows: list[list[str]]) -> str:
    import vtkmodules

    from hydrojam.actuator.render import _pyvista

    pv = _pyvista()
    window = type(pv.Plotter(off_screen=True).render_window).__name__
    lines = [f"Measured by `benchmarks/pictures.py`: code of `{_commit()}`, {os.cpu_count()} cores, one process, "
             f"PyVista {_version('pyvista')} / VTK {vtkmodules.__version__} through {window} (software OpenGL, no GPU).",
             "", "| what | conditions | wall time | CPU time |", "|---|---|---:|---:|"]
    lines += [f"| {' | '.join(r)} |" for r in rows]
    return "\n".join(lines) + "\n"


def replace_section(page: str, name: str, text: str) -> str:
    """``page`` with the lines between '<!-- pictures.py: NAME -->' and its closing marker replaced."""
    begin, end = f"<!-- pictures.py: {name} -->", f"<!-- /pictures.py: {name} -->"
    i, j = page.find(begin), page.find(end)
    if i < 0 or j < i:
        raise ValueError(f"no section {begin} ... {end} in the page")
    return page[: i + len(begin)] + "\n" + text.rstrip("\n") + "\n" + page[j:]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("outs", type=Path, nargs="+", help="finished runs' folders (2D or 3D)")
    ap.add_argument("--markdown", help="write the table into this page's section 'costs'")
    args = ap.parse_args()
    print_environment(["pyvista", "vtk", "matplotlib", "pillow"])
    rows = measure(args.outs)
    text = markdown(rows)
    print(text)
    if args.markdown:
        page = Path(args.markdown)
        page.write_text(replace_section(page.read_text(encoding="utf-8"), "costs", text), encoding="utf-8")


if __name__ == "__main__":
    main()
