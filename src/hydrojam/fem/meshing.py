"""Every call to gmsh lives here (project rule: a gmsh upgrade touches one file).

:func:`gmsh_session` opens a deterministic, quiet gmsh session holding a fresh model;
:func:`extract_mesh` turns the current meshed model into a :class:`~hydrojam.fem.mesh.Mesh`; the
shape builders (:func:`rectangle`, :func:`disk`, :func:`box`, :func:`ball`,
:func:`bonded_rectangles`, :func:`disks`, :func:`annulus`, :func:`shell_sector`, ...) make small
meshes for tests and verification.
Lengths in mm. 2D shapes are drawn in gmsh's x-y plane and returned with two point columns,
which the caller reads as x-z.
"""

from __future__ import annotations

import itertools
import signal
import threading
from contextlib import contextmanager
from typing import Iterator, Sequence

import gmsh
import numpy as np

from hydrojam.fem.mesh import MID_EDGES, Mesh

RANDOM_SEED = 1234

# gmsh element type -> meshio type (simplices only)
_GMSH_TYPES = {1: "line", 8: "line3", 2: "triangle", 9: "triangle6", 4: "tetra", 11: "tetra10"}

_model_counter = itertools.count()


# ----------------------------------------------------------------------------------------------
# Session
# ----------------------------------------------------------------------------------------------


# options this module changes after the session setup; a nested session restores them on exit
_SCOPED_OPTIONS = (
    "Mesh.MeshSizeMin", "Mesh.MeshSizeMax", "Mesh.MeshSizeExtendFromBoundary", "Mesh.ElementOrder",
)


def _set_options() -> None:
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.Verbosity", 1)
    gmsh.option.setNumber("General.NumThreads", 1)
    for opt in ("Mesh.MaxNumThreads1D", "Mesh.MaxNumThreads2D", "Mesh.MaxNumThreads3D"):
        gmsh.option.setNumber(opt, 1)
    gmsh.option.setNumber("Mesh.RandomSeed", RANDOM_SEED)


