"""The pneumatic baseline's load, verified (docs/assess.md): a follower pressure inside a
thick-walled spherical shell (an octant, symmetry planes held) against Lame at small strain, and
against the radially symmetric finite-strain solution (shooting on the radial equilibrium ODE)
up to and at a balloon's limit point; and the pneumatic chamber itself: pressurised to a target
angle, stiffened by the held pressure's follower Hessian only where the state says so."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem.meshing import shell_sector
from hydrojam.fem import PathOptions, solve_path
from hydrojam.fem.problem import Problem, fixed
from hydrojam.fem.terms import PressureTerm, ScaledTerm
from hydrojam.materials.energies import NeoHookean

G, NU = 1.0, 0.3  # MPa, -
MATERIAL = NeoHookean(shear_modulus=G, poisson_ratio=NU)


def lame_sphere(p, a, b, r):
    """Small-strain radial displacement [mm] at r of a sphere a <= r <= b under an inner
    pressure p [MPa]: u = p a^3 / (E (b^3 - a^3)) ((1 - 2 nu) r + (1 + nu) b^3 / (2 r^2))."""
    E = 2 * G * (1 + NU)
    return p * a**3 / (E * (b**3 - a**3)) * ((1 - 2 * NU) * r + (1 + NU) * b**3 / (2 * r**2))


def _response(stretch_r, stretch_t, tangent=True):
    return MATERIAL.evaluate(np.diag([stretch_r, stretch_t, stretch_t]), tangent=tangent)


def radial_sphere(lam_a, a, b):
    """Finite-strain spherical shell inflated to the inner hoop stretch lam_a: r(R) with
    F = diag(r', r/R, r/R), the material's own nominal stress P and tangent, equilibrium
    dP_rR/dR + 2 (P_rR - P_tt)/R = 0, the follower pressure on the inner surface
    P_rR(a) = -p lam_a^2 (Cauchy -p on the current area) and a free outer surface; p found by
    shooting. Returns (p [MPa], outer radial displacement [mm])."""

    def rhs(R, y):
        r, dr = y
        out = _response(dr, r / R)
        P, A = out.stress, out.tangent
        return [dr, -(2 * (P[0, 0] - P[1, 1]) / R + (A[0, 0, 1, 1] + A[0, 0, 2, 2]) * (dr / R - r / R**2)) / A[0, 0, 0, 0]]

    def outer(p):
        dr0 = brentq(lambda d: _response(d, lam_a, False).stress[0, 0] + p * lam_a**2, 0.05, 5.0, xtol=1e-14)
        sol = solve_ivp(rhs, (a, b), [lam_a * a, dr0], rtol=1e-10, atol=1e-12)
        rb, drb = sol.y[:, -1]
        return _response(drb, rb / b, False).stress[0, 0], rb

    p = brentq(lambda q: outer(q)[0], 0.0, 2.0 * G, xtol=1e-13)
    return p, outer(p)[1] - b


def solve_shell(a, b, size, pressure, ds0=1.0, ds_min=1e-3):
    """FE octant of the shell (quadratic tetrahedra of ``size``), the inner follower pressure
    ramped from 0 to ``pressure`` (:class:`PressureTerm`, oriented out of the body: a positive
    pressure inflates); each symmetry plane held normal to itself. Returns the path's result
    and the mesh."""
    mesh = shell_sector(a, b, size, dim=3)
    X = mesh.points
    S = Solid(X, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), MATERIAL, "body")])
    T = PressureTerm(X, mesh.facet_groups["inner"], pressure, cells=mesh.cells)
    bcs = [fixed(mesh.group_nodes(name), 3, [k]) for k, name in enumerate(("xsym", "ysym", "zsym"))]
    options = PathOptions(ds0=ds0, ds_min=ds_min)
    res = solve_path(Problem(X, lambda s: [S, ScaledTerm(T, s)], bcs, force_scale=pressure * a**2), options)
    return res, mesh


def _radial(mesh, x, group):
    nodes = mesh.group_nodes(group)
    u = np.linalg.norm(x[nodes], axis=1) - np.linalg.norm(mesh.points[nodes], axis=1)
    return u.mean(), np.ptp(u)


def test_radial_sphere_reduces_to_lame():
    """The finite-strain reference itself: inflated by a hoop strain of 1e-4 it is Lame's within
    O(strain)."""
    a, b = 1.0, 2.0
    p, ub = radial_sphere(1.0 + 1e-4, a, b)
    assert 1e-4 * a == pytest.approx(lame_sphere(p, a, b, a), rel=1e-3)
    assert ub == pytest.approx(lame_sphere(p, a, b, b), rel=1e-3)


def test_lame_sphere_small_pressure():
    """Inner follower pressure p = 1e-3 G in a 1 mm / 2 mm neo-Hookean spherical shell (G = 1
    MPa, nu = 0.3; octant, mesh 0.25 mm): inner and outer radial displacements within 1 % of
    Lame (quadratic tetrahedra, four through the wall; the geometric nonlinearity is O(p/G) =
    1e-3) and uniform over the surface to 2 %."""
    a, b, p = 1.0, 2.0, 1e-3 * G
    res, mesh = solve_shell(a, b, 0.25, p)
    assert res.converged, res.message
    for group, r in (("inner", a), ("outer", b)):
        u, spread = _radial(mesh, res.x, group)
        assert u == pytest.approx(lame_sphere(p, a, b, r), rel=1e-2)
        assert spread < 2e-2 * abs(u)


@pytest.mark.slow
def test_balloon_follows_the_radial_solution_to_its_limit_point():
    """A thin balloon (1 mm / 1.2 mm, octant, mesh 0.2 mm: one quadratic tetrahedron through the
    wall) inflated by a follower pressure ramped towards 1.1 p_max, p_max the limit point of the
    radial solution's pressure-stretch curve (its largest pressure, at a finite stretch): the
    ramp stops within 3 % of p_max (under pressure control there is no equilibrium beyond the
    limit point), and at its last converged state the radial solution's pressure at the FE's
    inner stretch is the FE's pressure within 3 % (the pressure, not the stretch, is compared:
    near the limit point dp/dlambda vanishes, so a small error in p moves lambda far)."""
    a, b = 1.0, 1.2
    peak = minimize_scalar(lambda lam: -radial_sphere(lam, a, b)[0], bounds=(1.05, 2.5), method="bounded",
                           options={"xatol": 1e-4})
    lam_max, p_max = peak.x, -peak.fun
    assert 1.05 < lam_max < 2.5 and radial_sphere(lam_max + 0.3, a, b)[0] < p_max
    res, mesh = solve_shell(a, b, 0.2, 1.1 * p_max, ds0=0.25, ds_min=1e-2)
    assert not res.converged
    p_reached = res.s * 1.1 * p_max
    assert p_reached == pytest.approx(p_max, rel=3e-2)
    u, _ = _radial(mesh, res.x, "inner")
    assert radial_sphere(1.0 + u / a, a, b)[0] == pytest.approx(p_reached, rel=3e-2)


@pytest.mark.parametrize("dimension", [2, 3])
def test_inflation_term_encloses_the_cavity(dimension):
    """The inflation term's facets are the cavity's wall oriented out of the walls, so the volume
    it encloses is minus the cavity's (2D: w x l; 3D half model: w x D/2 x l, the rim on y = 0
    closing it through the origin) and a positive pressure, E = p V, inflates."""
    from hydrojam import Design
    from hydrojam.assess.chamber import empty_chamber_mesh
    from hydrojam.assess.pneumatic import inflation_term

    d = Design(dimension=dimension, particle_layers=1, mesh={"size": 4.0}).resolved()
    mesh = empty_chamber_mesh(d)
    cavity = d.resolved_cavity_width * d.resolved_cavity_length * (d.resolved_cavity_depth / 2 if dimension == 3 else 1.0)
    assert inflation_term(mesh).volume(mesh.points) == pytest.approx(-cavity, rel=1e-9)


@pytest.mark.slow
def test_pneumatic_chamber_is_pressurised_to_the_target_angle():
    """The one-layer 2D chamber, empty (mesh 4 mm), pressurised to 35 deg: the pressure found
    bends it to the target within the tolerance (1 %), below the chamber's balloon limit
    (the ramp to 100 kPa stops near 6 kPa); the held pressure stiffens the tip over the empty
    chamber's; the blocked chamber pushes on the stop in +x (it bends toward -x)."""
    from hydrojam import Design
    from hydrojam.assess.loading import tangent_stiffness
    from hydrojam.assess.pneumatic import (ANGLE_TOLERANCE, pneumatic_blocked_force, pneumatic_stiffness,
                                           pressurise_to_angle, tip_angle)

    d = Design(particle_layers=1, mesh={"size": 4.0})
    pn = pressurise_to_angle(d, 35.0, 0.1)
    assert pn.converged, pn.message
    assert tip_angle(pn.structure, pn.x) == pytest.approx(35.0, rel=ANGLE_TOLERANCE)
    assert 0 < pn.pressure < 0.01
    assert pneumatic_stiffness(pn) > tangent_stiffness(pn.structure, pn.structure.X)
    force, give, ok = pneumatic_blocked_force(d, pn)
    assert ok and force > 0 and abs(give) < 0.1
