"""What the pictures of a run cost: the 3D render (final.png's), the actuation movie (GIF, and MP4
where an ffmpeg is found) and the HTML page, drawn from a finished run's folder after the run
(never inside the solve); and what a study's report.html weighs and costs to open.

    python benchmarks/pictures.py OUT [OUT ...] [--markdown docs/benchmarks.md]
    python benchmarks/pictures.py --study STUDY [--markdown docs/benchmarks.md]

OUT: folders of finished runs of ``hydrojam run`` (2D or 3D, with their steps/*.vtu). A 3D final
state's render is timed twice in one process: the first of the process includes importing PyVista
and opening the off-screen OpenGL context. STUDY: the folder of a finished 3D study of
``hydrojam reproduce`` (its report.md, figures, results.csv and points' final.vtu, read only):
its report.html is written anew into a temporary folder, its size split into its parts, and,
where Chromium is installed, opened headless (software WebGL) and scrolled through, view by
view. ``--markdown PAGE`` writes the table into PAGE's section between
``<!-- pictures.py: costs -->`` and ``<!-- /pictures.py: costs -->`` (``study`` with ``--study``).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import _version, print_environment, write_section

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True,
                              cwd=Path(__file__).parent).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


_cpu: list[float] = []


def _cpu_time() -> float:
    """CPU time [s] of this process (all its threads: llvmpipe's included) and of its finished
    child processes (ffmpeg's)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _timed(fn):
    """(wall time [s], result) of ``fn()``; its CPU time [s] (:func:`_cpu_time`) appended to ``_cpu``."""
    t0, c0 = time.perf_counter(), _cpu_time()
    out = fn()
    _cpu.append(_cpu_time() - c0)
    return time.perf_counter() - t0, out


def _label(out: Path) -> str:
    """The design of a run's folder in words: dimension and particle layers."""
    import tomllib

    d = tomllib.loads((out / "design.toml").read_text())
    n = d.get("particle_layers", 5)
    return f"{d.get('dimension', 2)}D, {n} layer{'s' if n != 1 else ''}"


def measure(outs: list[Path]) -> list[list[str]]:
    """Rows (what, conditions, wall time, CPU time) of the costs, for each finished run's folder."""
    from hydrojam.actuator.movie import mp4_encoder, write_movie, written_states
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
            if mp4_encoder() is not None:
                mp4 = Path(tmp) / "movie.mp4"
                t, _ = _timed(lambda: write_movie(out, mp4))
                rows.append([f"{label}: movie, MP4 (`--movie X.mp4`)",
                             f"{n} states, 800 x 700 px, H.264 {mp4.stat().st_size / 1e6:.2f} MB; "
                             "ffmpeg's CPU time included",
                             f"{t:.1f} s", f"{_cpu[-1]:.1f} s"])
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


def _study_copy(study: Path, dest: Path) -> None:
    """What report.html is written from: report.md, figures/, results.csv, each point's final.vtu
    and metrics.json."""
    for name in ("report.md", "results.csv"):
        shutil.copy2(study / name, dest / name)
    shutil.copytree(study / "figures", dest / "figures")
    for f in (study / "points").glob("*/*"):
        if f.name in ("final.vtu", "metrics.json"):
            (dest / f.parent.relative_to(study)).mkdir(parents=True, exist_ok=True)
            shutil.copy2(f, dest / f.relative_to(study))


def _browse(page: Path) -> list[list[str]]:
    """Rows of opening ``page`` in headless Chromium: the first view drawn, each view scrolled to."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from chromium import CHROMIUM, Page

    if CHROMIUM is None:
        return []
    t0 = time.perf_counter()
    with Page(page.as_uri(), (1200, 900)) as p:
        p.wait("document.body.dataset.hjReady")
        t_open = time.perf_counter() - t0
        n = p.run("document.querySelectorAll('.hj-scene').length")
        each = []
        for i in range(n):
            p.run(f"document.querySelectorAll('.hj-scene')[{i}].scrollIntoView({{block: 'center'}})")
            each.append(p.wait(f"document.querySelectorAll('.hj-scene')[{i}].dataset.hjDrawn"))
        console = list(p.console)
    version = subprocess.run([CHROMIUM, "--version"], capture_output=True, text=True).stdout.split(" built")[0].strip()
    cond = f"{version}, headless, software WebGL (SwiftShader), 1200 x 900 px window"
    return [["report.html opened: the page ready (the views in sight drawn)", cond + "; browser start included",
             f"{t_open:.1f} s", "—"],
            [f"a 3D view drawn once scrolled to ({n} views, one shared WebGL context)",
             cond + f"; console messages: {len(console)}",
             f"{sum(each) / max(n, 1):.2f} s a view (most {max(each, default=0):.2f} s)", "—"]]


def measure_study(study: Path) -> list[list[str]]:
    """Rows (what, conditions, wall time, CPU time) of a study's report.html: written, its size and
    parts, and (with Chromium) opened."""
    from hydrojam.paper.page import write_report_page
    from hydrojam.study.table import SweepTable

    with tempfile.TemporaryDirectory() as tmp:
        dest = Path(tmp)
        _study_copy(study, dest)
        table = SweepTable.read(dest)
        t, path = _timed(lambda: write_report_page(dest, table, dest / "report.md"))
        text = path.read_text(encoding="utf-8")
        views = re.findall(r'<script type="application/json" id="hj-point-\d+">.*?</script>', text, re.S)
        figures = re.findall(r"data:image/[a-z]+;base64,[A-Za-z0-9+/=]+", text)
        viewer = re.findall(r'<script type="(?:text/plain|module)".*?</script>', text, re.S)
        mb = lambda parts: sum(map(len, parts)) / 1e6  # noqa: E731
        import tomllib

        name = tomllib.loads((study / "study.toml").read_text(encoding="utf-8")).get("name", study.name)
        rows = [[f"report.html of `{name}` written", f"{len(views)} 3D views, {len(figures)} figures: "
                 f"{len(text) / 1e6:.1f} MB (figures {mb(figures):.1f} MB, 3D views {mb(views):.1f} MB, "
                 f"viewer code {mb(viewer):.2f} MB)", f"{t:.1f} s", f"{_cpu[-1]:.1f} s"]]
        rows += _browse(path)
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("outs", type=Path, nargs="*", help="finished runs' folders (2D or 3D)")
    ap.add_argument("--study", type=Path, help="a finished 3D study's folder: its report.html instead")
    ap.add_argument("--markdown", help="write the table into this page's section 'costs' ('study' with --study)")
    args = ap.parse_args()
    if bool(args.outs) == bool(args.study):
        ap.error("give either run folders or --study")
    print_environment(["pyvista", "vtk", "matplotlib", "pillow", "imageio-ffmpeg"])
    rows = measure_study(args.study) if args.study else measure(args.outs)
    text = markdown(rows)
    print(text)
    if args.markdown:
        write_section(args.markdown, "pictures.py", "study" if args.study else "costs", text)


if __name__ == "__main__":
    main()
