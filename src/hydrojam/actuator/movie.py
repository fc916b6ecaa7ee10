"""An actuation movie (GIF, or MP4 where an H.264 encoder is found: :func:`mp4_encoder`) from
the states a run wrote: ``steps/*.vtu`` in the order of ``results.pvd``, with each step's load
parameter s, temperature and bending angle from ``history.csv``.

A 3D run's frames are renders of the whole actuator (:mod:`hydrojam.actuator.render`, with the
extra ``render``; without it, its section y = 0), a 2D run's the section drawn as in
``final.png``. Every frame has one camera, one scale and one colour range: those of all the
states together. Frames are drawn from the written files after the run, never inside it.
"""

from __future__ import annotations

import csv
import os
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure

from hydrojam._io import atomic_path
from hydrojam.actuator.model import PARTICLE_BODY
from hydrojam.actuator.plots import mid_section
from hydrojam.actuator.render import Renderer, renders_available, state_surfaces, swelling_range
from hydrojam.fem.elements import ELEMENTS, straight_pieces

#: most frames a movie holds: a longer run's states are thinned evenly (first and last kept)
MAX_FRAMES = 120


class NoStates(ValueError):
    """The folder holds no written states to animate (one line: what is missing)."""


#: why an MP4 cannot be written here (one line)
NO_MP4 = ("an MP4 needs ffmpeg: install the extra 'render' (pip install 'hydrojam[render]', its imageio-ffmpeg "
          "brings one) or put ffmpeg on PATH; a .gif needs neither")


def mp4_encoder() -> str | None:
    """The ffmpeg that writes MP4 (H.264): ``ffmpeg`` on PATH, else the one the package
    imageio-ffmpeg (in the extra ``render``) ships; None where neither is found."""
    found = shutil.which("ffmpeg")
    if found:
        return found
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return None


def _write_mp4(frames: list[np.ndarray], fps: float, path: Path, exe: str) -> None:
    """``frames`` (h, w, 3) uint8 as an H.264 MP4 (yuv420p, which players expect: frames padded
    white to even sides), the last held a second more."""
    h, w = frames[0].shape[:2]
    ph, pw = h + h % 2, w + w % 2
    cmd = [exe, "-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{pw}x{ph}",
           "-r", f"{fps:g}", "-i", "-", "-an", "-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "20",
           "-movflags", "+faststart", "-f", "mp4", str(path)]
    held = frames + [frames[-1]] * max(1, round(fps))
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        for f in held:
            if (ph, pw) != (h, w):
                f = np.pad(f, ((0, ph - h), (0, pw - w), (0, 0)), constant_values=255)
            proc.stdin.write(np.ascontiguousarray(f, dtype=np.uint8).tobytes())
        proc.stdin.close()
    except BrokenPipeError:
        pass
    err = proc.stderr.read().decode(errors="replace").strip()
    if proc.wait() != 0:
        raise RuntimeError(f"ffmpeg ({exe}) could not write the MP4: {err.splitlines()[-1] if err else 'no message'}")


@dataclass(frozen=True)
class WrittenState:
    """One state a run wrote: its VTU file and its row of history.csv."""

    path: Path
    step: int
    s: float
    temperature_K: float
    angle_deg: float
    time_s: float | None

    def caption(self) -> str:
        """The frame's text: load parameter, (time,) temperature and bending angle."""
        t = "" if self.time_s is None else f"t = {self.time_s:.4g} s, "
        return f"s = {self.s:.3f}, {t}T = {self.temperature_K:.1f} K, bending angle {self.angle_deg:.1f} deg"


def written_states(out: str | os.PathLike) -> list[WrittenState]:
    """The states a run wrote into ``out``, as-prepared first (results.pvd's order).

    Raises
    ------
    NoStates
        Where ``out`` has no results.pvd or history.csv, or a listed step file is missing.
    """
    out = Path(out)
    pvd, hist = out / "results.pvd", out / "history.csv"
    for f in (pvd, hist):
        if not f.is_file():
            raise NoStates(f"{out}: no {f.name}: not a run's folder, or a run written with --no-vtu")
    rows = {}
    with hist.open(newline="") as fh:
        for r in csv.DictReader(fh):
            rows[int(r["step"])] = r
    states = []
    for ds in ET.parse(pvd).getroot().iter("DataSet"):
        path = out / ds.get("file")
        m = re.search(r"step_(\d+)\.vtu$", path.name)
        if not path.is_file() or m is None or int(m.group(1)) not in rows:
            raise NoStates(f"{out}: step file {ds.get('file')} missing or not in history.csv")
        r = rows[int(m.group(1))]
        states.append(WrittenState(path=path, step=int(r["step"]), s=float(r["s"]),
                                   temperature_K=float(r["temperature_K"]),
                                   angle_deg=float(r["bending_angle_deg"] or "nan"),
                                   time_s=float(r["time_s"]) if r.get("time_s") else None))
    if not states:
        raise NoStates(f"{out}: results.pvd lists no states")
    return states


def _thin(states: list, max_frames: int) -> list:
    if len(states) <= max_frames:
        return states
    keep = np.unique(np.round(np.linspace(0, len(states) - 1, max_frames)).astype(int))
    return [states[i] for i in keep]