def _python_signal_handlers() -> dict:
    """The signals with a Python handler (SIGINT's, a command's SIGTERM), by number: gmsh's
    initialisation replaces some of them in the C library, out of Python's sight, and they are
    installed again after it. Empty outside the main thread (where none can be installed)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {s: h for s in signal.valid_signals() if callable(h := signal.getsignal(s))}


@contextmanager
def gmsh_session() -> Iterator[str]:
    """Context manager for a gmsh session holding a fresh, current model.

    Initialises gmsh without signal handling (the Python handlers it replaces put back) and
    quiet, single-threaded, with a fixed random seed so meshes are reproducible. Nesting is safe: an inner session adds its own model,
    removes it on exit and restores the outer model; only the outermost session finalises
    gmsh, also when an exception escapes.

    Yields
    ------
    str
        The model's name.
    """
    outer = bool(gmsh.isInitialized())
    if not outer:
        handlers = _python_signal_handlers()
        try:
            gmsh.initialize(readConfigFiles=False, interruptible=False)
        except TypeError:  # older gmsh without the interruptible flag
            gmsh.initialize(readConfigFiles=False)
        for signum, handler in handlers.items():  # gmsh's start-up resets SIGTERM's to the default
            signal.signal(signum, handler)
    try:
        saved = {o: gmsh.option.getNumber(o) for o in _SCOPED_OPTIONS} if outer else {}
        _set_options()
        previous = gmsh.model.getCurrent() if outer else None
        name = f"hydrojam_{next(_model_counter)}"
        gmsh.model.add(name)
        try:
            yield name
        finally:
            if outer:
                try:
                    gmsh.model.setCurrent(name)
                    gmsh.model.remove()
                finally:
                    for o, val in saved.items():
                        gmsh.option.setNumber(o, val)
                    if previous:
                        gmsh.model.setCurrent(previous)
    finally:
        if not outer:
            gmsh.finalize()


# ----------------------------------------------------------------------------------------------
# Extraction
# ----------------------------------------------------------------------------------------------


def gmsh_to_meshio_order(gmsh_type: int) -> np.ndarray:
    """Permutation ``p`` with ``meshio_nodes = gmsh_nodes[:, p]`` for a simplex element type.

    Derived from gmsh's reference-element node coordinates: corners keep their order and each
    meshio mid node is the gmsh node at the midpoint of the meshio edge (for tetra10 this swaps
    the last two nodes: gmsh puts the (2,3) edge before the (1,3) edge)."""
    mtype = _GMSH_TYPES[gmsh_type]
    _, edim, order, nn, ref, ncorner = gmsh.model.mesh.getElementProperties(gmsh_type)
    if order == 1:
        return np.arange(nn)
    ref = np.asarray(ref, dtype=float).reshape(nn, edim)
    target = np.vstack([ref[:ncorner]] + [0.5 * (ref[a] + ref[b]) for a, b in MID_EDGES[mtype]])
    if len(target) != nn:
        raise RuntimeError(f"gmsh element type {gmsh_type} has {nn} nodes, meshio {mtype} {len(target)}")
    d = np.linalg.norm(target[:, None, :] - ref[None, :, :], axis=2)
    perm = np.argmin(d, axis=1)
    if not np.allclose(d[np.arange(nn), perm], 0.0) or len(set(perm.tolist())) != nn:
        raise RuntimeError(f"cannot map gmsh element type {gmsh_type} to meshio {mtype}")
    return perm


def _elements(dim: int, entities: Sequence[int]):
    """(element tags, meshio type, connectivity as gmsh node tags) of the given entities."""
    tags, conns, mtype = [], [], None
    for ent in entities:
        etypes, etags, enodes = gmsh.model.mesh.getElements(dim, ent)
        for et, t, n in zip(etypes, etags, enodes):
            if et not in _GMSH_TYPES:
                raise ValueError(f"gmsh element type {et} on entity ({dim}, {ent}) is not a simplex")
            if mtype is not None and _GMSH_TYPES[et] != mtype:
                raise ValueError(f"mixed element types in dimension {dim}: {mtype}, {_GMSH_TYPES[et]}")
            mtype = _GMSH_TYPES[et]
            nn = len(n) // len(t)
            tags.append(np.asarray(t, dtype=np.int64))
            conns.append(np.asarray(n, dtype=np.int64).reshape(-1, nn)[:, gmsh_to_meshio_order(et)])
    if not tags:
        return np.zeros(0, np.int64), None, None
    return np.concatenate(tags), mtype, np.vstack(conns)


def _physical_groups(dim: int):
    out = []
    for d, tag in gmsh.model.getPhysicalGroups(dim):
        name = gmsh.model.getPhysicalName(d, tag) or f"group{tag}"
        out.append((name, gmsh.model.getEntitiesForPhysicalGroup(d, tag)))
    return out


def extract_mesh(dim: int, order: int | None = None) -> Mesh:
    """Mesh of the current (meshed) gmsh model.

    Physical groups of dimension ``dim`` become cell groups, those of dimension ``dim - 1``
    facet groups (by name). Only nodes of elements in physical groups are kept, numbered
    compactly in gmsh node-tag order; cells are sorted by gmsh element tag; node order is
    converted to meshio's and orientation normalised (see :meth:`Mesh.create`).

    Parameters
    ----------
    dim : int
        The cells' dimension, 2 or 3.
    order : int, optional
        Bring the mesh to this order first (``setOrder``) if it is not already.

    Returns
    -------
    Mesh
        Positions in the model's length unit [mm].

    Raises
    ------
    ValueError
        Where the model has no physical group of dimension ``dim``, or more than one cell type.
    """
    cell_pg = _physical_groups(dim)
    if not cell_pg:
        raise ValueError(f"the gmsh model has no physical group of dimension {dim}")
    if order is not None:
        _, _, probe = _elements(dim, cell_pg[0][1])
        have = {3: 1, 4: 1, 6: 2, 10: 2}.get(probe.shape[1]) if probe is not None else None
        if have != order:
            set_order(dim, order)

    per_group = [(name, *_elements(dim, ents)) for name, ents in cell_pg]
    types = {t for _, _, t, _ in per_group if t is not None}
    if len(types) != 1:
        raise ValueError(f"expected one cell type in dimension {dim}, got {sorted(types)}")
    cell_type = types.pop()
    all_tags = np.concatenate([t for _, t, _, _ in per_group])
    all_conn = np.vstack([c for _, _, _, c in per_group if c is not None])
    uniq_tags, first = np.unique(all_tags, return_index=True)
    conn = all_conn[first]  # cells sorted by element tag
    cell_groups = {name: np.searchsorted(uniq_tags, t) for name, t, _, _ in per_group}

    facet_groups = {}
    for name, ents in _physical_groups(dim - 1):
        _, _, fconn = _elements(dim - 1, ents)
        if fconn is not None:
            facet_groups[name] = fconn

    node_tags, coords, _ = gmsh.model.mesh.getNodes(returnParametricCoord=False)
    node_tags = np.asarray(node_tags, dtype=np.int64)
    coords = np.asarray(coords, dtype=float).reshape(-1, 3)[:, :dim]
    srt = np.argsort(node_tags)
    node_tags, coords = node_tags[srt], coords[srt]

    def to_index(a):
        i = np.searchsorted(node_tags, a)
        if np.any(i >= len(node_tags)) or np.any(node_tags[np.minimum(i, len(node_tags) - 1)] != a):
            raise RuntimeError("element references an unknown gmsh node")
        return i

    return Mesh.create(
        coords,
        to_index(conn),
        cell_type,
        cell_groups,
        {k: to_index(v) for k, v in facet_groups.items()},
        prune=True,
    )


def set_order(dim: int, order: int) -> None:
    """Bring the current mesh to ``order`` (1 or 2). Quadratic nodes of curved boundaries are
    placed on the geometry; if that leaves an element with a non-positive Jacobian somewhere,
    gmsh's high-order optimiser is run, and an error raised if it cannot fix it."""
    if order not in (1, 2):
        raise ValueError(f"order must be 1 or 2, got {order}")
    gmsh.model.mesh.setOrder(order)
    if order == 1:
        return
    etypes, etags, _ = gmsh.model.mesh.getElements(dim)
    tags = np.concatenate([np.asarray(t) for t in etags]) if len(etags) else np.zeros(0)
    if len(tags) == 0:
        return
    q = np.asarray(gmsh.model.mesh.getElementQualities(tags.tolist(), "minSJ"))
    if np.all(q > 0):
        return
    gmsh.model.mesh.optimize("HighOrder")
    etypes, etags, _ = gmsh.model.mesh.getElements(dim)
    tags = np.concatenate([np.asarray(t) for t in etags])
    q = np.asarray(gmsh.model.mesh.getElementQualities(tags.tolist(), "minSJ"))
    if np.any(q <= 0):
        raise RuntimeError(f"{int(np.sum(q <= 0))} invalid quadratic elements after optimisation")


