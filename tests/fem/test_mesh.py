"""Meshes from gmsh: geometry, orientation, node orders, groups, boundary facets, I/O."""

from __future__ import annotations

import gmsh
import numpy as np
import pytest

from hydrojam.fem import meshing as _gmsh
from hydrojam.fem.elements import quadrature
from hydrojam.fem.mesh import MID_EDGES, Mesh, jacobian_determinants

SHAPES_2D = {
    "rectangle": lambda o: _gmsh.rectangle(2.0, 1.0, 0.25, order=o, origin=(0.5, -1.0)),
    "rectangle_structured": lambda o: _gmsh.rectangle(2.0, 1.0, 0.25, order=o, structured=True),
    "disk": lambda o: _gmsh.disk(1.0, 0.15, order=o, centre=(0.3, 0.2)),
    "bonded_rectangles": lambda o: _gmsh.bonded_rectangles(1.0, 2.0, 1.0, 0.25, order=o),
    "disks": lambda o: _gmsh.disks([(0.0, 0.0), (2.5, 0.0)], [1.0, 0.5], 0.2, order=o),
}
SHAPES_3D = {
    "box": lambda o: _gmsh.box(1.0, 0.5, 2.0, 0.3, order=o, origin=(0.0, 1.0, 0.0)),
    "ball": lambda o: _gmsh.ball(1.0, 0.3, order=o, centre=(0.1, 0.0, -0.2)),
}
SHAPES = {**SHAPES_2D, **SHAPES_3D}

# (area or volume, boundary length or surface); curved shapes are compared with a tolerance
EXACT = {
    "rectangle": (2.0, 6.0),
    "rectangle_structured": (2.0, 6.0),
    "disk": (np.pi, 2 * np.pi),
    "bonded_rectangles": (3.0, 8.0),
    "disks": (1.25 * np.pi, 3 * np.pi),
    "box": (1.0, 7.0),
    "ball": (4 / 3 * np.pi, 4 * np.pi),
}
CURVED = {"disk", "disks", "ball"}

_cache: dict = {}


def get(name: str, order: int) -> Mesh:
    if (name, order) not in _cache:
        _cache[name, order] = SHAPES[name](order)
    return _cache[name, order]


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("name", list(SHAPES))
def test_shape_basics(name, order):
    m = get(name, order)
    assert m.order == order
    assert m.dim == (3 if name in SHAPES_3D else 2)
    types = {(2, 1): "triangle", (2, 2): "triangle6", (3, 1): "tetra", (3, 2): "tetra10"}
    assert m.cell_type == types[m.dim, order]
    assert m.points.dtype == np.float64 and m.cells.dtype == np.int64
    # every node used, all cells positively oriented
    assert np.array_equal(np.unique(m.cells), np.arange(m.n_nodes))
    assert np.all(m.cell_volumes() > 0)
    # cell groups partition the cells
    allc = np.concatenate(list(m.cell_groups.values()))
    assert np.array_equal(np.sort(allc), np.arange(m.n_cells))
    for idx in m.cell_groups.values():
        assert np.all(np.diff(idx) > 0)
    # measure
    exact = EXACT[name][0]
    total = m.cell_volumes().sum()
    if name in CURVED:
        assert abs(total - exact) < 0.03 * exact
    else:
        assert total == pytest.approx(exact, rel=1e-12)