def _section(mesh: meshio.Mesh):
    """A state's section in the x-z plane: (reference (n, 2), deformed (n, 2), triangles (k, 3),
    body and swelling ratio of each triangle, outline segments (m, 2)); 2D: the whole mesh, 3D:
    the section y = 0 (:func:`hydrojam.actuator.plots.mid_section`)."""
    X = np.asarray(mesh.points, dtype=float)
    x = X + np.asarray(mesh.point_data["displacement"], dtype=float)
    block = mesh.cells[0]
    fields = {k: np.asarray(v[0]).ravel() for k, v in mesh.cell_data.items() if k in ("body_id", "swelling_ratio")}
    if block.type == "tetra10":
        tris, body, swell, seg = mid_section(X, block.data, float(np.ptp(X[:, 2])), fields)
    else:
        cells = block.data
        tris = straight_pieces(cells, 2)
        rep = len(tris) // len(cells)
        body, swell = np.repeat(fields["body_id"], rep), np.repeat(fields["swelling_ratio"], rep)
        edges = straight_pieces(cells[:, ELEMENTS["tri6"].facets].reshape(-1, 3), 1)
        _, first, counts = np.unique(np.sort(edges, axis=1), axis=0, return_index=True, return_counts=True)
        seg = edges[first[counts == 1]]
    return X[:, [0, 2]], x[:, [0, 2]], tris, body, swell, seg


def _section_frame(mesh: meshio.Mesh, caption: str, box: np.ndarray, clim, size) -> np.ndarray:
    X, x, tris, body, swell, seg = _section(mesh)
    fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.add_collection(LineCollection(X[seg], colors="0.6", linewidths=0.7, linestyles="--"))
    gel = body >= PARTICLE_BODY
    ax.add_collection(PolyCollection(x[tris[~gel]], facecolors=np.where(body[~gel, None] == 0, [[0.82] * 3], [[0.45] * 3]),
                                     edgecolors="face", linewidths=0.2))
    pc = PolyCollection(x[tris[gel]], array=swell[gel], cmap="viridis", edgecolors="face", linewidths=0.2)
    pc.set_clim(*clim)
    ax.add_collection(pc)
    ax.add_collection(LineCollection(x[seg], colors="k", linewidths=0.5))
    ax.set_xlim(box[0, 0], box[1, 0])
    ax.set_ylim(box[0, 1], box[1, 1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    fig.colorbar(pc, ax=ax, shrink=0.8, label="particle swelling ratio J")
    ax.set_title(caption, fontsize=10)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def write_movie(out: str | os.PathLike, path: str | os.PathLike | None = None, fps: float = 6.0,
                max_frames: int = MAX_FRAMES, size: tuple[int, int] = (800, 700)) -> Path:
    """Write the actuation movie of a run's folder as a GIF, or an MP4 where ``path`` ends in
    ``.mp4`` (atomically).

    Parameters
    ----------
    out : str or os.PathLike
        The run's output folder (:func:`written_states`).
    path : str or os.PathLike, optional
        The GIF or MP4 to write; default ``out/movie.gif``.
    fps : float
        Frames per second; the last frame is held for a second more.
    max_frames : int
        Most frames (states thinned evenly beyond it).
    size : (int, int)
        Width and height of a frame [pixels].

    Returns
    -------
    Path
        The movie written.

    Raises
    ------
    NoStates
        ``out`` holds no written states.
    ValueError
        An MP4 asked for where no encoder is found (:data:`NO_MP4`), before any frame is drawn.
    """
    from PIL import Image

    path = Path(out) / "movie.gif" if path is None else Path(path)
    exe = None
    if path.suffix.lower() == ".mp4" and (exe := mp4_encoder()) is None:
        raise ValueError(NO_MP4)
    states = _thin(written_states(out), max_frames)
    meshes = [meshio.read(st.path) for st in states]
    is3d = meshes[0].cells[0].type == "tetra10"
    render = is3d and renders_available()
    frames = []
    if render:
        surfs = [state_surfaces(m) for m in meshes]
        pts = np.vstack([np.vstack([sf.points, sf.reference]) for sf in surfs])
        gel = np.concatenate([sf.swelling[sf.group("particles")] for sf in surfs])
        with Renderer(size, bounds=(pts.min(axis=0), pts.max(axis=0)), clim=swelling_range(gel)) as r:
            frames = [r.draw(sf, st.caption()) for sf, st in zip(surfs, states)]
    else:
        sections = [_section(m) for m in meshes]
        pts = np.vstack([np.vstack([sec[0], sec[1]]) for sec in sections])
        pad = 0.05 * float(np.ptp(pts, axis=0).max())
        box = np.array([pts.min(axis=0) - pad, pts.max(axis=0) + pad])
        gel = np.concatenate([sec[4][sec[3] >= PARTICLE_BODY] for sec in sections])
        clim = swelling_range(gel)
        where = "3D, section y = 0: " if is3d else ""
        frames = [_section_frame(m, where + st.caption(), box, clim, size) for m, st in zip(meshes, states)]
    if exe is not None:
        with atomic_path(path) as tmp:
            _write_mp4(frames, fps, Path(tmp), exe)
        return path
    images = [Image.fromarray(f).convert("P", palette=Image.Palette.ADAPTIVE, colors=255) for f in frames]
    ms = int(round(1000.0 / fps))
    durations = [ms] * (len(images) - 1) + [ms + 1000]
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="gif", save_all=True, append_images=images[1:], duration=durations, loop=0)
    return path


__all__ = ["write_movie", "written_states", "WrittenState", "NoStates", "MAX_FRAMES", "mp4_encoder", "NO_MP4"]