# ----------------------------------------------------------------------------------------------
# Shapes
# ----------------------------------------------------------------------------------------------


def set_mesh_size(size: float) -> None:
    """Target element size [mm] of the next mesh (inside a :func:`gmsh_session`)."""
    if not size > 0:
        raise ValueError(f"mesh size must be positive, got {size}")
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)


def generate(dim: int, order: int) -> Mesh:
    """Mesh the current gmsh model in ``dim`` dimensions at element ``order`` and extract it."""
    gmsh.model.mesh.generate(dim)
    set_order(dim, order)
    return extract_mesh(dim)


def bounding_box(dim: int, tag: int) -> np.ndarray:
    """Bounding box [[xmin, ymin, zmin], [xmax, ymax, zmax]] [mm] of entity (dim, tag)."""
    return np.asarray(gmsh.model.getBoundingBox(dim, tag), dtype=float).reshape(2, 3)


def _classify_sides(dim_tags, lo, hi, names, tol):
    """Group boundary entities lying on the planes x = lo[0], x = hi[0], y = lo[1], ... into
    ``names`` (ordered xmin, xmax, ymin, ymax[, zmin, zmax])."""
    out = {n: [] for n in names}
    # OCC bounding boxes are padded by the geometric tolerance (about 1e-7 mm)
    tol = max(tol, 1e-6)
    for d, t in dim_tags:
        bb = bounding_box(d, t)
        for k, n in enumerate(names):
            axis, side = divmod(k, 2)
            plane = (lo if side == 0 else hi)[axis]
            if abs(bb[0, axis] - plane) < tol and abs(bb[1, axis] - plane) < tol:
                out[n].append(t)
    return out