@pytest.mark.parametrize("name", list(SHAPES))
def test_quadratic_nodes(name):
    """Mid nodes sit at their edge midpoints (straight edges), or on the curved boundary; every
    quadratic cell has a positive Jacobian throughout."""
    m = get(name, 2)
    p, c = m.points, m.cells
    nc = m.n_corners
    off = np.zeros(len(c), dtype=bool)
    for k, (a, b) in enumerate(MID_EDGES[m.cell_type]):
        mid = 0.5 * (p[c[:, a]] + p[c[:, b]])
        err = np.linalg.norm(p[c[:, nc + k]] - mid, axis=1)
        off |= err > 1e-9
        # curved edges move their mid node only a little
        assert np.all(err < 0.1 * np.linalg.norm(p[c[:, a]] - p[c[:, b]], axis=1))
    if name in CURVED:
        # only cells touching the boundary may be curved; the others are exact midpoints
        bnodes = np.unique(m.boundary_facets())
        assert np.all(np.isin(c[off], bnodes).any(axis=1))
        assert 0 < off.sum() < len(c)
        # boundary nodes, mid nodes included, lie on the circle / sphere
        centres = {"disk": [(0.3, 0.2)], "ball": [(0.1, 0.0, -0.2)], "disks": [(0.0, 0.0), (2.5, 0.0)]}[name]
        radii = {"disk": [1.0], "ball": [1.0], "disks": [1.0, 0.5]}[name]
        dist = np.min([np.abs(np.linalg.norm(p[bnodes] - c, axis=1) - r)
                       for c, r in zip(centres, radii)], axis=0)
        assert np.all(dist < 1e-6)
    else:
        assert not off.any()
    xi, _ = quadrature({2: "triangle", 3: "tetrahedron"}[m.dim], 7)  # 16 (2D) or 64 (3D) interior points
    assert np.all(jacobian_determinants(p, c, m.cell_type, xi) > 0)


@pytest.mark.parametrize("name", sorted(CURVED))
def test_curved_measure_converges_faster_at_order_2(name):
    exact = EXACT[name][0]
    e1 = abs(get(name, 1).cell_volumes(curved=True).sum() - exact)
    e2 = abs(get(name, 2).cell_volumes(curved=True).sum() - exact)
    assert e1 < 0.03 * exact
    assert e2 < 0.05 * e1


def test_gmsh_tetra10_order():
    """gmsh's 10-node tetrahedron lists the mid nodes of edges (2,3) and (1,3) the other way
    round from VTK/meshio; the derived permutation swaps them."""
    with _gmsh.gmsh_session():
        assert _gmsh.gmsh_to_meshio_order(11).tolist() == [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]
        assert _gmsh.gmsh_to_meshio_order(9).tolist() == list(range(6))
        assert _gmsh.gmsh_to_meshio_order(8).tolist() == [0, 1, 2]
        assert _gmsh.gmsh_to_meshio_order(4).tolist() == [0, 1, 2, 3]


def _outward_ok(m: Mesh, facets, owners):
    nfc = m.dim
    centroid_f = m.points[facets[:, :nfc]].mean(axis=1)
    centroid_c = m.points[m.cells[owners, : m.n_corners]].mean(axis=1)
    n = m.facet_normals(facets)
    return np.einsum("ij,ij->i", n, centroid_f - centroid_c) > 0


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("name", list(SHAPES))
def test_boundary_facets(name, order):
    m = get(name, order)
    f, owners = m.boundary_facets(return_cells=True)
    assert f.shape[1] == {"line": 2, "line3": 3, "triangle": 3, "triangle6": 6}[m.facet_type]
    assert np.all(_outward_ok(m, f, owners))
    # facet mid nodes: line3 (0,1)+2; triangle6 (0,1)+3, (1,2)+4, (2,0)+5
    if order == 2 and name not in CURVED:
        for k, (a, b) in enumerate(MID_EDGES[m.facet_type]):
            mid = 0.5 * (m.points[f[:, a]] + m.points[f[:, b]])
            assert np.allclose(m.points[f[:, m.dim + k]], mid)
    # the facet nodes are the owner's nodes
    assert all(set(fi) <= set(m.cells[o]) for fi, o in zip(f[:50], owners[:50]))
    # boundary measure
    exact = EXACT[name][1]
    total = m.facet_measures(f).sum()
    if name in CURVED:
        assert abs(total - exact) < 0.03 * exact
    else:
        assert total == pytest.approx(exact, rel=1e-12)
    # the facet groups cover the boundary for the shapes whose groups do, and are outward
    fg = np.concatenate(list(m.facet_groups.values()))
    key = lambda a: {tuple(sorted(r[: m.dim])) for r in a.tolist()}  # noqa: E731
    assert len(fg) == len(f)
    assert key(fg) == key(f)
    # group facets are literally the outward boundary facets (same node order)
    assert {tuple(r) for r in fg.tolist()} == {tuple(r) for r in f.tolist()}


