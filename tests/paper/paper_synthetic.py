"""Synthetic inputs for the tests of hydrojam.paper: sweep-table rows shaped like the paper's
statements (or against them), and point folders holding a tiny hand-made final.vtu (a few
quadratic triangles with a body id each) and a design.toml. No simulation runs.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from hydrojam.actuator.design import apply_overrides, default_design, write_design
from hydrojam.paper import study as pstudy

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
FIELDS = ("stimulus.temperature", "particle_layers", "strain_limit_thickness")
BASE = {"stimulus.temperature": 275.0, "particle_layers": 5, "strain_limit_thickness": 8.0}


def row(sweep: str, field: str, value, theta, dx, dz, ci=0.5, status="ok", **extra) -> dict:
    point = dict(BASE)
    point[field] = value
    failed = status == "failed"
    r = {"sweep": sweep, "point": f"{field}={value}", "key": f"{field}={value}", **point,
         "bending_angle_deg": None if failed else theta, "tip_dx_mm": None if failed else dx,
         "tip_dz_mm": None if failed else dz, "curling_index": None if failed else ci,
         "converged": None if failed else status == "ok", "stabilisation_released": status == "ok",
         "newton_iterations": None if failed else 900, "wall_time_s": None if failed else 120.0,
         "status": status, "error": "solver stopped: minimum increment" if failed else None,
         "point_dir": f"points/{sweep}-{value}"}
    r.update(extra)
    return r


def temperature_rows(Ts=pstudy.TEMPERATURES_K, sign=-1.0) -> list[dict]:
    """Paper-like (sign -1): angle and displacements fall linearly as T rises, δx falls most."""
    return [row("temperature", "stimulus.temperature", T, 75 + sign * 2.3 * (T - 275),
                -(50 + sign * 1.5 * (T - 275)), -(12 + sign * 0.3 * (T - 275))) for T in Ts]


def layer_rows(PLs=pstudy.PARTICLE_LAYERS) -> list[dict]:
    """Paper-like: θ peaks at 9, |δx| rises to 9 then flat, |δz| peaks at 7, curling from 10 on."""
    rows = []
    for n in PLs:
        theta = 60 + 5 * (n - 5) if n <= 9 else 80 - 1.5 * (n - 9)
        dx = 30 + 5 * (n - 5) if n <= 9 else 50.0
        dz = 10 + 3 * (n - 5) if n <= 7 else 16 - 0.6 * (n - 7)
        rows.append(row("particle_layers", "particle_layers", n, theta, -dx, -dz, ci=0.4 if n <= 9 else 0.7))
    return rows


def thickness_rows(hs=pstudy.STRAIN_LIMIT_THICKNESSES_MM) -> list[dict]:
    """Paper-like: θ rises to 10 mm then levels; displacements rise to 10 mm and drop at 12 (by a
    fifth of |δx| and |δz|, clear of the tolerance also when ``paper_like`` shifts the scale)."""
    rows = []
    for h in hs:
        theta = 40 + 8 * (h - 4) if h <= 10 else 89.0
        dx = 20 + 5 * (h - 4) if h <= 10 else 40.0
        dz = 8 + 2 * (h - 4) if h <= 10 else 16.0
        rows.append(row("strain_limit_thickness", "strain_limit_thickness", h, theta, -dx, -dz))
    return rows


def paper_like(design) -> dict:
    """Metrics of a design, paper-like in each parameter: the three sweeps' shapes added round the
    base point (275 K, PL 5, h 8 mm), so the shared base point has one set of values."""
    t, = temperature_rows([design.stimulus.temperature])
    n, = layer_rows([design.particle_layers])
    h, = thickness_rows([design.strain_limit_thickness])
    t0, = temperature_rows([275.0])
    n0, = layer_rows([5])
    h0, = thickness_rows([8.0])
    out = {k: t[k] + (n[k] - n0[k]) + (h[k] - h0[k]) for k in ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm")}
    out["curling_index"] = n["curling_index"]
    return out


def with_values(rows, **by_param):
    """Copies of rows with some metrics replaced: by_param = {key: {param: value}}."""
    out = []
    for r in rows:
        r = dict(r)
        field = {"temperature": "stimulus.temperature"}.get(r["sweep"], r["sweep"])
        for key, values in by_param.items():
            if r[field] in values:
                r[key] = values[r[field]]
        out.append(r)
    return out


CORNERS = np.array([[0, 1, 2], [0, 2, 3]])


def tri6(points: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic triangles from corner triangles: mid-side nodes appended (0-1, 1-2, 2-0)."""
    pts = [p for p in points]
    cells = []
    for a, b, c in tris:
        mids = []
        for i, j in ((a, b), (b, c), (c, a)):
            pts.append(0.5 * (points[i] + points[j]))
            mids.append(len(pts) - 1)
        cells.append([a, b, c, *mids])
    return np.array(pts), np.array(cells)


