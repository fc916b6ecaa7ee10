"""Results on disk: every file written atomically, as the run goes (docs/actuator.md, "Outputs").

Layout of an output folder ``OUT``::

    design.toml       the resolved design (every field explicit)
    history.csv       metrics at every accepted load step
    steps/step_NNNN.vtu  the state of every accepted step (quadratic triangles; 3D: quadratic
                      tetrahedra, a half model mirrored so that the whole actuator shows)
    results.pvd       ParaView's index of the steps, a time series in the load parameter s
                      (in the time [s] with a time-resolved stimulus)
    centreline.csv    final centreline profile: arc length, rotation, curvature
    metrics.json      final metrics, convergence, wall time, Newton iterations, provenance
    final.png         deformed actuator over the undeformed outline
    angle_time.png    with stimulus.schedule only: bending angle, free-end displacement and
                      temperature against time
    checkpoint.npz    while the run goes: its state after the last accepted step, to go on
                      from (:mod:`hydrojam.actuator.checkpoint`); removed by :meth:`ResultWriter.finish`

VTU fields: point data ``displacement`` [mm]; cell data ``body_id`` (0 membrane, 1 strain-limit
layer, 2 + k particle k), ``swelling_ratio`` (gel volume over dry-network volume, J = lambda0^3
det F; 1 in the elastomers, which do not swell), ``cauchy_stress`` [MPa] (3 x 3, plane strain:
the out-of-plane component included) and ``von_mises_stress`` [MPa], cell averages over
quadrature points. 2D results are written in the x-z plane of ParaView (y = 0), so the axes mean
what they mean in hydrojam; view them along -y. A 3D half model's files hold both halves (cell
field ``mirror_image``: 0 computed, 1 its mirror image about y = 0). centreline.csv and final.png
of a 3D run: the strain-limit layer's mid-surface along y = 0, and the section y = 0.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from hydrojam._io import atomic_path, finite_or_none, make_folder, write_text_atomic
from hydrojam.actuator.checkpoint import CHECKPOINT, CheckpointError, RunCheckpoint, load_checkpoint
from hydrojam.actuator.design import write_design
from hydrojam.actuator.fields import cell_fields
from hydrojam.actuator.metrics import HISTORY_FIELDS, STATE_METRICS, centreline_profile, metric_names
from hydrojam.actuator.model import ActuatorModel
from hydrojam.actuator.provenance import run_provenance
from hydrojam.actuator.plots import plot_actuator, plot_angle_time
from hydrojam.actuator.simulate import SimulationResult, StepState, checkpoint_states

#: the columns of history.csv (:data:`hydrojam.actuator.metrics.HISTORY_FIELDS`)
HISTORY_COLUMNS = [m.name for m in HISTORY_FIELDS]


def _xyz(p2: np.ndarray) -> np.ndarray:
    return np.column_stack([p2[:, 0], np.zeros(len(p2)), p2[:, 1]])


#: tetra10 node order (meshio) of a mirror image: corners 1 and 2 swapped, mid nodes following
_TETRA10_FLIP = np.array([0, 2, 1, 3, 6, 5, 4, 7, 9, 8])


def mirrored_half(model: ActuatorModel, x: np.ndarray, fields: dict[str, np.ndarray]):
    """The whole actuator from a 3D half model (y >= 0) and its mirror image about y = 0.

    Returns (reference points (n', 3), cells (2 n_cells, 10), displacement (n', 3), cell fields):
    the nodes on the symmetry plane are shared by both halves, the mirrored cells are reordered
    to stay positively oriented, the displacement's y component and the stress's xy and yz
    components change sign on the mirror side; the cell field ``mirror_image`` is 1 there."""
    X = model.mesh.points
    n = len(X)
    on_plane = np.zeros(n, dtype=bool)
    on_plane[model.symmetry_nodes] = True
    off = np.flatnonzero(~on_plane)
    image = np.arange(n)
    image[off] = n + np.arange(len(off))
    flip = np.array([1.0, -1.0, 1.0])
    points = np.vstack([X, X[off] * flip])
    u = x - X
    disp = np.vstack([u, u[off] * flip])
    cells = np.vstack([model.mesh.cells, image[model.mesh.cells][:, _TETRA10_FLIP]])
    out = {}
    for name, v in fields.items():
        w = v
        if name == "cauchy_stress":
            w = v * (flip[:, None] * flip[None, :])
        out[name] = np.concatenate([v, w])
    out["mirror_image"] = np.repeat(np.array([0, 1], dtype=np.int32), model.mesh.n_cells)
    return points, cells, disp, out


def vtu_mesh(model: ActuatorModel, state: StepState) -> meshio.Mesh:
    """One state as the mesh a VTU file holds (:func:`write_vtu`): reference points, displacement
    and the cell fields (a 3D half model mirrored about y = 0: :func:`mirrored_half`)."""
    fields = cell_fields(model, state.x, state.s)
    X, cells = model.mesh.points, model.mesh.cells
    if model.mesh.dim == 2:
        X, u = _xyz(X), _xyz(state.x - X)
    elif model.half:
        X, cells, u, fields = mirrored_half(model, state.x, fields)
    else:
        u = state.x - X
    return meshio.Mesh(
        X, [(model.mesh.cell_type, cells)],
        point_data={"displacement": u},
        cell_data={k: [v.reshape(len(v), -1) if v.ndim == 3 else v] for k, v in fields.items()},
    )


def write_vtu(path: Path, model: ActuatorModel, state: StepState) -> None:
    """One state as a VTU file (atomic): :func:`vtu_mesh`."""
    with atomic_path(path) as tmp:
        meshio.write(tmp, vtu_mesh(model, state), file_format="vtu")


def pvd_text(entries: list[tuple[float, str]]) -> str:
    """A ParaView collection (.pvd) of (time, relative file) entries."""
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">', "  <Collection>"]
    lines += [f'    <DataSet timestep="{t:.10g}" group="" part="0" file={quoteattr(f)}/>' for t, f in entries]
    lines += ["  </Collection>", "</VTKFile>", ""]
    return "\n".join(lines)


def history_row(state: StepState) -> dict:
    """One row of history.csv: the step's load parameter, stimulus, metrics and cost."""
    m = state.metrics
    row = {"step": state.index, "s": state.s, "mu_kT": state.mu, "temperature_K": state.T, "time_s": state.time_s,
           "newton_iterations": state.iterations, "wall_time_s": state.wall_time_s,
           "negative_eigenvalues": state.negative_eigenvalues, "residual_N": state.residual,
           "tolerance_N": state.tolerance}
    row.update({x.name: m.get(x.name) for x in STATE_METRICS})
    safe = {k: finite_or_none(row.get(k)) for k in HISTORY_COLUMNS}
    return {k: ("" if v is None else v) for k, v in safe.items()}


