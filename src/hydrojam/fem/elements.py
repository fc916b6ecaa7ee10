"""Lagrange reference elements on simplices, quadrature rules and isoparametric maps.

Elements (``ELEMENTS`` keys): ``line2``, ``line3``, ``tri3``, ``tri6``, ``tet4``, ``tet10``. Node order
is meshio's (= VTK's): corners first, then one node per edge, the edges being

* ``line3``: (0, 1)
* ``tri6``:  (0, 1), (1, 2), (2, 0)
* ``tet10``: (0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)

Reference simplices: ``[0, 1]``, the triangle ``(0,0), (1,0), (0,1)`` and the tetrahedron ``(0,0,0),
(1,0,0), (0,1,0), (0,0,1)``, with measures 1, 1/2 and 1/6. A positively oriented element has
``det J > 0`` (counterclockwise triangles, right-handed tets).

Facets (``ReferenceElement.facets``): triangles ``(0,1), (1,2), (2,0)``; tets ``(0,2,1), (0,1,3),
(0,3,2), (1,2,3)`` (:mod:`hydrojam.fem.mesh` uses these tables); local nodes are listed corners first, then
mid-edge nodes in the facet element's own order, oriented so the normal of :func:`facet_measure`
points out of a positively oriented element. Line elements list their two end points as facets.

Physical coordinates are in mm, so gradients are in 1/mm and ``dV`` / ``dA`` in mm^3 / mm^2 (mm^2
and mm in 2D plane strain: per unit thickness).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import roots_jacobi

__all__ = [
    "ELEMENTS",
    "ReferenceElement",
    "element_for_meshio_type",
    "facet_measure",
    "physical_gradients",
    "quadrature",
    "straight_pieces",
]

_SHAPE_OF_DIM = {1: "line", 2: "triangle", 3: "tetrahedron"}


# --------------------------------------------------------------------------------------------
# Quadrature
# --------------------------------------------------------------------------------------------


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float if a.dtype.kind == "f" else a.dtype)
    a.setflags(write=False)
    return a


def _orbit(bary: tuple[float, ...], weight: float) -> tuple[np.ndarray, np.ndarray]:
    """All distinct permutations of barycentric coordinates -> reference points (drop L0)."""
    pts = sorted(set(itertools.permutations(bary)))
    pts_arr = np.array(pts, dtype=float)[:, 1:]
    return pts_arr, np.full(len(pts), weight)


def _rule_from_orbits(orbits: list[tuple[tuple[float, ...], float]]) -> tuple[np.ndarray, np.ndarray]:
    parts = [_orbit(b, w) for b, w in orbits]
    return np.concatenate([p for p, _ in parts]), np.concatenate([w for _, w in parts])


def _gauss_jacobi01(n: int, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """n-point rule on [0, 1] for the weight (1 - s)^alpha (exact to degree 2n - 1)."""
    x, w = roots_jacobi(n, alpha, 0.0)
    return (1.0 + x) / 2.0, w / 2.0 ** (alpha + 1.0)


def _line_rule(degree: int) -> tuple[np.ndarray, np.ndarray]:
    n = max(1, math.ceil((degree + 1) / 2))
    x, w = np.polynomial.legendre.leggauss(n)
    return ((x + 1.0) / 2.0)[:, None], w / 2.0


def _conical_rule(dim: int, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Collapsed-coordinate (Stroud conical product) rule: positive weights, any degree."""
    n = max(1, math.ceil((degree + 1) / 2))
    s, ws = _gauss_jacobi01(n, dim - 1.0)
    t, wt = _gauss_jacobi01(n, dim - 2.0)
    if dim == 2:
        S, T = np.meshgrid(s, t, indexing="ij")
        pts = np.stack([S, T * (1.0 - S)], axis=-1).reshape(-1, 2)
        return pts, np.outer(ws, wt).ravel()
    r, wr = _gauss_jacobi01(n, 0.0)
    S, T, R = np.meshgrid(s, t, r, indexing="ij")
    pts = np.stack([S, T * (1.0 - S), R * (1.0 - S) * (1.0 - T)], axis=-1).reshape(-1, 3)
    return pts, np.einsum("i,j,k->ijk", ws, wt, wr).ravel()