def add_groups(dim: int, cell_groups: dict[str, list[int]], facet_groups: dict[str, list[int]]):
    """Name entity tags as physical groups: cells of dimension ``dim``, facets of ``dim`` - 1."""
    for name, tags in cell_groups.items():
        gmsh.model.addPhysicalGroup(dim, sorted(tags), name=name)
    for name, tags in facet_groups.items():
        if tags:
            gmsh.model.addPhysicalGroup(dim - 1, sorted(tags), name=name)


def rectangle(lx: float, ly: float, size: float, order: int = 2, origin=(0.0, 0.0),
              structured: bool = False, arrangement: str = "Left") -> Mesh:
    """Rectangle [x0, x0 + lx] x [z0, z0 + ly] of triangles.

    Cell group "body"; facet groups "left", "right", "bottom", "top".

    Parameters
    ----------
    lx, ly : float
        Side lengths along x and z [mm].
    size : float
        Element size [mm].
    order : {1, 2}, optional
        Element order.
    origin : tuple of float, optional
        The corner (x0, z0) [mm].
    structured : bool, optional
        A transfinite regular triangulation with round(lx/size) x round(ly/size) divisions, for
        convergence studies.
    arrangement : str, optional
        gmsh's arrangement of a structured mesh ("Left", "Right", "Alternate", ...).

    Returns
    -------
    Mesh
    """
    with gmsh_session():
        set_mesh_size(size)
        x0, y0 = float(origin[0]), float(origin[1])
        s = gmsh.model.occ.addRectangle(x0, y0, 0.0, lx, ly)
        gmsh.model.occ.synchronize()
        curves = gmsh.model.getBoundary([(2, s)], oriented=False)
        sides = _classify_sides(curves, (x0, y0), (x0 + lx, y0 + ly),
                                ("left", "right", "bottom", "top"), 1e-6 * max(lx, ly))
        if structured:
            nx, ny = max(1, round(lx / size)), max(1, round(ly / size))
            for name, n in (("left", ny), ("right", ny), ("bottom", nx), ("top", nx)):
                for c in sides[name]:
                    gmsh.model.mesh.setTransfiniteCurve(c, n + 1)
            gmsh.model.mesh.setTransfiniteSurface(s, arrangement)
        add_groups(2, {"body": [s]}, sides)
        return generate(2, order)


def disk(radius: float, size: float, order: int = 2, centre=(0.0, 0.0)) -> Mesh:
    """Disk about ``centre`` in the x-z plane. Cell group "body", facet group "boundary".

    Parameters
    ----------
    radius : float
        Radius [mm].
    size : float
        Element size [mm].
    order : {1, 2}, optional
        Element order.
    centre : tuple of float, optional
        Centre (x, z) [mm].

    Returns
    -------
    Mesh
    """
    with gmsh_session():
        set_mesh_size(size)
        s = gmsh.model.occ.addDisk(float(centre[0]), float(centre[1]), 0.0, radius, radius)
        gmsh.model.occ.synchronize()
        curves = [t for _, t in gmsh.model.getBoundary([(2, s)], oriented=False)]
        add_groups(2, {"body": [s]}, {"boundary": curves})
        return generate(2, order)