def ordered_metrics(metrics: dict) -> dict:
    """``metrics`` with the registry's keys first, in its order (state metrics, then run fields),
    then any other keys in their own order: the key order of metrics.json."""
    known = [k for k in metric_names() if k in metrics]
    return {**{k: metrics[k] for k in known}, **{k: v for k, v in metrics.items() if k not in known}}


def _csv(rows: list[dict], columns: list[str]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


class ResultWriter:
    """Writes a run's results into ``out_dir`` as the run goes; every file atomically.

    :meth:`start` writes the resolved design and clears step files of an earlier run; call
    :meth:`step` for every accepted state and :meth:`finish` at the end.

    Parameters
    ----------
    out_dir : str or Path
        The run's output folder.
    model : ActuatorModel
        The model being run.
    vtu : bool, optional
        Also write every accepted state as ``steps/step_<index>.vtu``, with ``results.pvd``.
    """

    def __init__(self, out_dir: str | Path, model: ActuatorModel, vtu: bool = True):
        self.out = Path(out_dir)
        self.model = model
        self.vtu = vtu
        self.rows: list[dict] = []
        self.entries: list[tuple[float, str]] = []
        self.discarded: str | None = None
        """Why :meth:`start` did not resume the folder's checkpoint (None: it did, or there was none)."""

    @property
    def checkpoint_path(self) -> Path:
        """The run's checkpoint file (:mod:`hydrojam.actuator.checkpoint`): pass it to
        :func:`~hydrojam.actuator.simulate.simulate`; :meth:`finish` removes it."""
        return self.out / CHECKPOINT

    def start(self, resume: bool = False) -> RunCheckpoint | None:
        """Make the folder and write the resolved design; clear the files of an earlier run.

        ``resume``: where the folder holds a checkpoint of this design, keep the files of its
        accepted states (history.csv and the step files rewritten to match it) and return it,
        for :func:`~hydrojam.actuator.simulate.simulate`'s ``resume``; otherwise (none, or one
        that cannot be resumed: :attr:`discarded` says why) start afresh and return None."""
        self.rows.clear()
        self.entries.clear()
        self.discarded = None
        make_folder(self.out)
        ck = None
        if resume:
            try:
                ck = load_checkpoint(self.checkpoint_path, self.model.design, self.model.mesh.points.shape)
            except FileNotFoundError:
                pass
            except CheckpointError as err:
                self.discarded = str(err)
        write_design(self.out / "design.toml", self.model.design)
        keep = set()
        if ck is not None:
            for st in checkpoint_states(ck):
                self.rows.append(history_row(st))
                if self.vtu:
                    rel = f"steps/step_{st.index:04d}.vtu"
                    if not (self.out / rel).is_file():
                        write_vtu(self.out / rel, self.model, st)
                    keep.add(rel)
                    self.entries.append((st.s if st.time_s is None else st.time_s, rel))
        steps = self.out / "steps"
        if steps.is_dir():
            for old in steps.glob("step_*.vtu"):
                if f"steps/{old.name}" not in keep:
                    old.unlink()
        for name in ("metrics.json", "final.png", "angle_time.png", "centreline.csv", "results.pvd", "history.csv"):
            (self.out / name).unlink(missing_ok=True)
        if ck is None:
            self.checkpoint_path.unlink(missing_ok=True)
        else:
            write_text_atomic(self.out / "history.csv", _csv(self.rows, HISTORY_COLUMNS))
            if self.vtu:
                write_text_atomic(self.out / "results.pvd", pvd_text(self.entries))
        return ck

    def step(self, state: StepState) -> None:
        """Write one accepted state; a state with the index of the last one replaces it (the
        final state once the stabilisation is released)."""
        if self.rows and self.rows[-1]["step"] == state.index:
            self.rows.pop()
            if self.entries:
                self.entries.pop()
        self.rows.append(history_row(state))
        write_text_atomic(self.out / "history.csv", _csv(self.rows, HISTORY_COLUMNS))
        if self.vtu:
            rel = f"steps/step_{state.index:04d}.vtu"
            write_vtu(self.out / rel, self.model, state)
            self.entries.append((state.s if state.time_s is None else state.time_s, rel))
            write_text_atomic(self.out / "results.pvd", pvd_text(self.entries))

    def finish(self, result: SimulationResult, plot: bool = True) -> dict:
        """Write centreline.csv, metrics.json and final.png (and angle_time.png on a time-resolved
        path); returns the metrics written."""
        model, final = self.model, result.final
        cl = model.centreline_nodes
        xz = [0, -1]  # 3D: the profile in the x-z plane
        prof = centreline_profile(model.mesh.points[cl][:, xz], final.x[cl][:, xz])
        rows = [{"reference_arc_length_mm": a, "arc_length_mm": b, "rotation_deg": math.degrees(r),
                 "curvature_per_mm": k}
                for a, b, r, k in zip(prof.reference_arc_length, prof.arc_length, prof.rotation, prof.curvature)]
        write_text_atomic(self.out / "centreline.csv",
                          _csv(rows, ["reference_arc_length_mm", "arc_length_mm", "rotation_deg", "curvature_per_mm"]))
        metrics = finite_or_none(ordered_metrics(result.metrics))
        metrics["timings_s"] = finite_or_none(result.timings)
        metrics["provenance"] = run_provenance(model.design.replicas.index, model.design.replicas.seed)
        if plot:
            plot_actuator(model, final, self.out / "final.png")
            if model.path.timed:
                plot_angle_time(result.states, model.path.schedule, self.out / "angle_time.png")
        if result.resumed:
            metrics["provenance"]["resumed"] = [finite_or_none(r) for r in result.resumed]
        write_text_atomic(self.out / "metrics.json", json.dumps(metrics, indent=2, allow_nan=False) + "\n")
        self.checkpoint_path.unlink(missing_ok=True)
        return metrics


__all__ = ["ResultWriter", "vtu_mesh", "write_vtu", "mirrored_half", "pvd_text", "history_row", "ordered_metrics", "HISTORY_COLUMNS"]
