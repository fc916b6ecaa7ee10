"""Reference elements, quadrature rules, isoparametric gradients and facet measures."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from hydrojam.fem.elements import (
    ELEMENTS,
    ReferenceElement,
    element_for_meshio_type,
    facet_measure,
    physical_gradients,
    quadrature,
)

VOLUME_ELEMENTS = ["tri3", "tri6", "tet4", "tet10"]
SHAPES = {"line": 1, "triangle": 2, "tetrahedron": 3}
MEASURE = {1: 1.0, 2: 0.5, 3: 1.0 / 6.0}


def random_interior_points(dim: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """Points strictly inside the reference simplex."""
    L = rng.dirichlet(np.ones(dim + 1), size=n)
    return L[:, 1:]


def random_affine(dim: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """x = A xi + b with det A > 0 and not too distorted."""
    A = np.eye(dim) + 0.4 * rng.standard_normal((dim, dim))
    if np.linalg.det(A) < 0:
        A[0] *= -1.0
    return 3.0 * A, rng.standard_normal(dim)


def curved_nodes(el: ReferenceElement, rng: np.random.Generator) -> np.ndarray:
    """Reference nodes with mid-edge nodes moved a little (a curved, still valid element)."""
    x = el.nodes.copy()
    x[el.n_corners :] += 0.05 * rng.standard_normal(x[el.n_corners :].shape)
    return x


# ---------------------------------------------------------------------------------- shapes


@pytest.mark.parametrize("name", list(ELEMENTS))
def test_element_metadata(name):
    el = ELEMENTS[name]
    assert el.name == name
    assert el.nodes.shape == (el.nen, el.dim)
    assert el.n_corners == el.dim + 1
    assert el.nen == {1: el.n_corners, 2: el.n_corners + len(el.edges)}[el.order]
    assert el.quad_points.shape == (el.quad_weights.shape[0], el.dim)
    assert el.quad_weights.sum() == pytest.approx(MEASURE[el.dim], rel=1e-14)
    assert element_for_meshio_type(el.meshio_type) is el
    assert not el.nodes.flags.writeable


def test_default_rules():
    npts = {"line2": 2, "line3": 3, "tri3": 1, "tri6": 3, "tet4": 1, "tet10": 4}
    assert {k: el.quad_points.shape[0] for k, el in ELEMENTS.items()} == npts
    assert [ELEMENTS[k].meshio_type for k in npts] == ["line", "line3", "triangle", "triangle6", "tetra", "tetra10"]
    assert [ELEMENTS[k].facet_name for k in npts] == [None, None, "line2", "line3", "tri3", "tri6"]


def test_unknown_meshio_type():
    with pytest.raises(ValueError, match="hexahedron"):
        element_for_meshio_type("hexahedron")


@pytest.mark.parametrize("name", list(ELEMENTS))
def test_partition_of_unity_and_kronecker(name):
    el = ELEMENTS[name]
    np.testing.assert_allclose(el.shape(el.nodes), np.eye(el.nen), atol=1e-14)
    xi = random_interior_points(el.dim, 50, np.random.default_rng(0))
    np.testing.assert_allclose(el.shape(xi).sum(axis=1), 1.0, atol=1e-14)
    # up to 10 terms of size <= 4: round-off ~10 x 4 x eps = 9e-15
    np.testing.assert_allclose(el.grad(xi).sum(axis=1), 0.0, atol=1e-12)


@pytest.mark.parametrize("name", list(ELEMENTS))
def test_grad_matches_finite_differences(name):
    el = ELEMENTS[name]
    xi = random_interior_points(el.dim, 20, np.random.default_rng(1))
    h = 1e-6
    fd = np.empty((xi.shape[0], el.nen, el.dim))
    for j in range(el.dim):
        e = np.zeros(el.dim)
        e[j] = h
        fd[:, :, j] = (el.shape(xi + e) - el.shape(xi - e)) / (2 * h)
    np.testing.assert_allclose(el.grad(xi), fd, atol=1e-8)


@pytest.mark.parametrize("name", ["line3", "tri6", "tet10"])
def test_mid_nodes_at_meshio_edge_midpoints(name):
    edges = {
        "line3": [(0, 1)],
        "tri6": [(0, 1), (1, 2), (2, 0)],
        "tet10": [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)],
    }[name]
    el = ELEMENTS[name]
    np.testing.assert_array_equal(el.edges, edges)
    corners = el.nodes[: el.n_corners]
    np.testing.assert_allclose(corners, np.vstack([np.zeros(el.dim), np.eye(el.dim)]))
    for k, (a, b) in enumerate(edges):
        np.testing.assert_allclose(el.nodes[el.n_corners + k], 0.5 * (corners[a] + corners[b]))


# ------------------------------------------------------------------------------ quadrature


def _monomial_cases(dim: int, degree: int):
    for ex in itertools.product(range(degree + 1), repeat=dim):
        if sum(ex) <= degree:
            exact = math.prod(math.factorial(e) for e in ex) / math.factorial(sum(ex) + dim)
            yield np.array(ex), exact


@pytest.mark.parametrize("shape", list(SHAPES))
@pytest.mark.parametrize("degree", range(1, 9))
def test_quadrature_exact_for_monomials(shape, degree):
    dim = SHAPES[shape]
    pts, w = quadrature(shape, degree)
    assert pts.shape == (w.shape[0], dim)
    assert np.all(w > 0)
    assert np.all(pts > 0) and np.all(pts.sum(axis=1) < 1)  # strictly inside
    for ex, exact in _monomial_cases(dim, degree):
        approx = np.sum(w * np.prod(pts**ex, axis=1))
        assert approx == pytest.approx(exact, rel=1e-13), (ex, approx, exact)


def test_quadrature_point_counts():
    counts = {s: [quadrature(s, d)[0].shape[0] for d in range(1, 6)] for s in SHAPES}
    assert counts == {"line": [1, 2, 2, 3, 3], "triangle": [1, 3, 6, 6, 7], "tetrahedron": [1, 4, 14, 14, 14]}


@pytest.mark.parametrize("name", list(ELEMENTS))
def test_default_rule_degree(name):
    el = ELEMENTS[name]
    for ex, exact in _monomial_cases(el.dim, el.quad_degree):
        assert np.sum(el.quad_weights * np.prod(el.quad_points**ex, axis=1)) == pytest.approx(exact, rel=1e-13)


def test_quadrature_bad_input():
    with pytest.raises(ValueError):
        quadrature("hexahedron", 2)
    with pytest.raises(ValueError):
        quadrature("triangle", -1)


def test_with_quadrature():
    el = ELEMENTS["tet10"]
    el5 = el.with_quadrature(5)
    assert el5.quad_points.shape == (14, 3) and el5.quad_degree == 5
    assert el.quad_points.shape == (4, 3)  # original untouched
    assert el5.name == "tet10" and el5.facets is el.facets


# ------------------------------------------------------------------------- physical maps


@pytest.mark.parametrize("name", VOLUME_ELEMENTS)
def test_affine_map_volume_and_exact_gradients(name):
    rng = np.random.default_rng(2)
    el = ELEMENTS[name]
    ne = 5
    maps = [random_affine(el.dim, rng) for _ in range(ne)]
    coords = np.stack([el.nodes @ A.T + b for A, b in maps])
    for rule in [el, el.with_quadrature(4)]:
        dNdX, dV = physical_gradients(el, coords, rule.quad_points, rule.quad_weights)
        nq = rule.quad_points.shape[0]
        assert dNdX.shape == (ne, nq, el.nen, el.dim) and dV.shape == (ne, nq)
        np.testing.assert_allclose(dV.sum(axis=1), [np.linalg.det(A) * MEASURE[el.dim] for A, _ in maps], rtol=1e-12)

        a = rng.standard_normal(el.dim)
        B = rng.standard_normal((el.dim, el.dim)) if el.order == 2 else np.zeros((el.dim, el.dim))
        u = coords @ a + np.einsum("eai,ij,eaj->ea", coords, B, coords)
        X = np.einsum("qa,eai->eqi", el.shape(rule.quad_points), coords)
        exact = a + X @ (B + B.T).T
        np.testing.assert_allclose(np.einsum("ea,eqai->eqi", u, dNdX), exact, atol=1e-11)


@pytest.mark.parametrize("name", ["tri6", "tet10"])
def test_curved_element_reproduces_linear_fields(name):
    rng = np.random.default_rng(3)
    el = ELEMENTS[name].with_quadrature(4)
    coords = np.stack([curved_nodes(el, rng) @ (2.0 * np.eye(el.dim)).T for _ in range(4)])
    dNdX, dV = physical_gradients(el, coords)
    a = rng.standard_normal(el.dim)
    np.testing.assert_allclose(np.einsum("ea,eqai->eqi", coords @ a, dNdX), np.broadcast_to(a, dNdX.shape[:2] + (el.dim,)), atol=1e-12)
    # volume of the curved element: integral of det J is exact (det J has degree dim*(order-1) <= 3 < 4)
    # and equals the divergence-theorem value (1/dim) * boundary integral of X.n
    facet = ELEMENTS[el.facet_name].with_quadrature(4)
    fc = coords[:, el.facets].reshape(-1, facet.nen, el.dim)
    N, dA, n = facet_measure(facet, fc)
    X = np.einsum("qa,fai->fqi", N, fc)
    flux = np.einsum("fqi,fqi,fq->f", X, n, dA).reshape(coords.shape[0], -1).sum(axis=1) / el.dim
    np.testing.assert_allclose(dV.sum(axis=1), flux, rtol=1e-12)


@pytest.mark.parametrize("name", VOLUME_ELEMENTS)
def test_inverted_element_raises_with_index(name):
    el = ELEMENTS[name]
    coords = np.stack([el.nodes + 0.1 * k for k in range(4)])
    physical_gradients(el, coords)  # all fine
    coords[2] = el.nodes @ np.diag([-1.0] + [1.0] * (el.dim - 1))  # mirrored: det J < 0
    with pytest.raises(ValueError, match=r"element 2\b"):
        physical_gradients(el, coords)
    coords[2] = el.nodes
    coords[3, :, 0] = 0.0  # flattened: det J = 0
    with pytest.raises(ValueError, match=r"element 3\b"):
        physical_gradients(el, coords)


def test_physical_gradients_shape_check():
    with pytest.raises(ValueError, match="shape"):
        physical_gradients(ELEMENTS["tet4"], np.zeros((3, 4, 2)))


# --------------------------------------------------------------------------------- facets


@pytest.mark.parametrize("name", VOLUME_ELEMENTS)
def test_facet_normals_outward_and_total_area(name):
    el = ELEMENTS[name]
    facet = ELEMENTS[el.facet_name]
    rng = np.random.default_rng(4)
    A, b = random_affine(el.dim, rng)
    for nodes in [el.nodes, el.nodes @ A.T + b]:
        fc = nodes[el.facets]
        N, dA, n = facet_measure(facet, fc)
        assert N.shape == (facet.quad_points.shape[0], facet.nen)
        centroid = nodes[: el.n_corners].mean(axis=0)
        fcent = fc[:, : facet.n_corners].mean(axis=1)
        assert np.all(np.einsum("fqi,fi->fq", n, fcent - centroid) > 0)
        np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0)
        corners = nodes[el.facets[:, : facet.n_corners]]
        if el.dim == 2:
            expected = np.linalg.norm(corners[:, 1] - corners[:, 0], axis=-1)
        else:
            expected = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=-1)
        np.testing.assert_allclose(dA.sum(axis=1), expected, rtol=1e-12)
        # divergence theorem: sum of n dA = 0, integral of X_i n_j dA = |element| delta_ij
        np.testing.assert_allclose(np.einsum("fqi,fq->i", n, dA), 0.0, atol=1e-12)
        X = np.einsum("qa,fai->fqi", N, fc)
        volume = abs(np.linalg.det(nodes[1 : el.n_corners] - nodes[0])) * MEASURE[el.dim]
        np.testing.assert_allclose(np.einsum("fqi,fqj,fq->ij", X, n, dA), volume * np.eye(el.dim), atol=1e-12)
    total = {2: 2.0 + math.sqrt(2.0), 3: 1.5 + math.sqrt(3.0) / 2.0}[el.dim]
    N, dA, _ = facet_measure(facet, el.nodes[el.facets])
    assert dA.sum() == pytest.approx(total, rel=1e-14)


@pytest.mark.parametrize("name", VOLUME_ELEMENTS)
def test_facet_trace_matches_facet_element(name):
    """On facet f, the element's shape functions are the facet element's, in the facet node order."""
    el = ELEMENTS[name]
    facet = ELEMENTS[el.facet_name]
    s = random_interior_points(facet.dim, 7, np.random.default_rng(5))
    Nf = facet.shape(s)
    for f, local in enumerate(el.facets):
        xi = Nf @ el.nodes[local]  # facet points in element reference coords (facet map is affine)
        Ne = el.shape(xi)
        # values <= 1 through a matmul and quadratic products: round-off a few eps (measured 6e-16)
        np.testing.assert_allclose(Ne[:, local], Nf, atol=1e-12, err_msg=f"facet {f}")
        others = np.setdiff1d(np.arange(el.nen), local)
        np.testing.assert_allclose(Ne[:, others], 0.0, atol=1e-12)
    expected = {
        "tri3": [[0, 1], [1, 2], [2, 0]],
        "tri6": [[0, 1, 3], [1, 2, 4], [2, 0, 5]],
        "tet4": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        "tet10": [[0, 2, 1, 6, 5, 4], [0, 1, 3, 4, 8, 7], [0, 3, 2, 7, 9, 6], [1, 2, 3, 5, 9, 8]],
    }[name]
    np.testing.assert_array_equal(el.facets, expected)


def test_facet_measure_curved_edge_and_normal_formula():
    # parabolic line3 edge y = x(1 - x) from (0,0) to (1,0), midpoint (0.5, 0.25); arc length closed form
    line3 = ELEMENTS["line3"].with_quadrature(40)
    fc = np.array([[[0.0, 0.0], [1.0, 0.0], [0.5, 0.25]]])
    N, dA, n = facet_measure(line3, fc)
    length = 0.5 * math.sqrt(2.0) + 0.5 * math.asinh(1.0)  # int_0^1 sqrt(1 + (1-2x)^2) dx
    assert dA.sum() == pytest.approx(length, rel=1e-12)
    x = line3.quad_points[:, 0]
    t = np.stack([np.ones_like(x), 1 - 2 * x], axis=-1)
    np.testing.assert_allclose(n[0], np.stack([t[:, 1], -t[:, 0]], -1) / np.linalg.norm(t, axis=-1)[:, None])
    # 3D triangle: normal along (x1 - x0) x (x2 - x0)
    tri = np.array([[[0.0, 0.0, 1.0], [0.0, 2.0, 1.0], [3.0, 0.0, 1.0]]])
    _, dA, n = facet_measure(ELEMENTS["tri3"], tri)
    np.testing.assert_allclose(n[0], [[0.0, 0.0, -1.0]])
    assert dA.sum() == pytest.approx(3.0)


def test_degenerate_facet_raises():
    fc = np.array([[[0.0, 0.0], [1.0, 0.0]], [[1.0, 1.0], [1.0, 1.0]]])
    with pytest.raises(ValueError, match=r"facet 1\b"):
        facet_measure(ELEMENTS["line2"], fc)
