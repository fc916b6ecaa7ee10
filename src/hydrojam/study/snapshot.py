"""The current state of unfinished runs, as files a person opens (`hydrojam snapshot OUT -o DIR`):
a 3D point of a long study runs for hours and writes its VTU and picture only when it finishes;
its checkpoint holds where it is now. Each unfinished run of a study's or a run's output folder
(:func:`hydrojam.study.status.folder_status`) gets ``DIR/<name>.vtu`` (ParaView; a 3D half model
mirrored) and ``DIR/<name>.png`` (as ``final.png``), of its last accepted state on the load path,
or at s = 1 of its release's current centre, which is not an equilibrium yet
(:func:`hydrojam.study.status.current_state`).

Reads the runs' folders only (their design.toml and checkpoint.npz): a run going on in another
process is seen at its last checkpoint. Lengths in mm.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from hydrojam._io import FolderKind, make_folder
from hydrojam.study.cache import PointStatus
from hydrojam.study.spec import Point
from hydrojam.study.status import current_state, folder_status

__all__ = ["Snapshot", "write_snapshots"]


@dataclass(frozen=True)
class Snapshot:
    """One unfinished run drawn.

    Parameters
    ----------
    name : str
        Its design key, or the run folder's name.
    points : tuple of Point
        The study points sharing it.
    s : float
        Its load parameter [-].
    releasing : bool
        Whether it is in its release at s = 1.
    metrics : dict
        The state's metrics (:func:`hydrojam.actuator.model.measure`).
    vtu, png : Path
        The files written.
    """

    name: str
    points: tuple[Point, ...]
    s: float
    releasing: bool
    metrics: dict
    vtu: Path
    png: Path


def write_snapshots(out: str | os.PathLike, dest: str | os.PathLike, on_run=None) -> list[Snapshot]:
    """Draw every unfinished (or failed, with a checkpoint to go on from) run of an output folder.

    Parameters
    ----------
    out : str or os.PathLike
        The output folder, a study's or a run's.
    dest : str or os.PathLike
        Where to write ``<name>.vtu`` and ``<name>.png`` (made where there is something to draw).
    on_run : callable, optional
        ``on_run(name, points)``, called before each (its model takes seconds to a minute to
        build).

    Returns
    -------
    list of Snapshot
        What was written, in the study's order.

    Raises
    ------
    StatusError
        For a folder that is neither a study's nor a run's.
    """
    from hydrojam.actuator.results import plot_state, write_vtu

    out, dest = Path(out), Path(dest)
    st = folder_status(out)
    written = []
    for run in st.runs:
        if run.state not in (PointStatus.UNFINISHED, PointStatus.FAILED):
            continue
        name = run.key or st.name
        if on_run is not None:
            on_run(name, run.points)
        got = current_state(out / "points" / run.key if st.kind == FolderKind.STUDY else out)
        if got is None:
            continue
        model, state, releasing = got
        make_folder(dest)
        vtu, png = dest / f"{name}.vtu", dest / f"{name}.png"
        write_vtu(vtu, model, state)
        plot_state(model, state, png)
        written.append(Snapshot(name, run.points, state.s, releasing, state.metrics, vtu, png))
    return written
