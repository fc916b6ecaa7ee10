"""Verification of the load terms (issue 15, item 1): the uniform pressure as an energy term.

Every test names the independent result it compares with: finite differences of the energy,
the mesh's own cell areas and volumes, the Lame thick-walled cylinder (small strain) and the
radially symmetric finite-strain solution found by shooting on the radial equilibrium ODE.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem.meshing import annulus, ball, disk
from hydrojam.fem.solver.path import PathOptions, solve_path
from hydrojam.fem.problem import Problem, fixed
from hydrojam.fem.terms import PressureTerm, ScaledTerm, outward_facets
from hydrojam.materials.energies import NeoHookean

G, NU = 1.0, 0.3  # MPa, -
R_IN, R_OUT = 1.0, 2.0  # mm
MESH_SIZE = 0.2  # mm, quadratic triangles
MATERIAL = NeoHookean(shear_modulus=G, poisson_ratio=NU)


# ----------------------------------------------------------------------------------------------
# Derivatives and the enclosed volume


def _distorted(points, seed=3):
    rng = np.random.default_rng(seed)
    return 1.1 * points + 0.05 * rng.standard_normal(points.shape) + 0.3


@pytest.mark.parametrize("dim", [2, 3])
def test_gradient_and_hessian_match_central_differences(dim):
    """line3 (2D) and tri6 (3D) facets at a distorted state: gradient = central FD of the energy,
    Hessian = central FD of the gradient. In 2D E is quadratic and in 3D cubic in x, so central
    differences have truncation error h^2/6 |E'''| (zero in 2D); with round-off eps |E| / h the
    tolerance is a few times the sum, from the energy's scale |E| ~ p L^d (L = 1 mm)."""
    mesh = disk(1.0, 0.5, order=2) if dim == 2 else ball(1.0, 0.8, order=2)
    facets = next(iter(mesh.facet_groups.values()))
    assert facets.shape[1] == (3 if dim == 2 else 6)
    p = 0.7
    T = PressureTerm(mesh.points, facets, p)
    x = _distorted(mesh.points)
    g, H = T.gradient(x), T.hessian(x).toarray()
    scale = abs(T.energy(x))
    h = 1e-5
    eps = np.finfo(float).eps
    tol_g = 10 * (eps * scale / h + (h**2 * scale if dim == 3 else 0.0))
    tol_H = 10 * (eps * scale / h + (h**2 * scale if dim == 3 else 0.0))
    rng = np.random.default_rng(0)
    dofs = np.unique(facets) * dim
    dofs = rng.choice(np.concatenate([dofs + k for k in range(dim)]), size=min(40, dofs.size * dim), replace=False)
    xf = x.ravel()
    for i in dofs:
        e = np.zeros_like(xf)
        e[i] = h
        fd_g = (T.energy((xf + e).reshape(x.shape)) - T.energy((xf - e).reshape(x.shape))) / (2 * h)
        assert abs(fd_g - g[i]) < tol_g
        fd_H = (T.gradient((xf + e).reshape(x.shape)) - T.gradient((xf - e).reshape(x.shape))) / (2 * h)
        assert np.max(np.abs(fd_H - H[:, i])) < tol_H
    assert np.allclose(H, H.T, atol=1e-14 * np.abs(H).max())
    # projected: positive semi-definite
    assert np.linalg.eigvalsh(T.hessian(x, project=True).toarray()).min() > -1e-12 * np.abs(H).max()


@pytest.mark.parametrize("dim", [2, 3])
def test_follower_energy_is_p_times_enclosed_volume_and_translation_invariant(dim):
    """Closed outward boundary of a body (annulus: both circles; ball): E = p times the body's
    area/volume from the mesh's own (curved, isoparametric) cell measures, to round-off, and a
    rigid translation (of a distorted state) leaves E unchanged."""
    mesh = annulus(R_IN, R_OUT, 0.4) if dim == 2 else ball(1.0, 0.8, order=2)
    facets = np.vstack(list(mesh.facet_groups.values()))
    p = 0.3
    T = PressureTerm(mesh.points, facets, p)
    body = mesh.cell_volumes(curved=True).sum()
    assert T.energy(mesh.points) == pytest.approx(p * body, rel=1e-12)
    x = _distorted(mesh.points)
    shift = np.array([3.0, -1.5, 0.7][:dim])
    assert T.energy(x + shift) == pytest.approx(T.energy(x), rel=1e-11)
    # distorted quadratic cells: the volume enclosed by the deformed boundary is still the
    # sum of the deformed cells' curved measures
    deformed = type(mesh)(x, mesh.cells, mesh.cell_type)
    assert T.volume(x) == pytest.approx(deformed.cell_volumes(curved=True).sum(), rel=1e-11)


def test_area_matches_shoelace_of_a_finely_sampled_boundary():
    """Outer circle alone, deformed by a smooth map: the area enclosed (about the origin) equals
    the shoelace formula on the quadratic facets sampled at 200 points each."""
    mesh = annulus(R_IN, R_OUT, 0.4)
    facets = mesh.facet_groups["outer"]
    X = mesh.points
    x = X + 0.1 * np.column_stack([np.sin(2 * X[:, 1]), X[:, 0] ** 2])
    T = PressureTerm(X, facets, 1.0)
    xi = np.linspace(0.0, 1.0, 200, endpoint=False)
    N = np.column_stack([(1 - xi) * (1 - 2 * xi), xi * (2 * xi - 1), 4 * xi * (1 - xi)])  # line3
    # facets are oriented consistently, so their samples concatenate into a closed polygon
    # once ordered along the circle
    order = np.argsort(np.arctan2(X[facets[:, 0], 1], X[facets[:, 0], 0]))
    curve = np.vstack([N @ x[f] for f in facets[order]])
    shoelace = 0.5 * np.sum(curve[:, 0] * np.roll(curve[:, 1], -1) - np.roll(curve[:, 0], -1) * curve[:, 1])
    assert T.volume(x) == pytest.approx(shoelace, rel=1e-6)  # measured 2e-7
    assert T.volume(X) == pytest.approx(np.pi * R_OUT**2, rel=1e-5)  # the quadratic arcs: 3e-6


def test_outward_facets_reorients_reversed_facets():
    """Facets given inward (reversed) are turned outward from the cells they bound; a facet
    that bounds no cell, and a facet of no known type, are refused."""
    mesh = annulus(R_IN, R_OUT, 0.4)
    facets = np.vstack([mesh.facet_groups["inner"], mesh.facet_groups["outer"]])
    flipped = facets[:, [1, 0, 2]]
    assert np.array_equal(outward_facets(mesh.points, mesh.cells, flipped), facets)
    T = PressureTerm(mesh.points, flipped, 1.0, cells=mesh.cells)
    assert T.volume(mesh.points) == pytest.approx(mesh.cell_volumes(curved=True).sum(), rel=1e-12)
    with pytest.raises(ValueError, match="bounds 0 cells"):
        outward_facets(mesh.points, mesh.cells[:10], facets)
    with pytest.raises(ValueError, match="no facet type with 4 nodes in 2D"):
        PressureTerm(mesh.points, np.zeros((1, 4), dtype=int), 1.0)


# ----------------------------------------------------------------------------------------------
# Thick-walled cylinder


def lame_displacements(p):
    """Plane-strain Lame solution for an external pressure p [MPa] on r = R_OUT, free r = R_IN:
    u(r) = A r + B / r with the small-strain Lame constants of the material (lambda from G and
    nu, as NeoHookean's bulk modulus K = 2G(1 + nu) / (3(1 - 2nu)) = lambda + 2G/3).
    Radial displacements [mm] of the inner and outer surfaces."""
    lam = MATERIAL.bulk_modulus - 2.0 * G / 3.0
    A = -p * R_OUT**2 / (2.0 * (lam + G) * (R_OUT**2 - R_IN**2))
    B = (lam + G) * A * R_IN**2 / G
    return A * R_IN + B / R_IN, A * R_OUT + B / R_OUT


def radial_solution(p, follower=True):
    """Finite-strain plane-strain solution of the same cylinder: r(R) with F = diag(r', r/R) in
    polar axes, the material's own nominal stress P and tangent (evaluate), equilibrium
    dP_rR/dR + (P_rR - P_thTh)/R = 0, P_rR(R_IN) = 0 and on R_OUT the follower traction
    P_rR = -p r/R (pressure on the current length) or the dead one P_rR = -p; shooting on r(R_IN).
    Radial displacements [mm] of the inner and outer surfaces."""

    def response(stretch_r, stretch_t, tangent=True):
        return MATERIAL.evaluate(np.array([[stretch_r, 0.0], [0.0, stretch_t]]), tangent=tangent)

    def rhs(R, y):
        r, dr = y
        out = response(dr, r / R)
        P, A = out.stress, out.tangent
        return [dr, -((P[0, 0] - P[1, 1]) / R + A[0, 0, 1, 1] * (dr / R - r / R**2)) / A[0, 0, 0, 0]]

    def outer(ra):
        dr0 = brentq(lambda d: response(d, ra / R_IN, False).stress[0, 0], 0.2, 5.0, xtol=1e-14)
        sol = solve_ivp(rhs, (R_IN, R_OUT), [ra, dr0], rtol=1e-11, atol=1e-13)
        return sol.y[:, -1]

    def miss(ra):
        rb, drb = outer(ra)
        return response(drb, rb / R_OUT, False).stress[0, 0] + p * (rb / R_OUT if follower else 1.0)

    ra = brentq(miss, 0.5 * R_IN, R_IN, xtol=1e-14)
    return ra - R_IN, outer(ra)[0] - R_OUT


def solve_cylinder(p, follower=True):
    """FE thick-walled cylinder: full annulus (quadratic triangles of size MESH_SIZE) under the
    pressure ramped with s; the rigid modes pinned by symmetry (x = 0 held in x, z = 0 held in z,
    exact for the axisymmetric solution). Mean radial displacements [mm] of the inner and outer
    surfaces, and their spread over the nodes."""
    mesh = annulus(R_IN, R_OUT, MESH_SIZE)
    X = mesh.points
    S = Solid(X, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), MATERIAL, "body")])
    T = PressureTerm(X, mesh.facet_groups["outer"], p, follower=follower)
    bcs = [fixed(np.flatnonzero(np.abs(X[:, 0]) < 1e-9), 2, [0]), fixed(np.flatnonzero(np.abs(X[:, 1]) < 1e-9), 2, [1])]
    res = solve_path(Problem(X, lambda s: [S, ScaledTerm(T, s)], bcs, force_scale=p * R_OUT), PathOptions(ds0=1.0))
    assert res.converged, res.message
    out = []
    for g in ("inner", "outer"):
        nodes = mesh.group_nodes(g)
        u = np.linalg.norm(res.x[nodes], axis=1) - np.linalg.norm(X[nodes], axis=1)
        out.append((u.mean(), np.ptp(u)))
    return out


def test_radial_ode_reduces_to_lame_at_small_pressure():
    """The finite-strain reference itself: at p = 1e-3 G it is the Lame solution within O(p/G)."""
    p = 1e-3 * G
    for ode, lame in zip(radial_solution(p), lame_displacements(p)):
        assert ode == pytest.approx(lame, rel=3 * p / G)


def test_lame_cylinder_small_pressure():
    """External follower pressure p = 1e-3 G on the neo-Hookean annulus (G = 1 MPa, nu = 0.3,
    1 mm / 2 mm, mesh size 0.2 mm): inner and outer radial displacements within 0.5 % of Lame
    (measured 0.13 % and 0.09 %, mostly the geometric nonlinearity of order p/G: against the
    finite-strain solution 1e-4), and uniform around the circle."""
    p = 1e-3 * G
    fe = solve_cylinder(p)
    for (u, spread), lame, ode in zip(fe, lame_displacements(p), radial_solution(p)):
        assert u == pytest.approx(lame, rel=5e-3)
        assert u == pytest.approx(ode, rel=5e-4)
        assert spread < 1e-3 * abs(lame)


def test_cylinder_finite_strain_follower_pressure():
    """p = 0.2 G (inner hoop strain about -15 %, Lame would say -19 %): the FE inner and outer
    radii against the shooting solution within 1e-3 of the displacement (measured 1e-4 at mesh
    size 0.2 mm, 1e-5 at 0.1 mm)."""
    p = 0.2 * G
    fe = solve_cylinder(p)
    for (u, spread), ode in zip(fe, radial_solution(p)):
        assert u == pytest.approx(ode, rel=1e-3)
        assert spread < 2e-3 * abs(ode)


def test_dead_and_follower_pressure():
    """At the reference the dead and follower loads are the same forces; at p = 1e-3 G their
    solutions differ by the order of the strain (|u|/r ~ 1e-3): within 3 |u|/r of |u|. At p = 0.2 G
    the dead load matches its own finite-strain solution (P_rR = -p on R_OUT)."""
    mesh = annulus(R_IN, R_OUT, 0.4)
    f = mesh.facet_groups["outer"]
    dead, follower = PressureTerm(mesh.points, f, 0.5, follower=False), PressureTerm(mesh.points, f, 0.5)
    assert dead.hessian(mesh.points).nnz == 0 and dead.energy(mesh.points) == 0.0
    assert np.allclose(dead.gradient(mesh.points), follower.gradient(mesh.points), atol=1e-13)
    p = 1e-3 * G
    for (u_d, _), (u_f, _) in zip(solve_cylinder(p, follower=False), solve_cylinder(p)):
        strain = abs(u_f) / R_IN
        assert abs(u_d - u_f) < 3 * strain * abs(u_f)
        assert abs(u_d - u_f) > 0.0
    p = 0.2 * G
    for (u, _), ode in zip(solve_cylinder(p, follower=False), radial_solution(p, follower=False)):
        assert u == pytest.approx(ode, rel=1e-3)