def box(lx: float, ly: float, lz: float, size: float, order: int = 2, origin=(0.0, 0.0, 0.0)) -> Mesh:
    """Box [x0, x0+lx] x [y0, y0+ly] x [z0, z0+lz] of tetrahedra.

    Cell group "body"; facet groups "xmin", "xmax", "ymin", "ymax", "zmin", "zmax".

    Parameters
    ----------
    lx, ly, lz : float
        Side lengths [mm].
    size : float
        Element size [mm].
    order : {1, 2}, optional
        Element order.
    origin : tuple of float, optional
        The corner (x0, y0, z0) [mm].

    Returns
    -------
    Mesh
    """
    with gmsh_session():
        set_mesh_size(size)
        o = [float(v) for v in origin]
        v = gmsh.model.occ.addBox(*o, lx, ly, lz)
        gmsh.model.occ.synchronize()
        faces = gmsh.model.getBoundary([(3, v)], oriented=False)
        hi = (o[0] + lx, o[1] + ly, o[2] + lz)
        sides = _classify_sides(faces, o, hi, ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"),
                                1e-6 * max(lx, ly, lz))
        add_groups(3, {"body": [v]}, sides)
        return generate(3, order)


def ball(radius: float, size: float, order: int = 2, centre=(0.0, 0.0, 0.0)) -> Mesh:
    """Ball about ``centre``. Cell group "body", facet group "boundary".

    Parameters
    ----------
    radius : float
        Radius [mm].
    size : float
        Element size [mm].
    order : {1, 2}, optional
        Element order.
    centre : tuple of float, optional
        Centre (x, y, z) [mm].

    Returns
    -------
    Mesh
    """
    with gmsh_session():
        set_mesh_size(size)
        v = gmsh.model.occ.addSphere(*[float(c) for c in centre], radius)
        gmsh.model.occ.synchronize()
        faces = [t for _, t in gmsh.model.getBoundary([(3, v)], oriented=False)]
        add_groups(3, {"body": [v]}, {"boundary": faces})
        return generate(3, order)


def bonded_rectangles(lx1: float, lx2: float, ly: float, size: float, order: int = 2) -> Mesh:
    """Two rectangles [0, lx1] x [0, ly] and [lx1, lx1 + lx2] x [0, ly] meshed conformally.

    They share the nodes on x = lx1 (a bonded interface). Cell groups "left_body",
    "right_body"; facet groups "left", "right", "bottom", "top" (outer boundary pieces).

    Parameters
    ----------
    lx1, lx2 : float
        Widths of the two rectangles along x [mm].
    ly : float
        Their common height along z [mm].
    size : float
        Element size [mm].
    order : {1, 2}, optional
        Element order.

    Returns
    -------
    Mesh
    """
    with gmsh_session():
        set_mesh_size(size)
        a = gmsh.model.occ.addRectangle(0.0, 0.0, 0.0, lx1, ly)
        b = gmsh.model.occ.addRectangle(lx1, 0.0, 0.0, lx2, ly)
        gmsh.model.occ.fragment([(2, a)], [(2, b)])
        gmsh.model.occ.synchronize()
        surfaces = gmsh.model.getEntities(2)
        left, right = [], []
        for _, t in surfaces:
            cx = bounding_box(2, t)[:, 0].mean()
            (left if cx < lx1 else right).append(t)
        outer = gmsh.model.getBoundary(surfaces, combined=True, oriented=False)
        sides = _classify_sides(outer, (0.0, 0.0), (lx1 + lx2, ly),
                                ("left", "right", "bottom", "top"), 1e-6 * max(lx1 + lx2, ly))
        add_groups(2, {"left_body": left, "right_body": right}, sides)
        return generate(2, order)