def _triangle_rule(degree: int) -> tuple[np.ndarray, np.ndarray]:
    if degree <= 1:  # centroid, 1 point
        return np.array([[1.0 / 3.0, 1.0 / 3.0]]), np.array([0.5])
    if degree == 2:  # 3 interior points (Strang-Fix)
        return _rule_from_orbits([((2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0), 1.0 / 6.0)])
    if degree <= 4:  # Dunavant degree 4, 6 points (the degree-3 Dunavant rule has a negative weight)
        a1, w1 = 0.445948490915964886318329253883, 0.223381589678011465944827594602
        a2, w2 = 0.091576213509770743459571463402, 0.109951743655321867388505738731
        return _rule_from_orbits([((1 - 2 * a1, a1, a1), w1 / 2), ((1 - 2 * a2, a2, a2), w2 / 2)])
    if degree == 5:  # Radon / Dunavant degree 5, 7 points, closed form
        r15 = math.sqrt(15.0)
        a1, a2 = (6.0 - r15) / 21.0, (6.0 + r15) / 21.0
        w1, w2 = (155.0 - r15) / 1200.0, (155.0 + r15) / 1200.0
        return _rule_from_orbits(
            [((1 / 3, 1 / 3, 1 / 3), 9.0 / 80.0), ((1 - 2 * a1, a1, a1), w1 / 2), ((1 - 2 * a2, a2, a2), w2 / 2)]
        )
    return _conical_rule(2, degree)


def _tet_rule(degree: int) -> tuple[np.ndarray, np.ndarray]:
    if degree <= 1:  # centroid, 1 point
        return np.array([[0.25, 0.25, 0.25]]), np.array([1.0 / 6.0])
    if degree == 2:  # 4 points
        b = (5.0 - math.sqrt(5.0)) / 20.0
        return _rule_from_orbits([((1 - 3 * b, b, b, b), 1.0 / 24.0)])
    if degree <= 5:  # Walkington (2000) degree 5, 14 points, all weights positive
        a1, w1 = 0.3108859192633006097973457337634578, 0.1126879257180158507991856523332863
        a2, w2 = 0.0927352503108912264023239137370306, 0.0734930431163619495437102054863275
        b, w3 = 0.0455037041256496494918805262793394, 0.0425460207770814664380694281202574
        return _rule_from_orbits(
            [
                ((1 - 3 * a1, a1, a1, a1), w1 / 6),
                ((1 - 3 * a2, a2, a2, a2), w2 / 6),
                ((0.5 - b, 0.5 - b, b, b), w3 / 6),
            ]
        )
    return _conical_rule(3, degree)