def test_boundary_facets_of_subset_and_counts():
    m = get("rectangle", 2)
    n_groups = sum(len(v) for v in m.facet_groups.values())
    assert len(m.boundary_facets()) == n_groups
    assert set(m.facet_groups) == {"left", "right", "bottom", "top"}
    x0, z0 = 0.5, -1.0
    for name, axis, val in [("left", 0, x0), ("right", 0, x0 + 2), ("bottom", 1, z0), ("top", 1, z0 + 1)]:
        assert np.allclose(m.points[m.group_nodes(name), axis], val)
    # bonded bodies: each body's boundary includes the interface, oriented out of that body
    b = get("bonded_rectangles", 2)
    for g in ("left_body", "right_body"):
        f, owners = b.boundary_facets(b.cell_groups[g], return_cells=True)
        assert np.all(np.isin(owners, b.cell_groups[g]))
        assert np.all(_outward_ok(b, f, owners))
        assert b.facet_measures(f).sum() == pytest.approx({"left_body": 4.0, "right_body": 6.0}[g])
    mask = np.zeros(b.n_cells, dtype=bool)
    mask[b.cell_groups["left_body"]] = True
    assert len(b.boundary_facets(mask)) == len(b.boundary_facets(b.cell_groups["left_body"]))


def test_structured_rectangle():
    m = _gmsh.rectangle(2.0, 1.0, 0.25, order=1, structured=True)
    assert m.n_cells == 2 * 8 * 4 and m.n_nodes == 9 * 5
    assert len(m.facet_groups["bottom"]) == 8 and len(m.facet_groups["left"]) == 4
    assert np.allclose(m.cell_volumes(), 0.25**2 / 2)


def test_bonded_rectangles_share_interface():
    m = get("bonded_rectangles", 2)
    lx1 = 1.0
    iface = np.flatnonzero(np.abs(m.points[:, 0] - lx1) < 1e-12)
    assert len(iface) == 2 * 4 + 1  # 4 quadratic edges along z in [0, 1]
    left = m.group_nodes("left_body")
    right = m.group_nodes("right_body")
    assert np.array_equal(np.intersect1d(left, right), iface)
    assert np.all(m.points[m.cells[m.cell_groups["left_body"]], 0] <= lx1 + 1e-12)
    assert np.all(m.points[m.cells[m.cell_groups["right_body"]], 0] >= lx1 - 1e-12)
    # no duplicate points
    from scipy.spatial import cKDTree

    assert not cKDTree(m.points).query_pairs(1e-9)
    # outer pieces only: no interface facet in any facet group
    for name in ("bottom", "top"):
        xs = m.points[m.facet_groups[name][:, :2], 0]
        assert np.all((xs.max(axis=1) <= lx1 + 1e-12) | (xs.min(axis=1) >= lx1 - 1e-12))
        assert m.facet_measures(m.facet_groups[name]).sum() == pytest.approx(3.0)


def test_disks_are_disjoint():
    m = get("disks", 2)
    assert set(m.cell_groups) == {"disk0", "disk1"}
    assert set(m.facet_groups) == {"disk0_boundary", "disk1_boundary"}
    n0, n1 = m.group_nodes("disk0"), m.group_nodes("disk1")
    assert len(np.intersect1d(n0, n1)) == 0
    assert len(n0) + len(n1) == m.n_nodes
    assert np.all(np.isin(m.group_nodes("disk0_boundary"), n0))
    r1 = np.linalg.norm(m.points[m.group_nodes("disk1_boundary")] - (2.5, 0.0), axis=1)
    assert np.allclose(r1, 0.5, atol=1e-6)
    with pytest.raises(ValueError):
        _gmsh.disks([(0, 0), (1, 0)], 0.6, 0.2)


def test_group_nodes_errors():
    m = get("rectangle", 1)
    with pytest.raises(KeyError):
        m.group_nodes("nope")
    assert np.array_equal(m.group_nodes("body"), np.arange(m.n_nodes))