def disks(centres, radii, size: float, order: int = 2) -> Mesh:
    """Separate disks that share no nodes (separate bodies, e.g. for contact).

    Cell groups "disk0", "disk1", ...; facet groups "disk0_boundary", ...

    Parameters
    ----------
    centres : array_like, shape (m, 2)
        Centres (x, z) [mm].
    radii : float or array_like, shape (m,)
        Radii [mm]; a scalar for all.
    size : float
        Element size [mm].
    order : {1, 2}, optional
        Element order.

    Returns
    -------
    Mesh

    Raises
    ------
    ValueError
        For overlapping disks.
    """
    centres = np.atleast_2d(np.asarray(centres, dtype=float))
    radii = np.broadcast_to(np.asarray(radii, dtype=float), (len(centres),))
    for i, j in itertools.combinations(range(len(centres)), 2):
        if np.linalg.norm(centres[i] - centres[j]) < radii[i] + radii[j]:
            raise ValueError(f"disks {i} and {j} overlap")
    with gmsh_session():
        set_mesh_size(size)
        tags = [gmsh.model.occ.addDisk(c[0], c[1], 0.0, r, r) for c, r in zip(centres, radii)]
        gmsh.model.occ.synchronize()
        cell_groups, facet_groups = {}, {}
        for k, s in enumerate(tags):
            cell_groups[f"disk{k}"] = [s]
            boundary = gmsh.model.getBoundary([(2, s)], oriented=False)
            facet_groups[f"disk{k}_boundary"] = [t for _, t in boundary]
        add_groups(2, cell_groups, facet_groups)
        return generate(2, order)


def quarter_disk(radius: float, size: float, order: int = 2) -> Mesh:
    """Quarter disk x >= 0, z >= 0 of ``radius`` (mm) about the origin, for symmetric problems.
    Cell group "body"; facet groups "xsym" (x = 0), "zsym" (z = 0), "arc"."""
    with gmsh_session():
        set_mesh_size(size)
        s = gmsh.model.occ.addDisk(0.0, 0.0, 0.0, radius, radius)
        cut = gmsh.model.occ.addRectangle(0.0, 0.0, 0.0, 2 * radius, 2 * radius)
        (out, _) = gmsh.model.occ.intersect([(2, s)], [(2, cut)])
        gmsh.model.occ.synchronize()
        body = [t for d, t in out if d == 2]
        curves = gmsh.model.getBoundary([(2, t) for t in body], oriented=False)
        sides = _classify_sides(curves, (0.0, 0.0), (radius, radius), ("xsym", "_", "zsym", "__"), 1e-6 * radius)
        straight = set(sides["xsym"]) | set(sides["zsym"])
        arc = [t for _, t in curves if t not in straight]
        add_groups(2, {"body": body}, {"xsym": sides["xsym"], "zsym": sides["zsym"], "arc": arc})
        return generate(2, order)


def annulus(r_in: float, r_out: float, size: float, order: int = 2) -> Mesh:
    """Annulus r_in <= r <= r_out about the origin in the x-z plane (a thick-walled cylinder in
    plane strain).

    Each circle is drawn as four quarter arcs, so nodes lie on both axes at (+-r, 0) and
    (0, +-r) for symmetry conditions. Cell group "body"; facet groups "inner" and "outer".

    Parameters
    ----------
    r_in, r_out : float
        Inner and outer radius [mm], 0 < r_in < r_out.
    size : float
        Element size [mm].
    order : {1, 2}, optional
        Element order.

    Returns
    -------
    Mesh

    Raises
    ------
    ValueError
        Unless 0 < r_in < r_out.
    """
    if not 0 < r_in < r_out:
        raise ValueError(f"annulus needs 0 < r_in < r_out, got r_in = {r_in}, r_out = {r_out}")
    with gmsh_session():
        set_mesh_size(size)
        occ = gmsh.model.occ
        centre = occ.addPoint(0.0, 0.0, 0.0)
        loops, arcs = [], {}
        for name, r in (("outer", r_out), ("inner", r_in)):
            p = [occ.addPoint(x, y, 0.0) for x, y in ((r, 0.0), (0.0, r), (-r, 0.0), (0.0, -r))]
            arcs[name] = [occ.addCircleArc(p[k], centre, p[(k + 1) % 4]) for k in range(4)]
            loops.append(occ.addCurveLoop(arcs[name]))
        s = occ.addPlaneSurface(loops)
        occ.synchronize()
        add_groups(2, {"body": [s]}, arcs)
        return generate(2, order)