def quadrature(shape: str, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature rule on a reference simplex, exact for polynomials of total degree ``degree``.

    Rules: line: Gauss-Legendre (any degree); triangle: 1 point (deg 1), 3 points (2), Dunavant 6
    points (3-4), 7 points (5); tet: 1 point (1), 4 points (2), Walkington 14 points (3-5); higher
    degrees: conical Gauss-Jacobi products.

    Parameters
    ----------
    shape : {"line", "triangle", "tetrahedron"}
        The reference shape (the line is [0, 1]).
    degree : int
        Total polynomial degree integrated exactly, >= 0.

    Returns
    -------
    points : ndarray, shape (nq, dim)
        Points in reference coordinates [-], all inside the shape.
    weights : ndarray, shape (nq,)
        Weights, all positive, summing to the reference measure (1, 1/2, 1/6).

    Raises
    ------
    ValueError
        For a negative degree or an unknown shape.
    """
    degree = int(degree)
    if degree < 0:
        raise ValueError(f"quadrature degree must be >= 0, got {degree}")
    if shape == "line":
        pts, w = _line_rule(degree)
    elif shape == "triangle":
        pts, w = _triangle_rule(degree)
    elif shape == "tetrahedron":
        pts, w = _tet_rule(degree)
    else:
        raise ValueError(f"unknown reference shape {shape!r}; expected 'line', 'triangle' or 'tetrahedron'")
    return np.array(pts, dtype=float), np.array(w, dtype=float)


# --------------------------------------------------------------------------------------------
# Reference elements
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ReferenceElement:
    """A Lagrange simplex element of order 1 or 2 with its default quadrature rule.

    Shape functions are written in barycentric coordinates ``L0 = 1 - sum(xi), L_i = xi_{i-1}``:
    ``N = L_i`` (order 1); ``L_i (2 L_i - 1)`` at corners and ``4 L_a L_b`` at the node of edge
    ``(a, b)`` (order 2). Arrays are read-only.
    """

    name: str
    meshio_type: str
    dim: int
    order: int
    nodes: np.ndarray
    quad_points: np.ndarray
    quad_weights: np.ndarray
    facets: np.ndarray
    facet_name: str | None
    n_corners: int
    edges: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=int), repr=False)
    """(n_edge_nodes, 2) corner pair of each mid-edge node (empty for order 1)."""
    quad_degree: int = -1
    """Polynomial degree integrated exactly by ``quad_points``/``quad_weights``."""

    @property
    def nen(self) -> int:
        """Number of element nodes."""
        return self.nodes.shape[0]

    def _xi(self, xi: np.ndarray) -> np.ndarray:
        return np.asarray(xi, dtype=float).reshape(-1, self.dim)

    def _bary(self, xi: np.ndarray) -> np.ndarray:
        return np.concatenate([1.0 - xi.sum(axis=1, keepdims=True), xi], axis=1)

    def shape(self, xi: np.ndarray) -> np.ndarray:
        """Shape function values ``(nq, nen)`` at reference points ``xi`` ``(nq, dim)``."""
        L = self._bary(self._xi(xi))
        if self.order == 1:
            return L
        Lc = L[:, : self.n_corners]
        corner = Lc * (2.0 * Lc - 1.0)
        edge = 4.0 * L[:, self.edges[:, 0]] * L[:, self.edges[:, 1]]
        return np.concatenate([corner, edge], axis=1)

    def grad(self, xi: np.ndarray) -> np.ndarray:
        """Shape function derivatives wrt reference coordinates, ``(nq, nen, dim)``."""
        xi = self._xi(xi)
        nq = xi.shape[0]
        dL = np.concatenate([-np.ones((1, self.dim)), np.eye(self.dim)], axis=0)  # (n_corners, dim)
        if self.order == 1:
            return np.broadcast_to(dL, (nq, self.n_corners, self.dim)).copy()
        L = self._bary(xi)
        a, b = self.edges[:, 0], self.edges[:, 1]
        corner = (4.0 * L - 1.0)[:, :, None] * dL[None, :, :]
        edge = 4.0 * (L[:, b, None] * dL[None, a, :] + L[:, a, None] * dL[None, b, :])
        return np.concatenate([corner, edge], axis=1)

    def with_quadrature(self, degree: int) -> ReferenceElement:
        """The same element carrying the rule ``quadrature(<shape>, degree)``."""
        pts, w = quadrature(_SHAPE_OF_DIM[self.dim], degree)
        return replace(self, quad_points=_readonly(pts), quad_weights=_readonly(w), quad_degree=int(degree))


_CORNERS = {
    1: np.array([[0.0], [1.0]]),
    2: np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
    3: np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
}
_EDGES = {
    1: [(0, 1)],
    2: [(0, 1), (1, 2), (2, 0)],
    3: [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)],
}
# Facet corners, ordered so the normal points outward (hydrojam.fem.mesh uses this table).
_FACET_CORNERS = {
    1: [(0,), (1,)],
    2: [(0, 1), (1, 2), (2, 0)],
    3: [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)],
}
_SPECS = {
    # name: (meshio type, dim, order, facet name, default quadrature degree)
    "line2": ("line", 1, 1, None, 3),
    "line3": ("line3", 1, 2, None, 5),
    "tri3": ("triangle", 2, 1, "line2", 1),
    "tri6": ("triangle6", 2, 2, "line3", 2),
    "tet4": ("tetra", 3, 1, "tri3", 1),
    "tet10": ("tetra10", 3, 2, "tri6", 2),
}


def _make_element(name: str) -> ReferenceElement:
    meshio_type, dim, order, facet_name, qdeg = _SPECS[name]
    corners = _CORNERS[dim]
    n_corners = dim + 1
    edges = np.array(_EDGES[dim] if order == 2 else np.zeros((0, 2)), dtype=int).reshape(-1, 2)
    nodes = np.concatenate([corners, 0.5 * (corners[edges[:, 0]] + corners[edges[:, 1]])], axis=0)
    edge_node = {frozenset(map(int, e)): n_corners + k for k, e in enumerate(edges)}
    facets = []
    for fc in _FACET_CORNERS[dim]:
        mids = []
        if order == 2 and len(fc) > 1:
            fedges = _EDGES[len(fc) - 1]  # the facet element's own edge order
            mids = [edge_node[frozenset((fc[i], fc[j]))] for i, j in fedges]
        facets.append(list(fc) + mids)
    pts, w = quadrature(_SHAPE_OF_DIM[dim], qdeg)
    return ReferenceElement(
        name=name,
        meshio_type=meshio_type,
        dim=dim,
        order=order,
        nodes=_readonly(nodes),
        quad_points=_readonly(pts),
        quad_weights=_readonly(w),
        facets=_readonly(np.array(facets, dtype=int)),
        facet_name=facet_name,
        n_corners=n_corners,
        edges=_readonly(edges),
        quad_degree=qdeg,
    )


ELEMENTS: dict[str, ReferenceElement] = {name: _make_element(name) for name in _SPECS}
"""The reference elements, keyed ``line2, line3, tri3, tri6, tet4, tet10``."""

_BY_MESHIO_TYPE = {el.meshio_type: el for el in ELEMENTS.values()}


def element_for_meshio_type(cell_type: str) -> ReferenceElement:
    """The reference element of a meshio cell type.

    Parameters
    ----------
    cell_type : str
        The meshio cell type (``line``, ``line3``, ``triangle``, ...).

    Returns
    -------
    ReferenceElement

    Raises
    ------
    ValueError
        For an unsupported cell type.
    """
    try:
        return _BY_MESHIO_TYPE[cell_type]
    except KeyError:
        raise ValueError(
            f"unsupported meshio cell type {cell_type!r}; supported: {sorted(_BY_MESHIO_TYPE)}"
        ) from None


#: straight pieces of the elements of dimension 1 and 2 (node indices, meshio order: corners
#: first, then mid-edge nodes): a line3 is 2 segments, a tri6 4 triangles (the three at its
#: corners, then the middle one), each oriented like its element; a linear element is one piece
_STRAIGHT_PIECES = {
    (ELEMENTS[name].dim, ELEMENTS[name].nen): np.array(pieces)
    for name, pieces in {
        "line2": [[0, 1]],
        "line3": [[0, 2], [2, 1]],
        "tri3": [[0, 1, 2]],
        "tri6": [[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]],
    }.items()
}


def straight_pieces(cells: np.ndarray, dim: int) -> np.ndarray:
    """The straight pieces of line or triangle elements: quadratic ones split at their mid-nodes.

    This is how quadratic elements enter the collision mesh (segments in 2D, triangles in 3D),
    the enclosed areas and volumes of the metrics, and the figures.

    Parameters
    ----------
    cells : ndarray, shape (k, nen)
        Node indices of k elements of dimension ``dim``: line2 or line3 (``dim`` 1: the facets
        of a 2D mesh), tri3 or tri6 (``dim`` 2: the facets of a 3D mesh, or the cells of a 2D
        one), in meshio's node order.
    dim : {1, 2}
        The elements' own dimension.

    Returns
    -------
    ndarray, shape (k * p, dim + 1)
        Node indices of the pieces, the p pieces of each element together (p = 2 for a line3, 4
        for a tri6, 1 for a linear element), each oriented like its element.

    Raises
    ------
    ValueError
        For elements of another dimension or node count.
    """
    cells = np.asarray(cells)
    try:
        table = _STRAIGHT_PIECES[(dim, cells.shape[1])]
    except KeyError:
        raise ValueError(f"no line or triangle element of dimension {dim} with {cells.shape[1]} nodes "
                         "(expected line2/line3 for dimension 1, tri3/tri6 for 2)") from None
    return cells[:, table].reshape(-1, dim + 1)


# --------------------------------------------------------------------------------------------
# Isoparametric maps
# --------------------------------------------------------------------------------------------


def _det_and_adjugate(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Determinant and adjugate (= det * inverse) of stacked square matrices, closed form."""
    d = J.shape[-1]
    if d == 1:
        return J[..., 0, 0], np.ones_like(J)
    if d == 2:
        a, b, c, e = J[..., 0, 0], J[..., 0, 1], J[..., 1, 0], J[..., 1, 1]
        det = a * e - b * c
        adj = np.stack([np.stack([e, -b], -1), np.stack([-c, a], -1)], -2)
        return det, adj
    a, b, c = J[..., 0, 0], J[..., 0, 1], J[..., 0, 2]
    d, e, f = J[..., 1, 0], J[..., 1, 1], J[..., 1, 2]
    g, h, i = J[..., 2, 0], J[..., 2, 1], J[..., 2, 2]
    adj = np.empty_like(J)
    adj[..., 0, 0] = e * i - f * h
    adj[..., 0, 1] = c * h - b * i
    adj[..., 0, 2] = b * f - c * e
    adj[..., 1, 0] = f * g - d * i
    adj[..., 1, 1] = a * i - c * g
    adj[..., 1, 2] = c * d - a * f
    adj[..., 2, 0] = d * h - e * g
    adj[..., 2, 1] = b * g - a * h
    adj[..., 2, 2] = a * e - b * d
    det = a * adj[..., 0, 0] + b * adj[..., 1, 0] + c * adj[..., 2, 0]
    return det, adj


def _jacobians(coords: np.ndarray, dN: np.ndarray) -> np.ndarray:
    """``J[e, q, i, j] = sum_a coords[e, a, i] dN[q, a, j]`` as one 2D matrix product (fast)."""
    ne, nen, dim = coords.shape
    nq, _, rdim = dN.shape
    J = coords.transpose(0, 2, 1).reshape(ne * dim, nen) @ dN.transpose(1, 0, 2).reshape(nen, nq * rdim)
    return np.ascontiguousarray(J.reshape(ne, dim, nq, rdim).transpose(0, 2, 1, 3))


def _rule(element: ReferenceElement, quad_points, quad_weights) -> tuple[np.ndarray, np.ndarray]:
    if (quad_points is None) != (quad_weights is None):
        raise ValueError("give both quad_points and quad_weights, or neither")
    if quad_points is None:
        return element.quad_points, element.quad_weights
    pts = np.asarray(quad_points, dtype=float).reshape(-1, element.dim)
    w = np.asarray(quad_weights, dtype=float).reshape(-1)
    if w.shape[0] != pts.shape[0]:
        raise ValueError(f"{pts.shape[0]} quadrature points but {w.shape[0]} weights")
    return pts, w


def physical_gradients(
    element: ReferenceElement,
    coords: np.ndarray,
    quad_points: np.ndarray | None = None,
    quad_weights: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function gradients in physical coordinates and quadrature volume elements.

    Parameters
    ----------
    element : ReferenceElement
        The element type.
    coords : ndarray, shape (ne, nen, dim)
        Node coordinates of ``ne`` elements [mm] (``dim == element.dim``).
    quad_points : ndarray, shape (nq, dim), optional
        Quadrature points in reference coordinates [-] (default: the element's own rule).
    quad_weights : ndarray, shape (nq,), optional
        Their weights [-].

    Returns
    -------
    dNdX : ndarray, shape (ne, nq, nen, dim)
        Shape-function gradients [1/mm].
    dV : ndarray, shape (ne, nq)
        ``det J * weight`` [mm^dim].

    Raises
    ------
    ValueError
        For ``coords`` of the wrong shape, or naming the first element with ``det J <= 0`` at a
        quadrature point (inverted or degenerate).
    """
    coords = np.asarray(coords, dtype=float)
    if coords.ndim != 3 or coords.shape[1:] != (element.nen, element.dim):
        raise ValueError(
            f"coords for {element.name} must have shape (ne, {element.nen}, {element.dim}), got {coords.shape}"
        )
    pts, w = _rule(element, quad_points, quad_weights)
    dN = element.grad(pts)  # (nq, nen, dim)
    # J_ij = dx_i / dxi_j, (ne, nq, dim, dim); affine elements: one Jacobian, broadcast over points
    J = _jacobians(coords, dN[:1] if element.order == 1 else dN)
    det, adj = _det_and_adjugate(J)
    bad = ~(det > 0.0)
    if bad.any():
        e, q = np.argwhere(bad)[0]
        raise ValueError(
            f"element {e} of {coords.shape[0]} ({element.name}) is inverted or degenerate: "
            f"det J = {det[e, q]:.3g} <= 0 at quadrature point {q} "
            f"({int(bad.any(axis=1).sum())} bad element(s) in total)"
        )
    Jinv = adj / det[..., None, None]
    dNdX = np.matmul(dN[None], Jinv)  # (ne, nq, nen, dim): dN/dxi_j dxi_j/dX_k
    dV = np.broadcast_to(det, (coords.shape[0], pts.shape[0])) * w
    if element.order == 1:
        dNdX = np.ascontiguousarray(np.broadcast_to(dNdX, (coords.shape[0], pts.shape[0], element.nen, element.dim)))
    return dNdX, dV


def facet_measure(
    facet: ReferenceElement,
    coords: np.ndarray,
    quad_points: np.ndarray | None = None,
    quad_weights: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shape values, area elements and unit normals of boundary facets.

    For an edge from node 0 to node 1 with tangent ``t = dx/dxi``, ``n = (t_y, -t_x) / |t|``;
    for a triangle, ``n ~ dx/dxi1 x dx/dxi2`` (the direction of ``(x1 - x0) x (x2 - x0)``). With
    the facets of ``ReferenceElement.facets`` these normals point out of positively oriented
    elements.

    Parameters
    ----------
    facet : ReferenceElement
        A ``line2``/``line3`` (in 2D) or ``tri3``/``tri6`` (in 3D) element.
    coords : ndarray, shape (nf, nfn, facet.dim + 1)
        Node coordinates of the facets [mm].
    quad_points : ndarray, shape (nq, facet.dim), optional
        Quadrature points in reference coordinates [-] (default: the facet's own rule).
    quad_weights : ndarray, shape (nq,), optional
        Their weights [-].

    Returns
    -------
    N : ndarray, shape (nq, nfn)
        Shape values [-].
    dA : ndarray, shape (nf, nq)
        Area element times weight [mm^(dim-1)].
    normals : ndarray, shape (nf, nq, dim)
        Unit normals [-].

    Raises
    ------
    ValueError
        For a facet element of the wrong dimension, ``coords`` of the wrong shape, or naming the
        first facet with zero area element at a quadrature point.
    """
    if facet.dim not in (1, 2):
        raise ValueError(f"facet element must be of dimension 1 or 2, got {facet.name} (dim {facet.dim})")
    dim = facet.dim + 1
    coords = np.asarray(coords, dtype=float)
    if coords.ndim != 3 or coords.shape[1:] != (facet.nen, dim):
        raise ValueError(f"coords for facets {facet.name} must have shape (nf, {facet.nen}, {dim}), got {coords.shape}")
    pts, w = _rule(facet, quad_points, quad_weights)
    N = facet.shape(pts)
    T = _jacobians(coords, facet.grad(pts))  # (nf, nq, dim, fdim) tangents dx/dxi
    if dim == 2:
        t = T[..., 0]
        n = np.stack([t[..., 1], -t[..., 0]], axis=-1)
    else:
        n = np.cross(T[..., 0], T[..., 1])
    area = np.linalg.norm(n, axis=-1)
    bad = ~(area > 0.0)
    if bad.any():
        f, q = np.argwhere(bad)[0]
        raise ValueError(f"facet {f} of {coords.shape[0]} ({facet.name}) is degenerate at quadrature point {q}")
    return N, area * w, n / area[..., None]
