"""The current state of unfinished runs, as files a person opens (`hydrojam snapshot OUT -o DIR`):
a 3D point of a long study runs for hours and writes its VTU and picture only when it finishes;
its checkpoint holds where it is now. Each unfinished run of a study's or a run's output folder
(:func:`hydrojam.study.status.folder_status`) gets ``DIR/<name>.vtu`` (ParaView; a 3D half model
mirrored) and ``DIR/<name>.png`` (as ``final.png``), of its last accepted state on the load path,
or at s = 1 of its release's current centre, which is not an equilibrium yet.

Reads the runs' folders only (their design.toml and checkpoint.npz): a run going on in another
process is seen at its last checkpoint. Lengths in mm.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from hydrojam._io import make_folder
from hydrojam.actuator.checkpoint import CHECKPOINT
from hydrojam.study.spec import Point
from hydrojam.study.status import folder_status

__all__ = ["Snapshot", "current_state", "write_snapshots"]


@dataclass(frozen=True)
class Snapshot:
    """One unfinished run drawn: ``name`` (its design key, or the run folder's name), the study
    points sharing it, its load parameter ``s`` [-], whether it is in its release at s = 1
    (``releasing``), the state's metrics (:func:`hydrojam.actuator.model.measure`) and the
    files written."""

    name: str
    points: tuple[Point, ...]
    s: float
    releasing: bool
    metrics: dict
    vtu: Path
    png: Path


def current_state(folder: str | os.PathLike):
    """(model, state, releasing) of the unfinished run in ``folder`` from its design.toml and
    checkpoint: the last accepted state (a :class:`~hydrojam.actuator.simulate.StepState`), or at
    s = 1 the release's current centre with ``releasing`` True; None where the folder has no
    checkpoint that fits its design (the model is built: seconds in 2D, up to a minute for a long
    3D chamber)."""
    from hydrojam.actuator.checkpoint import CheckpointError, load_checkpoint
    from hydrojam.actuator.design import DesignError, load_design
    from hydrojam.actuator.model import build_model, measure
    from hydrojam.actuator.simulate import StepState

    folder = Path(folder)
    if not (folder / CHECKPOINT).is_file():
        return None
    try:
        model = build_model(load_design(folder / "design.toml"))
        ck = load_checkpoint(folder / CHECKPOINT, model.design, model.mesh.points.shape)
    except (OSError, DesignError, CheckpointError):
        return None
    releasing = ck.release is not None
    x, s = (ck.release.x, 1.0) if releasing else (ck.xs[-1], float(ck.states[-1]["s"]))
    mu, T = model.stimulus(s)
    state = StepState(len(ck.states), s, mu, T, x, measure(model, x), 0, ck.elapsed_s)
    return model, state, releasing


def write_snapshots(out: str | os.PathLike, dest: str | os.PathLike, on_run=None) -> list[Snapshot]:
    """Draw every unfinished (or failed, with a checkpoint to go on from) run of the output folder
    ``out`` (a study's or a run's; StatusError for another) into ``dest`` (made where there is
    something to draw): ``<name>.vtu`` and ``<name>.png``. ``on_run(name, points)`` is called
    before each (its model takes seconds to a minute to build). Returns what was written, in the study's order."""
    from hydrojam.actuator.plots import plot_actuator
    from hydrojam.actuator.results import write_vtu

    out, dest = Path(out), Path(dest)
    st = folder_status(out)
    written = []
    for run in st.runs:
        if run.state not in ("unfinished", "failed"):
            continue
        name = run.key or st.name
        if on_run is not None:
            on_run(name, run.points)
        got = current_state(out / "points" / run.key if st.kind == "study" else out)
        if got is None:
            continue
        model, state, releasing = got
        make_folder(dest)
        vtu, png = dest / f"{name}.vtu", dest / f"{name}.png"
        write_vtu(vtu, model, state)
        plot_actuator(model, state, png)
        written.append(Snapshot(name, run.points, state.s, releasing, state.metrics, vtu, png))
    return written