def write_point(out: Path, r: dict, bend: float, design=None) -> None:
    """A point folder: design.toml and a final.vtu of membrane, layer and one particle, sheared by ``bend``."""
    pdir = out / r["point_dir"]
    pdir.mkdir(parents=True)
    if design is None:
        design = apply_overrides(default_design(), [f"{f}={r[f]!r}" for f in FIELDS])
    write_design(pdir / "design.toml", design)
    L, w, h = design.length, design.resolved_cavity_width / 2 + 2.0, design.strain_limit_thickness
    quads = [np.array([[-w, -L], [w, -L], [w, 0], [-w, 0]]),  # membrane
             np.array([[-w - h, -L], [-w, -L], [-w, 0], [-w - h, 0]]),  # strain-limit layer
             np.array([[-6, -20], [6, -20], [6, -8], [-6, -8]])]  # a particle
    pts, cells, body = [], [], []
    for k, q in enumerate(quads):
        p, c = tri6(q, CORNERS)
        cells.append(c + sum(len(x) for x in pts))
        pts.append(p)
        body += [k, k]
    p2 = np.vstack(pts)
    p2 = p2 + np.column_stack([bend * p2[:, 1] ** 2 / L, np.zeros(len(p2))])  # a parabolic bend to -x
    mesh = meshio.Mesh(np.column_stack([p2[:, 0], np.zeros(len(p2)), p2[:, 1]]), [("triangle6", np.vstack(cells))],
                       cell_data={"body_id": [np.array(body, dtype=np.int32)]})
    meshio.write(pdir / "final.vtu", mesh)


class Table:
    """The part of hydrojam.sweep.SweepTable the report reads."""

    def __init__(self, rows):
        self.rows = rows

    def select(self, sweep):
        return [r for r in self.rows if r["sweep"] == sweep]


def with_spread(rows, std: dict[str, float], replicas: int = 4) -> list[dict]:
    """Copies of rows as replicated points: ``<metric>_std`` = std[metric] at every point, the
    range mean ± 2 std, ``replicas`` run and all of them used."""
    out = []
    for r in rows:
        r = dict(r, replicas=replicas, replicas_used=replicas)
        for key, sd in std.items():
            v = r.get(key)
            r[f"{key}_std"] = sd
            r[f"{key}_min"], r[f"{key}_max"] = (None, None) if v is None else (v - 2 * sd, v + 2 * sd)
        out.append(r)
    return out


_TET10_EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))  # meshio/VTK order of the mid-edge nodes


def tet10_boxes(boxes: list[tuple[float, float, float, float, float, float]]):
    """Quadratic tetrahedra filling boxes (x0, x1, y0, y1, z0, z1) [mm], each box a body (its index):
    every box is cut at y = 0 into two halves (when it spans it) and each half into the 6 tetrahedra
    of its main diagonal (Kuhn). Returns points (n, 3), tetra10 cells (k, 10) and body ids (k,)."""
    from itertools import permutations

    pts, cells, body = [], [], []

    def node(p):
        pts.append(np.asarray(p, dtype=float))
        return len(pts) - 1

    for b, (x0, x1, y0, y1, z0, z1) in enumerate(boxes):
        for ya, yb in ([(y0, 0.0), (0.0, y1)] if y0 < 0.0 < y1 else [(y0, y1)]):
            lo, hi = np.array([x0, ya, z0]), np.array([x1, yb, z1])
            for perm in permutations(range(3)):
                corner = [lo.copy()]
                for axis in perm:
                    nxt = corner[-1].copy()
                    nxt[axis] = hi[axis]
                    corner.append(nxt)
                ids = [node(c) for c in corner]
                ids += [node(0.5 * (corner[i] + corner[j])) for i, j in _TET10_EDGES]
                cells.append(ids)
                body.append(b)
    return np.array(pts), np.array(cells), np.array(body, dtype=np.int32)


#: a 3D actuator's boxes (x0, x1, y0, y1, z0, z1) [mm]: membrane, strain-limit layer, a particle
BOXES_3D = [(-10.0, 10.0, -10.0, 10.0, -40.0, 0.0), (-18.0, -10.0, -10.0, 10.0, -40.0, 0.0),
            (-6.0, 6.0, -6.0, 6.0, -20.0, -8.0)]


def write_point_3d(out: Path, r: dict, bend: float, design=None) -> None:
    """A 3D point folder: design.toml (dimension 3) and a final.vtu of tetra10 boxes (membrane,
    layer, particle) in results.write_vtu's layout (reference points + displacement, body_id,
    swelling_ratio 3 in the particle), bent by ``bend``."""
    pdir = out / r["point_dir"]
    pdir.mkdir(parents=True)
    if design is None:
        design = apply_overrides(default_design(), ["dimension=3", "mesh.size=4.0"]
                                 + [f"{f}={r[f]!r}" for f in FIELDS])
    write_design(pdir / "design.toml", design)
    pts, cells, body = tet10_boxes(BOXES_3D)
    disp = np.zeros_like(pts)
    disp[:, 0] = bend * pts[:, 2] ** 2 / 40.0
    meshio.write(pdir / "final.vtu", meshio.Mesh(pts, [("tetra10", cells)], point_data={"displacement": disp},
                                                 cell_data={"body_id": [body],
                                                            "swelling_ratio": [np.where(body >= 2, 3.0, 1.0)]}))