def ball_octant(radius: float, size: float, order: int = 2) -> Mesh:
    """Octant x, y, z >= 0 of a ball of ``radius`` (mm) about the origin, for symmetric problems.
    Cell group "body"; facet groups "xsym", "ysym", "zsym" (the symmetry planes), "sphere"."""
    with gmsh_session():
        set_mesh_size(size)
        v = gmsh.model.occ.addSphere(0.0, 0.0, 0.0, radius)
        cut = gmsh.model.occ.addBox(0.0, 0.0, 0.0, 2 * radius, 2 * radius, 2 * radius)
        (out, _) = gmsh.model.occ.intersect([(3, v)], [(3, cut)])
        gmsh.model.occ.synchronize()
        body = [t for d, t in out if d == 3]
        faces = gmsh.model.getBoundary([(3, t) for t in body], oriented=False)
        sides = _classify_sides(faces, (0.0, 0.0, 0.0), (radius,) * 3,
                                ("xsym", "_", "ysym", "__", "zsym", "___"), 1e-6 * radius)
        planes = set(sides["xsym"]) | set(sides["ysym"]) | set(sides["zsym"])
        sphere = [t for _, t in faces if t not in planes]
        add_groups(3, {"body": body}, {"xsym": sides["xsym"], "ysym": sides["ysym"], "zsym": sides["zsym"],
                                         "sphere": sphere})
        return generate(3, order)


def shell_sector(r_in: float, r_out: float, size: float, dim: int = 3, order: int = 2) -> Mesh:
    """The part x, z >= 0 (2D: a quarter annulus) or x, y, z >= 0 (3D: an octant of a spherical
    shell) of the shell r_in <= r <= r_out about the origin, for symmetric problems.

    Cell group "body"; facet groups "xsym", "zsym" (and in 3D "ysym"): the symmetry planes,
    "inner" (r = r_in) and "outer" (r = r_out). 2D is drawn in the x-z plane like
    :func:`quarter_disk`.

    Parameters
    ----------
    r_in, r_out : float
        Inner and outer radius [mm], 0 < r_in < r_out.
    size : float
        Element size [mm].
    dim : (2, 3), optional
        The dimension.
    order : {1, 2}, optional
        Element order.

    Returns
    -------
    Mesh

    Raises
    ------
    ValueError
        Unless 0 < r_in < r_out and dim is 2 or 3.
    """
    if not 0 < r_in < r_out:
        raise ValueError(f"shell_sector needs 0 < r_in < r_out, got r_in = {r_in}, r_out = {r_out}")
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim}")
    with gmsh_session():
        set_mesh_size(size)
        occ = gmsh.model.occ
        if dim == 2:
            solid = occ.cut([(2, occ.addDisk(0.0, 0.0, 0.0, r_out, r_out))], [(2, occ.addDisk(0.0, 0.0, 0.0, r_in, r_in))])[0]
            quadrant = [(2, occ.addRectangle(0.0, 0.0, 0.0, 2 * r_out, 2 * r_out))]
            names = ("xsym", "_", "zsym", "__")
        else:
            solid = occ.cut([(3, occ.addSphere(0.0, 0.0, 0.0, r_out))], [(3, occ.addSphere(0.0, 0.0, 0.0, r_in))])[0]
            quadrant = [(3, occ.addBox(0.0, 0.0, 0.0, 2 * r_out, 2 * r_out, 2 * r_out))]
            names = ("xsym", "_", "ysym", "__", "zsym", "___")
        out, _ = occ.intersect(solid, quadrant)
        occ.synchronize()
        body = [t for d, t in out if d == dim]
        faces = gmsh.model.getBoundary([(dim, t) for t in body], oriented=False)
        sides = _classify_sides(faces, (0.0,) * dim, (r_out,) * dim, names, 1e-6 * r_out)
        planes = {n: sides[n] for n in names if not n.startswith("_")}
        flat = set().union(*planes.values())
        curved = [t for _, t in faces if t not in flat]
        # the inner surface lies within r_in of the origin, the outer reaches out to r_out
        inner = [t for t in curved if np.abs(bounding_box(dim - 1, t)[1]).max() < 0.5 * (r_in + r_out)]
        outer = [t for t in curved if t not in inner]
        add_groups(dim, {"body": body}, {**planes, "inner": inner, "outer": outer})
        return generate(dim, order)


