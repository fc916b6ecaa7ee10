"""Plain-data simplex meshes (units mm) and their meshio I/O.

A :class:`Mesh` is one block of triangles (2D, x-z plane stored as two columns) or tetrahedra
(3D), linear or quadratic, in meshio/VTK node order, with named cell groups (bodies, materials)
and named boundary-facet groups (clamped faces, loaded faces). Cells are always positively
oriented: counterclockwise triangles, positive-volume tetrahedra.

This module imports nothing from gmsh (gmsh is called from ``meshing.py``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Mapping

import meshio
import numpy as np

from hydrojam.fem.elements import ELEMENTS, element_for_meshio_type

# ----------------------------------------------------------------------------------------------
# Reference tables: the cells' and facets' own come from hydrojam.fem.elements (meshio order)
# ----------------------------------------------------------------------------------------------

CELL_TYPES = ("triangle", "triangle6", "tetra", "tetra10")


def _nodes(cell_type: str) -> int:
    return element_for_meshio_type(cell_type).nen


def _cell_dim(cell_type: str) -> int:
    return element_for_meshio_type(cell_type).dim


def _facet_type(cell_type: str) -> str:
    return ELEMENTS[element_for_meshio_type(cell_type).facet_name].meshio_type


#: Mid-edge nodes of quadratic cells and facets: the corner pair each mid node sits between, in
#: local order (the reference elements' ``edges``).
MID_EDGES = {t: tuple(tuple(e) for e in element_for_meshio_type(t).edges.tolist()) for t in ("line3", "triangle6", "tetra10")}

# Node permutation that flips a cell's orientation (swap corners 1 and 2, mid nodes follow).
_FLIP = {
    "triangle": (0, 2, 1),
    "triangle6": (0, 2, 1, 5, 4, 3),
    "tetra": (0, 2, 1, 3),
    "tetra10": (0, 2, 1, 3, 6, 5, 4, 7, 9, 8),
}

# Local node indices of each facet, outward, corners then mid nodes (the reference elements' facets).
_FACETS = {t: np.asarray(element_for_meshio_type(t).facets, dtype=np.int64) for t in CELL_TYPES}


def _group_rows(keys: np.ndarray):
    """Group identical rows of an integer array. Returns (order, starts, counts): rows
    ``order[starts[g]:starts[g] + counts[g]]`` are identical."""
    if len(keys) == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e, e
    order = np.lexsort(keys.T[::-1])
    k = keys[order]
    new = np.ones(len(k), dtype=bool)
    new[1:] = np.any(k[1:] != k[:-1], axis=1)
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(k)))
    return order, starts, counts


def signed_measures(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed area (triangles, 2D points) or volume (tetrahedra) from the corner nodes [mm^2/mm^3]."""
    if points.shape[1] == 2:
        p0, p1, p2 = (points[cells[:, i]] for i in range(3))
        a, b = p1 - p0, p2 - p0
        return 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    p0, p1, p2, p3 = (points[cells[:, i]] for i in range(4))
    return np.einsum("ij,ij->i", np.cross(p1 - p0, p2 - p0), p3 - p0) / 6.0


def jacobian_determinants(points: np.ndarray, cells: np.ndarray, cell_type: str, xi: np.ndarray):
    """det(dx/dxi) of the isoparametric map of each cell at reference points ``xi`` (q, dim):
    shape (n_cells, q). Positive everywhere for a valid, positively oriented cell."""
    dN = element_for_meshio_type(cell_type).grad(np.atleast_2d(np.asarray(xi, dtype=float)))
    J = np.einsum("cai,qaj->cqij", points[cells], dN)
    return np.linalg.det(J)


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.setflags(write=False)
    return a


