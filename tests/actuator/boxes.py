"""Small hand-made states as a run's VTU files hold them, for the tests of the pictures (render,
movie, HTML page): boxes of quadratic elements with body ids, no solver, no gmsh.

3D: a membrane box [0, 10] x [0, 10] x [-10, 0] mm (body 0) with a strain-limit layer box
[-3, 0] x [0, 10] x [-10, 0] bonded to its -x face (body 1, nodes shared) and a particle box
[12, 16] x [0, 4] x [-6, -2] (body 2), each box 6 tetra10 (Kuhn's split of a cube). 2D: the same
in the x-z plane with triangle6 cells (points at y = 0).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import meshio
import numpy as np

from hydrojam.actuator.results import pvd_text

BOXES = [((0.0, 0.0, -10.0), (10.0, 10.0, 0.0), 0), ((-3.0, 0.0, -10.0), (0.0, 10.0, 0.0), 1),
         ((12.0, 0.0, -6.0), (16.0, 4.0, -2.0), 2)]
#: meshio's mid-node order: tetra10 edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3); triangle6 (0,1), (1,2), (2,0)
_TET_EDGES = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
_TRI_EDGES = [(0, 1), (1, 2), (2, 0)]


class _Points:
    """Points deduplicated by position (shared faces share nodes)."""

    def __init__(self):
        self.index: dict[tuple, int] = {}
        self.points: list = []

    def __call__(self, p) -> int:
        key = tuple(np.round(np.asarray(p, dtype=float), 9))
        if key not in self.index:
            self.index[key] = len(self.points)
            self.points.append(key)
        return self.index[key]


def _quadratic(pts: _Points, corners: list, edges) -> list[int]:
    ids = [pts(c) for c in corners]
    return ids + [pts((np.asarray(corners[a]) + np.asarray(corners[b])) / 2) for a, b in edges]


def box_mesh(dim: int = 3, swelling=(2.0, 3.0)) -> meshio.Mesh:
    """The boxes as a VTU mesh without displacement (reference points, cells, ``body_id``,
    ``swelling_ratio``: 1 in the walls, ``swelling`` spread over the particle's cells)."""
    pts, cells, body = _Points(), [], []
    for lo, hi, b in BOXES:
        lo, hi = np.array(lo), np.array(hi)
        if dim == 3:
            for perm in itertools.permutations(range(3)):
                path = [np.zeros(3)]
                for axis in perm:
                    step = path[-1].copy()
                    step[axis] = 1.0
                    path.append(step)
                corners = [lo + (hi - lo) * c for c in path]
                e = [corners[1] - corners[0], corners[2] - corners[0], corners[3] - corners[0]]
                if np.dot(np.cross(e[0], e[1]), e[2]) < 0:
                    corners[1], corners[2] = corners[2], corners[1]
                cells.append(_quadratic(pts, corners, _TET_EDGES))
                body.append(b)
        else:
            (x0, _, z0), (x1, _, z1) = lo, hi
            for tri in (((x0, 0, z0), (x1, 0, z0), (x1, 0, z1)), ((x0, 0, z0), (x1, 0, z1), (x0, 0, z1))):
                cells.append(_quadratic(pts, [np.array(c, dtype=float) for c in tri], _TRI_EDGES))
                body.append(b)
    body = np.array(body, dtype=np.int32)
    swell = np.ones(len(body))
    gel = body >= 2
    swell[gel] = np.linspace(*swelling, int(gel.sum()))
    return meshio.Mesh(np.array(pts.points), [("tetra10" if dim == 3 else "triangle6", np.array(cells))],
                       point_data={"displacement": np.zeros((len(pts.points), 3))},
                       cell_data={"body_id": [body], "swelling_ratio": [swell]})


def bent(mesh: meshio.Mesh, angle_deg: float, swelling=None) -> meshio.Mesh:
    """``mesh`` rotated rigidly by ``angle_deg`` about the y axis through the origin (the clamp),
    toward -x at the free end (z < 0), with the particle's swelling ratios replaced."""
    a = np.radians(angle_deg)
    R = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    X = mesh.points
    fields = {k: [np.array(v[0])] for k, v in mesh.cell_data.items()}
    if swelling is not None:
        gel = fields["body_id"][0] >= 2
        fields["swelling_ratio"][0][gel] = np.linspace(*swelling, int(gel.sum()))
    return meshio.Mesh(X, mesh.cells, point_data={"displacement": X @ R.T - X}, cell_data=fields)


def write_run(out: Path, dim: int = 3, n: int = 4) -> list[float]:
    """A run's folder with ``n`` states (steps/*.vtu, results.pvd, history.csv) bending from 0 to
    30 deg as s goes from 0 to 1; returns the angles [deg]."""
    (out / "steps").mkdir(parents=True)
    base = box_mesh(dim)
    angles, rows, entries = [], ["step,s,temperature_K,time_s,bending_angle_deg"], []
    for i, s in enumerate(float(v) for v in np.linspace(0.0, 1.0, n)):
        angle = 30.0 * s
        rel = f"steps/step_{i:04d}.vtu"
        meshio.write(out / rel, bent(base, angle, (1.0 + s, 1.0 + 2 * s)), file_format="vtu")
        rows.append(f"{i},{s!r},{306.0 - 31.0 * s!r},,{angle!r}")
        entries.append((s, rel))
        angles.append(angle)
    (out / "history.csv").write_text("\n".join(rows) + "\n")
    (out / "results.pvd").write_text(pvd_text(entries))
    return angles
