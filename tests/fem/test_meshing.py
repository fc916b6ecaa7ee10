"""The gmsh wrapper (hydrojam.fem.meshing) on its own: shapes measured against their analytic
areas and volumes, named groups where the docstrings put them, conformal bonding, reproducible
meshes and nested sessions."""

import math

import gmsh
import numpy as np
import pytest

from hydrojam.fem.elements import element_for_meshio_type, physical_gradients
from hydrojam.fem.meshing import ball, bonded_rectangles, box, disk, gmsh_session, rectangle
from hydrojam.fem.terms import nodal_areas


def test_a_rectangle_has_its_area_and_its_sides_where_named():
    m = rectangle(3.0, 2.0, 0.5, order=2, origin=(1.0, -1.0))
    assert m.cell_type == "triangle6" and m.cell_volumes().sum() == pytest.approx(6.0, rel=1e-12)
    side = {"left": (0, 1.0), "right": (0, 4.0), "bottom": (1, -1.0), "top": (1, 1.0)}
    for name, (axis, value) in side.items():
        nodes = m.group_nodes(name)
        assert np.allclose(m.points[nodes, axis], value, atol=1e-12)
        length = 2.0 if axis == 0 else 3.0
        assert nodal_areas(m.points, m.facet_groups[name]).sum() == pytest.approx(length, rel=1e-12)
    assert len(m.cell_groups["body"]) == m.n_cells


def _curved_measure(m):
    """Area or volume of a mesh with its quadratic (curved) geometry: the element quadrature's
    weights summed (``cell_volumes`` measures the straight corner simplices)."""
    _, dV = physical_gradients(element_for_meshio_type(m.cell_type), m.points[m.cells])
    return float(dV.sum())


def test_a_quadratic_disk_approximates_its_area_at_the_rate_of_its_geometry():
    """Quadratic edges on the circle: the area error falls as h^4, below 0.05 (h / r)^4 of the
    area (straight edges would leave about 0.17 (h / r)^2); halving h cuts it 8x or more."""
    r, errors = 2.0, []
    for size in (1.0, 0.5):
        m = disk(r, size, order=2)
        errors.append(abs(_curved_measure(m) - math.pi * r**2) / (math.pi * r**2))
        assert errors[-1] <= 0.05 * (size / r) ** 4
        boundary = m.group_nodes("boundary")
        assert np.allclose(np.linalg.norm(m.points[boundary], axis=1), r, rtol=1e-9)
    assert errors[1] <= errors[0] / 8


def test_a_box_and_a_ball_have_their_volumes():
    b = box(1.0, 2.0, 0.75, 0.5, order=2)
    assert b.cell_type == "tetra10" and b.cell_volumes().sum() == pytest.approx(1.5, rel=1e-12)
    assert np.allclose(b.points[b.group_nodes("zmax"), 2], 0.75, atol=1e-12)
    r, h = 1.0, 0.5
    s = ball(r, h, order=2)
    assert abs(_curved_measure(s) - 4 / 3 * math.pi * r**3) <= 0.05 * (h / r) ** 4 * 4 / 3 * math.pi * r**3
    assert np.allclose(np.linalg.norm(s.points[s.group_nodes("boundary")], axis=1), r, rtol=1e-9)


def test_bonded_rectangles_share_their_interface_nodes():
    m = bonded_rectangles(1.0, 2.0, 1.5, 0.4, order=2)
    left, right = (np.unique(m.cells[m.cell_groups[k]]) for k in ("left_body", "right_body"))
    shared = np.intersect1d(left, right)
    assert len(shared) > 0 and np.allclose(m.points[shared, 0], 1.0, atol=1e-12)
    # every node on x = 1 belongs to both bodies: no duplicated, unbonded interface nodes
    on_interface = np.flatnonzero(np.isclose(m.points[:, 0], 1.0, atol=1e-12))
    assert set(on_interface) == set(shared)
    assert m.cell_volumes().sum() == pytest.approx(4.5, rel=1e-12)


def test_meshes_are_reproducible_and_sessions_nest():
    a, b = rectangle(2.0, 1.0, 0.3), rectangle(2.0, 1.0, 0.3)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.cells, b.cells)
    with gmsh_session() as outer:
        inner_mesh = disk(1.0, 0.5)
        assert gmsh.isInitialized() and gmsh.model.getCurrent() == outer
    assert not gmsh.isInitialized()
    assert inner_mesh.n_cells > 0