def _refine_near(point, fine_size: float, fine_radius: float, size: float) -> None:
    """Mesh size fine_size within fine_radius of point, growing linearly to size at 3 fine_radius."""
    gmsh.option.setNumber("Mesh.MeshSizeMin", min(fine_size, size))
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    f = gmsh.model.mesh.field.add("MathEval")
    x, y = float(point[0]), float(point[1])
    z = float(point[2]) if len(point) > 2 else 0.0
    r = f"Sqrt((x-({x}))^2+(y-({y}))^2+(z-({z}))^2)"
    gmsh.model.mesh.field.setString(
        f, "F", f"Min({size}, Max({fine_size}, {fine_size} + ({size}-{fine_size})*({r}-{fine_radius})/(2*{fine_radius})))"
    )
    gmsh.model.mesh.field.setAsBackgroundMesh(f)


def half_disk(radius: float, size: float, fine_size: float, fine_radius: float, order: int = 2) -> Mesh:
    """Lower half disk (z <= 0) of ``radius`` (mm) about the origin, refined to ``fine_size``
    within ``fine_radius`` of its bottom point (0, -radius): a cylinder for Hertz contact.
    Cell group "body"; facet groups "top" (the flat face z = 0) and "arc"."""
    with gmsh_session():
        set_mesh_size(size)
        d = gmsh.model.occ.addDisk(0.0, 0.0, 0.0, radius, radius)
        cut = gmsh.model.occ.addRectangle(-2 * radius, -2 * radius, 0.0, 4 * radius, 2 * radius)
        (out, _) = gmsh.model.occ.intersect([(2, d)], [(2, cut)])
        gmsh.model.occ.synchronize()
        body = [t for dd, t in out if dd == 2]
        curves = gmsh.model.getBoundary([(2, t) for t in body], oriented=False)
        top = [t for _, t in curves if abs(bounding_box(1, t)[0, 1]) < 1e-6 * radius and abs(bounding_box(1, t)[1, 1]) < 1e-6 * radius]
        arc = [t for _, t in curves if t not in top]
        add_groups(2, {"body": body}, {"top": top, "arc": arc})
        _refine_near((0.0, -radius), fine_size, fine_radius, size)
        return generate(2, order)


def quarter_hemisphere(radius: float, size: float, fine_size: float, fine_radius: float, order: int = 2) -> Mesh:
    """Quarter of the lower hemisphere (x, y >= 0, z <= 0) of ``radius`` (mm), refined near its
    bottom pole (0, 0, -radius): a sphere for Hertz contact with two symmetry planes.
    Cell group "body"; facet groups "top" (z = 0), "xsym" (x = 0), "ysym" (y = 0), "sphere"."""
    with gmsh_session():
        set_mesh_size(size)
        v = gmsh.model.occ.addSphere(0.0, 0.0, 0.0, radius)
        cut = gmsh.model.occ.addBox(0.0, 0.0, -2 * radius, 2 * radius, 2 * radius, 2 * radius)
        (out, _) = gmsh.model.occ.intersect([(3, v)], [(3, cut)])
        gmsh.model.occ.synchronize()
        body = [t for dd, t in out if dd == 3]
        faces = gmsh.model.getBoundary([(3, t) for t in body], oriented=False)
        sides = _classify_sides(faces, (0.0, 0.0, -radius), (radius, radius, 0.0),
                                ("xsym", "_", "ysym", "__", "___", "top"), 1e-6 * radius)
        planes = set(sides["xsym"]) | set(sides["ysym"]) | set(sides["top"])
        sphere = [t for _, t in faces if t not in planes]
        add_groups(3, {"body": body}, {"xsym": sides["xsym"], "ysym": sides["ysym"], "top": sides["top"],
                                         "sphere": sphere})
        _refine_near((0.0, 0.0, -radius), fine_size, fine_radius, size)
        return generate(3, order)