# ----------------------------------------------------------------------------------------------
# Mesh
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Mesh:
    """Simplex mesh in mm.

    Arrays are stored as read-only copies. Build with :meth:`create` to normalise orientation and
    drop unused nodes; the plain constructor only validates.

    Parameters
    ----------
    points : ndarray, shape (n_nodes, dim)
        Node positions [mm], float64: dim 2 means the x-z plane (columns x, z), dim 3 is x, y, z.
    cells : ndarray, shape (n_cells, nen)
        int64 node indices in meshio/VTK node order, positively oriented.
    cell_type : str
        The meshio cell type.
    cell_groups : dict of str to ndarray, optional
        Name -> sorted int64 cell indices.
    facet_groups : dict of str to ndarray, optional
        Name -> (nf, nfn) int64 node indices of facets (``facet_type``), corners then mid-edge
        nodes in meshio order; facets on the mesh boundary are oriented outward.
    """

    points: np.ndarray
    cells: np.ndarray
    cell_type: str
    cell_groups: dict[str, np.ndarray] = field(default_factory=dict)
    facet_groups: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        if self.cell_type not in CELL_TYPES:
            raise ValueError(f"unsupported cell type {self.cell_type!r}; expected one of {CELL_TYPES}")
        pts = np.asarray(self.points, dtype=np.float64)
        cells = np.asarray(self.cells, dtype=np.int64)
        dim = _cell_dim(self.cell_type)
        if pts.ndim != 2 or pts.shape[1] != dim:
            raise ValueError(f"{self.cell_type} mesh needs points of shape (n, {dim}), got {pts.shape}")
        nen = _nodes(self.cell_type)
        if cells.ndim != 2 or cells.shape[1] != nen:
            raise ValueError(f"{self.cell_type} cells need shape (n, {nen}), got {cells.shape}")
        if cells.size and (cells.min() < 0 or cells.max() >= len(pts)):
            raise ValueError("cell node index out of range")
        cg = {}
        for name, idx in self.cell_groups.items():
            idx = np.unique(np.asarray(idx, dtype=np.int64).ravel())
            if idx.size and (idx[0] < 0 or idx[-1] >= len(cells)):
                raise ValueError(f"cell group {name!r}: index out of range")
            cg[str(name)] = _readonly(idx)
        nfn = _nodes(_facet_type(self.cell_type))
        fg = {}
        for name, fac in self.facet_groups.items():
            fac = np.asarray(fac, dtype=np.int64).reshape(-1, nfn)
            if fac.size and (fac.min() < 0 or fac.max() >= len(pts)):
                raise ValueError(f"facet group {name!r}: node index out of range")
            fg[str(name)] = _readonly(fac)
        object.__setattr__(self, "points", _readonly(pts))
        object.__setattr__(self, "cells", _readonly(cells))
        object.__setattr__(self, "cell_groups", cg)
        object.__setattr__(self, "facet_groups", fg)

    # -- construction ---------------------------------------------------------------------------

    @classmethod
    def create(
        cls,
        points,
        cells,
        cell_type: str,
        cell_groups: Mapping[str, np.ndarray] | None = None,
        facet_groups: Mapping[str, np.ndarray] | None = None,
        prune: bool = True,
    ) -> "Mesh":
        """Build a mesh, normalising it: flip negatively oriented cells (mid nodes follow),
        orient group facets that lie on the mesh boundary outward (node order taken from their
        owning cell), and with ``prune`` drop nodes used by no cell or facet (renumbering
        compactly, keeping the relative order)."""
        points = np.asarray(points, dtype=np.float64)
        cells = np.array(cells, dtype=np.int64)
        cell_groups = dict(cell_groups or {})
        facet_groups = {k: np.asarray(v, dtype=np.int64) for k, v in (facet_groups or {}).items()}
        if cells.size:
            neg = signed_measures(points, cells) < 0
            if np.any(neg):
                cells[neg] = cells[neg][:, list(_FLIP[cell_type])]
        nfn = _nodes(_facet_type(cell_type))
        if prune:
            used = [cells.ravel()] + [f.ravel() for f in facet_groups.values()]
            used = np.unique(np.concatenate(used))
            remap = np.full(len(points), -1, dtype=np.int64)
            remap[used] = np.arange(len(used))
            points = points[used]
            cells = remap[cells]
            facet_groups = {k: remap[v].reshape(-1, nfn) for k, v in facet_groups.items()}
        mesh = cls(points, cells, cell_type, cell_groups, {})
        if facet_groups:
            facet_groups = {k: mesh._orient_facets(v.reshape(-1, nfn)) for k, v in facet_groups.items()}
        return cls(mesh.points, mesh.cells, cell_type, mesh.cell_groups, facet_groups)

    def _orient_facets(self, facets: np.ndarray) -> np.ndarray:
        """Replace each facet that bounds exactly one cell by that cell's outward local facet."""
        if len(facets) == 0:
            return facets
        nc = self.dim  # corners per facet
        all_f = self.cells[:, _FACETS[self.cell_type]].reshape(-1, _FACETS[self.cell_type].shape[1])
        keys = np.vstack([np.sort(all_f[:, :nc], axis=1), np.sort(facets[:, :nc], axis=1)])
        n_all = len(all_f)
        order, starts, counts = _group_rows(keys)
        gid = np.repeat(np.arange(len(starts)), counts)  # group of each sorted position
        is_own = order < n_all
        n_own = np.bincount(gid, weights=is_own, minlength=len(starts))
        owner = np.full(len(starts), -1, dtype=np.int64)
        owner[gid[is_own]] = order[is_own]
        fix = ~is_own & (n_own[gid] == 1)
        out = facets.copy()
        out[order[fix] - n_all] = all_f[owner[gid[fix]]]
        return out

    # -- basic properties -----------------------------------------------------------------------

    @property
    def dim(self) -> int:
        """Spatial dimension (2: x-z plane, 3)."""
        return int(self.points.shape[1])

    @property
    def n_nodes(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_cells(self) -> int:
        return int(self.cells.shape[0])

    @property
    def facet_type(self) -> str:
        """meshio type of the facets: "line", "line3", "triangle" or "triangle6"."""
        return _facet_type(self.cell_type)

    @property
    def order(self) -> int:
        """Polynomial order of the cells (1 or 2)."""
        return element_for_meshio_type(self.cell_type).order

    @property
    def n_corners(self) -> int:
        """Corner nodes per cell (3 or 4)."""
        return self.dim + 1

    # -- queries --------------------------------------------------------------------------------

    def group_nodes(self, name: str) -> np.ndarray:
        """Sorted unique node indices of a facet group or a cell group."""
        in_f, in_c = name in self.facet_groups, name in self.cell_groups
        if in_f and in_c:
            raise ValueError(f"{name!r} is both a cell group and a facet group")
        if in_f:
            return np.unique(self.facet_groups[name])
        if in_c:
            return np.unique(self.cells[self.cell_groups[name]])
        raise KeyError(f"no group {name!r}; cell groups {sorted(self.cell_groups)}, "
                       f"facet groups {sorted(self.facet_groups)}")

    def boundary_facets(self, cells: np.ndarray | None = None, return_cells: bool = False):
        """Facets of a cell subset (indices or boolean mask; default all cells) that belong to
        exactly one cell of the subset, oriented outward, corners first then mid nodes in meshio
        order: (nf, nfn) int64. With ``return_cells`` also the owning cell index of each facet."""
        if cells is None:
            idx = np.arange(self.n_cells)
        else:
            idx = np.asarray(cells)
            idx = np.flatnonzero(idx) if idx.dtype == bool else idx.astype(np.int64).ravel()
        table = _FACETS[self.cell_type]
        nf_cell, nfn = table.shape
        f = self.cells[idx][:, table].reshape(-1, nfn)
        order, starts, counts = _group_rows(np.sort(f[:, : self.dim], axis=1))
        single = np.sort(order[starts[counts == 1]])
        if return_cells:
            return f[single], idx[single // nf_cell]
        return f[single]

    def cell_volumes(self, curved: bool = False) -> np.ndarray:
        """Signed area (2D) [mm^2] or volume (3D) [mm^3] of each cell; positive for a valid mesh.
        From the corner nodes (straight-sided) by default; with ``curved`` the isoparametric
        (possibly curved) quadratic cell is integrated exactly."""
        if not curved or self.order == 1:
            return signed_measures(self.points, self.cells[:, : self.n_corners])
        # det J of a quadratic cell is a polynomial of degree dim: a rule of that degree is exact
        rule = element_for_meshio_type(self.cell_type).with_quadrature(self.dim)
        return jacobian_determinants(self.points, self.cells, self.cell_type, rule.quad_points) @ rule.quad_weights

    def facet_measures(self, facets: np.ndarray) -> np.ndarray:
        """Length (2D) [mm] or area (3D) [mm^2] of facets from their corner nodes."""
        facets = np.asarray(facets, dtype=np.int64)
        if self.dim == 2:
            return np.linalg.norm(self.points[facets[:, 1]] - self.points[facets[:, 0]], axis=1)
        p0, p1, p2 = (self.points[facets[:, i]] for i in range(3))
        return 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)

    def facet_normals(self, facets: np.ndarray) -> np.ndarray:
        """Unit normals of facets from their corner nodes (outward for outward-oriented facets)."""
        facets = np.asarray(facets, dtype=np.int64)
        if self.dim == 2:
            t = self.points[facets[:, 1]] - self.points[facets[:, 0]]
            n = np.column_stack([t[:, 1], -t[:, 0]])
        else:
            p0, p1, p2 = (self.points[facets[:, i]] for i in range(3))
            n = np.cross(p1 - p0, p2 - p0)
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    # -- meshio I/O -----------------------------------------------------------------------------

    def to_meshio(self) -> meshio.Mesh:
        """meshio mesh: block 0 holds the cells, then one facet block per facet group. 2D points
        get a zero third column. Groups travel as cell data "group:<name>" (0/1 per cell of every
        block) and as gmsh physical tags ("gmsh:physical", "gmsh:geometrical", field_data); a cell
        in several cell groups carries the first one's physical tag."""
        pts = self.points if self.dim == 3 else np.column_stack([self.points, np.zeros(self.n_nodes)])
        fnames = list(self.facet_groups)
        blocks = [meshio.CellBlock(self.cell_type, np.asarray(self.cells))]
        blocks += [meshio.CellBlock(self.facet_type, np.asarray(self.facet_groups[n])) for n in fnames]
        sizes = [len(b.data) for b in blocks]
        cell_data: dict[str, list[np.ndarray]] = {}
        field_data: dict[str, np.ndarray] = {}
        phys = [np.zeros(s, dtype=np.int32) for s in sizes]
        tag = 0
        for name, idx in self.cell_groups.items():
            tag += 1
            ind = [np.zeros(s, dtype=np.int32) for s in sizes]
            ind[0][idx] = 1
            cell_data[f"group:{name}"] = ind
            free = idx[phys[0][idx] == 0]
            phys[0][free] = tag
            field_data[name] = np.array([tag, self.dim])
        for b, name in enumerate(fnames, start=1):
            tag += 1
            ind = [np.zeros(s, dtype=np.int32) for s in sizes]
            ind[b][:] = 1
            cell_data[f"group:{name}"] = ind
            phys[b][:] = tag
            field_data[name] = np.array([tag, self.dim - 1])
        cell_data["gmsh:physical"] = phys
        cell_data["gmsh:geometrical"] = [np.full(s, b + 1, dtype=np.int32) for b, s in enumerate(sizes)]
        return meshio.Mesh(pts, blocks, cell_data=cell_data, field_data=field_data)

    @classmethod
    def from_meshio(cls, m: meshio.Mesh, dim: int | None = None, prune: bool = True) -> "Mesh":
        """Mesh from a meshio mesh. The cells are the blocks of the highest simplex dimension
        (or ``dim``); groups are read from "group:<name>" cell data if present, else from
        cell_sets, else from gmsh physical tags with field_data names. 2D meshes keep the first
        two point columns. ``prune`` drops nodes that no cell or group facet uses."""
        types = {b.type for b in m.cells}
        if dim is None:
            dim = 3 if types & {"tetra", "tetra10"} else 2
        cand = [t for t in types if t in CELL_TYPES and _cell_dim(t) == dim]
        if len(cand) != 1:
            raise ValueError(f"need exactly one {dim}D cell type in the meshio mesh, found {sorted(types)}")
        cell_type = cand[0]
        facet_type = _facet_type(cell_type)
        cell_blocks = [i for i, b in enumerate(m.cells) if b.type == cell_type]
        facet_blocks = [i for i, b in enumerate(m.cells) if b.type == facet_type]
        offsets = {}
        off = 0
        for i in cell_blocks:
            offsets[i] = off
            off += len(m.cells[i].data)
        cells = np.concatenate([np.asarray(m.cells[i].data) for i in cell_blocks]).astype(np.int64)

        # membership[name][block] = indices of that block's rows in the group
        membership: dict[str, dict[int, np.ndarray]] = {}
        gkeys = [k for k in m.cell_data if k.startswith("group:")]
        if gkeys:
            for k in gkeys:
                membership[k[len("group:"):]] = {
                    i: np.flatnonzero(np.asarray(m.cell_data[k][i]).ravel()) for i in range(len(m.cells))
                }
        elif any(k != "gmsh:bounding_entities" for k in m.cell_sets):
            for name, per_block in m.cell_sets.items():
                if name == "gmsh:bounding_entities":
                    continue
                membership[name] = {
                    i: np.asarray(a, dtype=np.int64).ravel() for i, a in enumerate(per_block) if a is not None
                }
        elif "gmsh:physical" in m.cell_data and m.field_data:
            phys = m.cell_data["gmsh:physical"]
            for name, (tag, gdim) in ((n, tuple(np.asarray(v).ravel()[:2])) for n, v in m.field_data.items()):
                membership[name] = {
                    i: np.flatnonzero(np.asarray(phys[i]).ravel() == tag)
                    for i, b in enumerate(m.cells)
                    if (gdim == dim and b.type == cell_type) or (gdim == dim - 1 and b.type == facet_type)
                }

        cell_groups, facet_groups = {}, {}
        for name, per_block in membership.items():
            c = [offsets[i] + a for i, a in per_block.items() if i in offsets and len(a)]
            f = [np.asarray(m.cells[i].data)[a] for i, a in per_block.items() if i in facet_blocks and len(a)]
            if c:
                cell_groups[name] = np.concatenate(c)
            if f:
                facet_groups[name] = np.concatenate(f)
        pts = np.asarray(m.points, dtype=np.float64)[:, :dim]
        return cls.create(pts, cells, cell_type, cell_groups, facet_groups, prune=prune)

    def write(self, path: str | os.PathLike, **kwargs) -> None:
        """Write with meshio, format from the extension (.vtu, .xdmf, .msh, ...). ``.msh`` is
        written as ASCII gmsh 2.2 unless ``file_format`` is given; there groups are physical
        tags only, so a cell in several cell groups keeps only the first."""
        path = os.fspath(path)
        if path.lower().endswith(".msh") and "file_format" not in kwargs:
            kwargs = {"file_format": "gmsh22", "binary": False, **kwargs}
        m = self.to_meshio()
        if kwargs.get("file_format", "").startswith("gmsh") or path.lower().endswith(".msh"):
            # meshio 5.3's ASCII gmsh writer garbles element data under numpy 2 ("np.int32(1)"),
            # so gmsh files carry the groups as physical tags only
            m.cell_data = {k: v for k, v in m.cell_data.items() if not k.startswith("group:")}
        meshio.write(path, m, **kwargs)

    @classmethod
    def read(cls, path: str | os.PathLike, dim: int | None = None) -> "Mesh":
        """Read any meshio-supported file (see :meth:`from_meshio`)."""
        return cls.from_meshio(meshio.read(os.fspath(path)), dim=dim)

    def __repr__(self) -> str:
        return (f"Mesh({self.cell_type}, n_nodes={self.n_nodes}, n_cells={self.n_cells}, "
                f"cell_groups={sorted(self.cell_groups)}, facet_groups={sorted(self.facet_groups)})")


def merge(parts: dict[str, Mesh]) -> Mesh:
    """Separate meshes side by side in one Mesh (no node is shared: separate bodies).

    Groups are renamed ``"<part>"`` (all cells of a part), ``"<part>/<group>"`` for each cell and
    facet group.

    Parameters
    ----------
    parts : dict of str to Mesh
        Part name -> mesh [mm]; all of the same cell type.

    Returns
    -------
    Mesh

    Raises
    ------
    ValueError
        For parts of different cell types.
    """
    types = {m.cell_type for m in parts.values()}
    if len(types) != 1:
        raise ValueError(f"cannot merge meshes of different cell types {sorted(types)}")
    points, cells, cgroups, fgroups = [], [], {}, {}
    n_nodes = n_cells = 0
    for name, m in parts.items():
        points.append(m.points)
        cells.append(m.cells + n_nodes)
        cgroups[name] = np.arange(n_cells, n_cells + m.n_cells)
        for g, idx in m.cell_groups.items():
            cgroups[f"{name}/{g}"] = idx + n_cells
        for g, fac in m.facet_groups.items():
            fgroups[f"{name}/{g}"] = fac + n_nodes
        n_nodes += m.n_nodes
        n_cells += m.n_cells
    return Mesh(np.vstack(points), np.vstack(cells), types.pop(), cgroups, fgroups)