@pytest.mark.parametrize("cell_type", ["triangle", "triangle6", "tetra", "tetra10"])
def test_create_flips_negative_cells(cell_type):
    name = "rectangle" if cell_type.startswith("triangle") else "box"
    m = get(name, 2 if cell_type.endswith(("6", "10")) else 1)
    flip = {
        "triangle": [0, 2, 1],
        "triangle6": [0, 2, 1, 5, 4, 3],
        "tetra": [1, 0, 2, 3],
        "tetra10": [1, 0, 2, 3, 4, 6, 5, 8, 7, 9],  # swap corners 0 and 1, mid nodes follow
    }[cell_type]
    bad = m.cells.copy()
    bad[::2] = bad[::2][:, flip]
    assert np.any(Mesh(m.points, bad, cell_type).cell_volumes() < 0)
    fixed = Mesh.create(m.points, bad, cell_type, m.cell_groups, m.facet_groups)
    assert np.all(fixed.cell_volumes() > 0)
    assert np.allclose(fixed.cell_volumes(), m.cell_volumes())
    # the mid nodes still sit on the right edges
    nc = fixed.n_corners
    for k, (a, b) in enumerate(MID_EDGES.get(cell_type, ())):
        mid = 0.5 * (fixed.points[fixed.cells[:, a]] + fixed.points[fixed.cells[:, b]])
        assert np.allclose(fixed.points[fixed.cells[:, nc + k]], mid)
    f, owners = fixed.boundary_facets(return_cells=True)
    assert np.all(_outward_ok(fixed, f, owners))


@pytest.mark.parametrize("ext", ["vtu", "msh", "vtk"])
@pytest.mark.parametrize("name", ["bonded_rectangles", "box"])
def test_meshio_round_trip(tmp_path, name, ext):
    m = get(name, 2)
    path = tmp_path / f"mesh.{ext}"
    m.write(path)
    r = Mesh.read(path)
    assert r.cell_type == m.cell_type
    assert np.array_equal(r.points, m.points)
    assert np.array_equal(r.cells, m.cells)
    assert r.cell_groups.keys() == m.cell_groups.keys()
    assert r.facet_groups.keys() == m.facet_groups.keys()
    for k in m.cell_groups:
        assert np.array_equal(r.cell_groups[k], m.cell_groups[k])
    for k in m.facet_groups:
        assert np.array_equal(r.facet_groups[k], m.facet_groups[k])


def test_to_meshio_2d_pads_points():
    m = get("disk", 1)
    mm = m.to_meshio()
    assert mm.points.shape == (m.n_nodes, 3) and np.all(mm.points[:, 2] == 0)
    assert mm.cells[0].type == "triangle"
    assert Mesh.from_meshio(mm).points.shape == (m.n_nodes, 2)


def test_meshing_is_deterministic():
    a = _gmsh.disk(1.0, 0.2, order=2)
    b = _gmsh.disk(1.0, 0.2, order=2)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.cells, b.cells)


def test_arrays_are_read_only():
    m = get("rectangle", 1)
    with pytest.raises(ValueError):
        m.points[0, 0] = 1.0


def test_gmsh_session_nesting():
    assert not gmsh.isInitialized()
    with _gmsh.gmsh_session() as outer:
        gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 7.0)
        with _gmsh.gmsh_session() as inner:
            assert inner != outer and gmsh.model.getCurrent() == inner
            assert gmsh.model.getEntities(2) == []
        # a shape builder inside a session leaves the outer model and options alone
        d = _gmsh.disk(1.0, 0.5, order=1)
        assert d.n_cells > 0
        assert gmsh.isInitialized()
        assert gmsh.model.getCurrent() == outer
        assert gmsh.model.getEntities(2) == [(2, 1)]
        assert gmsh.option.getNumber("Mesh.MeshSizeMax") == 7.0
    assert not gmsh.isInitialized()
    with pytest.raises(RuntimeError):
        with _gmsh.gmsh_session():
            raise RuntimeError("boom")
    assert not gmsh.isInitialized()


def test_extract_mesh_from_user_model():
    with _gmsh.gmsh_session():
        s = gmsh.model.occ.addRectangle(0, 0, 0, 1, 2)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [s], name="gel")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
        gmsh.model.mesh.generate(2)
        m = _gmsh.extract_mesh(2, order=2)
    assert m.cell_type == "triangle6" and set(m.cell_groups) == {"gel"} and m.facet_groups == {}
    assert m.cell_volumes().sum() == pytest.approx(2.0)
