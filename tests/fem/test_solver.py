"""Verification of the finite-strain FE core and the energy-minimising solver (issue: FE core).

Every test names the analytic or independent result it compares with.
"""

import numpy as np
import scipy.sparse as sp
import pytest
from scipy.optimize import brentq

from hydrojam.fem.meshing import ball_octant, box, quarter_disk, rectangle
from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.materials.energies import Hydrogel, HydrogelParams, NeoHookean
from hydrojam.fem import (
    Dirichlet,
    NewtonOptions,
    PathOptions,
    Problem,
    fixed,
    minimize,
    prescribed,
    solve_path,
)
from hydrojam.materials.swelling import constrained_swelling, free_swelling
from hydrojam.fem.terms import ScaledTerm, surface_load

PARAMS = HydrogelParams()
GEL = Hydrogel(PARAMS)


def solid(mesh, material):
    return Solid(mesh.points, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), material, "body")])


def stimulus(s, T_target=275.0, mu_target=0.0):
    """The design's stimulus path: (mu0, T0) -> (mu_target, T_target) linearly in s."""
    return PARAMS.mu0 + s * (mu_target - PARAMS.mu0), PARAMS.T0 + s * (T_target - PARAMS.T0)


def gel_terms(S, **kw):
    return lambda s: [S.with_materials({"body": GEL.at(*stimulus(s, **kw))})]


# ----------------------------------------------------------------------------------------------
# Derivatives


@pytest.mark.parametrize("dim", [2, 3])
def test_gradient_and_hessian_match_finite_differences(dim):
    """Assembled gradient = central FD of the assembled energy; Hessian . v = FD of the gradient
    along v (quadratic elements, swollen gel, perturbed state)."""
    mesh = rectangle(2.0, 1.0, 0.5, order=2) if dim == 2 else box(1.0, 1.0, 1.0, 0.7, order=2)
    S = solid(mesh, GEL.at(0.0, 280.0))
    rng = np.random.default_rng(1)
    x = mesh.points * 1.1 + 0.02 * rng.standard_normal(mesh.points.shape)
    g = S.gradient(x)
    H = S.hessian(x)
    h = 1e-6
    for _ in range(3):
        v = rng.standard_normal(x.shape)
        fd = (S.energy(x + h * v) - S.energy(x - h * v)) / (2 * h)
        assert fd == pytest.approx(g @ v.ravel(), rel=1e-6)
        fdg = (S.gradient(x + h * v) - S.gradient(x - h * v)) / (2 * h)
        assert np.linalg.norm(fdg - H @ v.ravel()) <= 1e-6 * np.linalg.norm(fdg)
    assert abs(H - H.T).max() <= 1e-10 * abs(H).max()


def test_projected_hessian_is_positive_semidefinite_and_exact_where_convex():
    """Element PSD projection: no negative eigenvalue; unchanged at the stress-free reference,
    where every element matrix is already positive semi-definite."""
    mesh = rectangle(2.0, 1.0, 0.5, order=2)
    rng = np.random.default_rng(2)
    S = solid(mesh, GEL.at(0.0, 275.0))
    x = mesh.points + 0.05 * rng.standard_normal(mesh.points.shape)
    Hp = S.hessian(x, project=True).toarray()
    assert np.linalg.eigvalsh(Hp).min() >= -1e-9 * np.abs(Hp).max()
    E = solid(mesh, NeoHookean())
    Hf, Hq = E.hessian(mesh.points).toarray(), E.hessian(mesh.points, project=True).toarray()
    assert np.abs(Hf - Hq).max() <= 1e-12 * np.abs(Hf).max()  # stress-free: already PSD


def test_surface_load_nodal_forces_sum_to_traction_times_area():
    """Consistent nodal forces of a uniform traction t on a face of area A sum to t A."""
    m2 = rectangle(3.0, 2.0, 0.4, order=2)
    f = surface_load(m2.points, m2.facet_groups["right"], [0.5, -0.25]).forces
    assert f.sum(axis=0) == pytest.approx([0.5 * 2.0, -0.25 * 2.0], rel=1e-12)
    m3 = box(1.0, 2.0, 3.0, 0.8, order=2)
    f = surface_load(m3.points, m3.facet_groups["zmax"], [0.0, 0.0, 2.0]).forces
    assert f.sum(axis=0) == pytest.approx([0.0, 0.0, 2.0 * 2.0], abs=1e-12)


# ----------------------------------------------------------------------------------------------
# Patch test and homogeneous deformations


@pytest.mark.parametrize("shape, order", [("rect", 1), ("rect", 2), ("box", 1), ("box", 2)])
def test_patch_test_reproduces_affine_deformation(shape, order):
    """Patch test: an affine map x = A X + b prescribed on the boundary of an irregular mesh is
    reproduced exactly at every interior node (a homogeneous state is an exact equilibrium)."""
    mesh = rectangle(2.0, 1.5, 0.35, order=order) if shape == "rect" else box(1.0, 1.0, 1.0, 0.45, order=order)
    d = mesh.dim
    rng = np.random.default_rng(3)
    A = np.eye(d) + 0.15 * rng.standard_normal((d, d))
    b = rng.standard_normal(d)
    target = mesh.points @ A.T + b
    bnodes = np.unique(mesh.boundary_facets())
    dofs = (bnodes[:, None] * d + np.arange(d)).ravel()
    bc = Dirichlet(dofs, (target - mesh.points).ravel()[dofs])
    S = solid(mesh, NeoHookean(poisson_ratio=0.3))
    res = solve_path(Problem(mesh.points, lambda s: [S], [bc], force_scale=0.023), PathOptions(ds0=0.5))
    assert res.converged, res.message
    inner = np.setdiff1d(np.arange(mesh.n_nodes), bnodes)
    assert len(inner) > 0
    # known to rtol 1e-6 x the forces in play (0.015-0.063 N) / the softest stiffness (0.0044-0.075 N/mm)
    # = 2e-7 - 1.5e-5 mm (measured 1e-15 - 3e-9); 1e-4 mm is 1e-4 of the 1-3.7 mm displacement
    assert np.abs(res.x[inner] - target[inner]).max() < 1e-4


def _nh_principal_stress(G, K, lam):
    """Nominal stresses dW/dl_i of W = G/2 (J^(-2/3) I1 - 3) + K/2 (J - 1)^2 in principal stretches
    (coded independently of the tensor kernel)."""
    lam = np.asarray(lam, dtype=float)
    J = lam.prod()
    I1 = (lam**2).sum()
    return G / 2 * J ** (-2 / 3) * (2 * lam - 2 / 3 * I1 / lam) + K * (J - 1) * J / lam


def test_uniaxial_tension_matches_analytic_stress_stretch_curve():
    """3D uniaxial tension of a neo-Hookean block (symmetry planes, free lateral faces): the
    reaction per reference area equals the analytic P11(l1) with l2 = l3 from P22 = 0."""
    mesh = box(2.0, 1.0, 1.0, 0.5, order=2)
    mat = NeoHookean(shear_modulus=0.023, poisson_ratio=0.45)
    S = solid(mesh, mat)
    g = mesh.group_nodes
    bcs = [fixed(g("xmin"), 3, [0]), fixed(g("ymin"), 3, [1]), fixed(g("zmin"), 3, [2]), prescribed(g("xmax"), 3, 0, 2.0)]
    prob = Problem(mesh.points, lambda s: [S], bcs, force_scale=mat.shear_modulus)
    seen = []

    def record(s, x, rec):
        seen.append((s, S.gradient(x).reshape(-1, 3)[g("xmax"), 0].sum()))

    res = solve_path(prob, PathOptions(ds0=0.2, ds_max=0.2, newton=NewtonOptions(rtol=1e-10)), callback=record)
    assert res.converged and len(seen) >= 5
    G, K = mat.shear_modulus, mat.bulk_modulus
    for s, reaction in seen:
        l1 = 1.0 + s  # stretch of the 2 mm bar displaced by 2 s mm
        l2 = brentq(lambda l: _nh_principal_stress(G, K, [l1, l, l])[1], 0.3, 1.2)
        P11 = _nh_principal_stress(G, K, [l1, l2, l2])[0]
        # reference area 1 mm^2. The reaction is known to the accepted residual: solver rtol 1e-10 x 0.05 N
        # in play, x 1e3 at most on the stall path = 5e-9 N, 4.5e-7 of P11 >= 0.011 N (measured 4e-8)
        assert reaction / 1.0 == pytest.approx(P11, rel=1e-6)


# ----------------------------------------------------------------------------------------------
# Cantilever: quadratic elements do not lock, linear ones do


def _cantilever_tip_ratio(order, nu, L=100.0, h=4.0, size=1.0):
    mesh = rectangle(L, h, size, order=order, structured=True)
    mat = NeoHookean(shear_modulus=0.023, poisson_ratio=nu)
    S = solid(mesh, mat)
    Ep = 2 * mat.shear_modulus * (1 + nu) / (1 - nu**2)  # plane-strain modulus
    I = h**3 / 12
    P = 1e-3 * L * 3 * Ep * I / L**3  # Euler-Bernoulli tip deflection of L/1000: linear regime
    load = surface_load(mesh.points, mesh.facet_groups["right"], [0.0, -P / h])
    prob = Problem(mesh.points, lambda s: [S, ScaledTerm(load, s)], [fixed(mesh.group_nodes("left"), 2)],
                   force_scale=mat.shear_modulus * h)
    res = solve_path(prob, PathOptions(ds0=1.0))
    assert res.converged
    tip = -(res.x - mesh.points)[mesh.group_nodes("right"), 1].mean()
    return tip / (P * L**3 / (3 * Ep * I))


@pytest.mark.parametrize("nu", [0.45, 0.49])
def test_cantilever_quadratic_matches_euler_bernoulli(nu):
    """Slender plane-strain cantilever (L/h = 25) under a small tip shear load: the tip deflection
    of quadratic triangles is within 2% of Euler-Bernoulli, P L^3 / (3 E' I), E' = E/(1 - nu^2)."""
    assert _cantilever_tip_ratio(2, nu) == pytest.approx(1.0, abs=0.02)


def test_cantilever_linear_triangles_lock():
    """Linear triangles at nu = 0.49 on the same mesh lock: far stiffer than Euler-Bernoulli."""
    assert _cantilever_tip_ratio(1, 0.49) < 0.5


# ----------------------------------------------------------------------------------------------
# Hydrogel swelling against the material-point analysis


def test_free_swelling_of_a_disk_plane_strain():
    """A gel disk (quarter, symmetry planes) swells from (mu0, T0) to (0, 275 K): the radius ratio
    equals the plane-strain material-point stretch (out-of-plane dry stretch held at lambda0)."""
    mesh = quarter_disk(2.0, 0.5, order=2)
    S = solid(mesh, GEL)
    g = mesh.group_nodes
    prob = Problem(mesh.points, gel_terms(S), [fixed(g("xsym"), 2, [0]), fixed(g("zsym"), 2, [1])],
                   force_scale=GEL.shear_modulus_ref * 2.0)
    res = solve_path(prob)
    assert res.converged, res.message
    expected = constrained_swelling(PARAMS, 0.0, 275.0, (PARAMS.lambda0,)).stretch / PARAMS.lambda0
    arc = g("arc")
    ratio = np.linalg.norm(res.x[arc], axis=1) / np.linalg.norm(mesh.points[arc], axis=1)
    assert ratio == pytest.approx(expected, rel=1e-7)
    assert expected > 2.0  # a real swelling, not a trivial pass


def test_free_swelling_of_a_sphere_3d():
    """A gel sphere (octant) swells from (mu0, T0) to (0, 285 K): every node moves radially by the
    free-swelling stretch of the swelling module."""
    mesh = ball_octant(2.0, 0.9, order=2)
    S = solid(mesh, GEL)
    g = mesh.group_nodes
    bcs = [fixed(g("xsym"), 3, [0]), fixed(g("ysym"), 3, [1]), fixed(g("zsym"), 3, [2])]
    prob = Problem(mesh.points, gel_terms(S, T_target=285.0), bcs, force_scale=GEL.shear_modulus_ref * 4.0)
    res = solve_path(prob)
    assert res.converged, res.message
    expected = free_swelling(PARAMS, 0.0, 285.0).stretch_rel
    assert np.abs(res.x - expected * mesh.points).max() < 1e-6
    assert expected > 1.9


def test_bonded_layer_swells_as_hong_liu_suo_predict():
    """Hong, Liu & Suo (2009) benchmark: a gel layer bonded to a rigid substrate (lateral stretch
    held at lambda0) swells in thickness only, n (l - 1/l) + lambda0^2 g(lambda0^2 l) = 0. Swollen
    this far the homogeneous layer is unstable (its free surface wrinkles: negative eigenvalues),
    so the path keeps that branch (settle "never") instead of leaving it for a folded state."""
    mesh = rectangle(4.0, 1.0, 0.3, order=2)
    S = solid(mesh, GEL)
    g = mesh.group_nodes
    bcs = [fixed(g("bottom"), 2), fixed(g("left"), 2, [0]), fixed(g("right"), 2, [0])]
    res = solve_path(Problem(mesh.points, gel_terms(S), bcs, force_scale=GEL.shear_modulus_ref),
                     PathOptions(settle="never"))
    assert res.converged, res.message
    l = constrained_swelling(PARAMS, 0.0, 275.0, (PARAMS.lambda0, PARAMS.lambda0)).stretch
    n, lam0 = PARAMS.n, PARAMS.lambda0
    chi0, chi1 = PARAMS.chi_coefficients(275.0)
    J = lam0**2 * l
    gJ = np.log(1 - 1 / J) + 1 / J + (chi0 - chi1) / J**2 + 2 * chi1 / J**3
    assert n * (l - 1 / l) + lam0**2 * gJ == pytest.approx(0.0, abs=1e-10)
    thickness = res.x[g("top"), 1] / mesh.points[g("top"), 1]
    # known to rtol 1e-6 x 10.6 N in play over the thickness mode's stiffness (3.0 N/mm per |u| = 10):
    # 3.5e-5 mm of 2.45 mm = 1.4e-5 relative (measured 8e-10)
    assert thickness == pytest.approx(np.full(len(thickness), l / lam0), rel=1e-4)
    # no lateral motion: zero by symmetry at every Newton iterate, so only round-off of the 10.6 N in
    # play over the softest |eigenvalue| 0.014 N/mm, amplified over the iterations: measured 2.4e-11 mm, 400x below
    assert np.abs(res.x[:, 0] - mesh.points[:, 0]).max() < 1e-8


def test_newton_converges_quadratically():
    """Measured convergence order of full Newton: the error e_k = max|x_k - x*| satisfies
    e_k+1 <= C e_k^2 with a bounded C, and log(e_k+1/e_k)/log(e_k/e_k-1) reaches about 2."""
    mesh = rectangle(4.0, 1.0, 0.3, order=2)
    S = solid(mesh, GEL)
    g = mesh.group_nodes
    bcs = [fixed(g("bottom"), 2), fixed(g("left"), 2, [0])]
    prob = Problem(mesh.points, gel_terms(S), bcs, force_scale=GEL.shear_modulus_ref)
    free = prob.free_mask()
    # from the equilibrium at s = 0.13, near enough to 0.15 for full Newton steps from the start
    # (farther, the damped steps of a non-convex start take most of the iterations)
    first = minimize(gel_terms(S)(0.13), mesh.points, free, prob.force_scale)
    assert first.converged  # stable regime: no swelling-induced creasing of the layer yet
    start = first.x
    terms = gel_terms(S)(0.15)
    opts = NewtonOptions(rtol=1e-13)
    final = minimize(terms, start, free, prob.force_scale, opts)
    assert final.converged
    iterates = [minimize(terms, start, free, prob.force_scale, NewtonOptions(rtol=1e-13, max_iter=k)).x
                for k in range(final.iterations)]
    e = np.array([np.abs(x - final.x).max() for x in iterates])
    # e is measurable only above the error of final.x itself: its residual 9.4e-11 N / the softest
    # stiffness 8.5e-3 N/mm = 1.1e-8 mm
    k = [i for i in range(1, len(e) - 1) if 1e-7 < e[i + 1] and e[i] < 1e-2]
    assert len(k) >= 2, e
    orders = [np.log(e[i + 1] / e[i]) / np.log(e[i] / e[i - 1]) for i in k]
    assert max(orders) > 1.8, (orders, e)
    assert max(e[i + 1] / e[i] ** 2 for i in k) < 1e3, e


# ----------------------------------------------------------------------------------------------
# Failure handling


def test_unreachable_load_keeps_last_converged_state_and_says_so():
    """Squeezing a gel block below its dry volume is inadmissible: the path stops below the
    minimum increment with a message, keeps the last converged (finite) state, writes no NaN."""
    mesh = rectangle(1.0, 1.0, 0.5, order=1)
    S = solid(mesh, GEL)
    g = mesh.group_nodes
    # J_dry = lambda0^3 * 0.25 < 1 at s = 1: impossible
    bcs = [fixed(g("bottom"), 2), prescribed(g("top"), 2, 1, -0.75), fixed(g("left"), 2, [0]), fixed(g("right"), 2, [0])]
    res = solve_path(Problem(mesh.points, lambda s: [S], bcs, force_scale=GEL.shear_modulus_ref),
                     PathOptions(ds0=0.25, ds_min=1e-3))
    assert not res.converged
    assert 0.5 < res.s < 1.0
    assert "last converged state kept" in res.message
    assert np.all(np.isfinite(res.x))
    assert np.isfinite(S.energy(res.x))
    assert res.history and res.history[-1].s == res.s


# ----------------------------------------------------------------------------------------------
# Contracts: the term protocol, named blocks, the Newton status


def test_a_term_gets_the_documented_defaults_of_the_protocol():
    """Only energy, gradient and hessian are required; the optional parts have their defaults."""
    from hydrojam.fem.terms import EnergyTerm

    class Quadratic(EnergyTerm):
        name = "quadratic"

        def energy(self, x):
            return 0.5 * float(np.sum(x * x))

        def gradient(self, x):
            return np.ravel(x).copy()

        def hessian(self, x, project=False):
            return sp.identity(np.size(x), format="csr")

    t, x = Quadratic(), np.ones((2, 2))
    assert t.max_step(x, x) == 1.0 and t.begin_step(x) is None and t.fallback_projection is False
    assert np.array_equal(t.force_flux(x), t.gradient(x))

    class Incomplete(EnergyTerm):
        def energy(self, x):
            return 0.0

    with pytest.raises(TypeError):
        Incomplete()


def test_terms_and_blocks_are_addressed_by_name():
    from hydrojam.fem.terms import LinearTerm, by_name

    mesh = rectangle(1.0, 1.0, 0.5, order=1)
    el = element_for_meshio_type(mesh.cell_type)
    half = len(mesh.cells) // 2
    S = Solid(mesh.points, [Block(mesh.cells[:half], el, GEL, "gel"), Block(mesh.cells[half:], el, NeoHookean(), "wall")])
    load = LinearTerm(np.zeros_like(mesh.points), mesh.points)
    assert list(by_name([S, load])) == ["elastic", "load"]
    with pytest.raises(ValueError, match="load"):
        by_name([S, load, load])
    softer = S.with_materials({"gel": GEL.at(0.0, 280.0)})
    assert [b.name for b in softer.blocks] == ["gel", "wall"]
    assert softer.blocks[1].material is S.blocks[1].material  # a block not named keeps its material
    assert set(softer.block_energies(mesh.points)) == {"gel", "wall"}
    assert set(S.current_volumes(mesh.points)) == set(S.deformation_gradients(mesh.points)) == {"gel", "wall"}
    with pytest.raises(KeyError, match="membrane"):
        S.with_materials({"membrane": GEL})
    with pytest.raises(TypeError, match="mapping"):
        S.with_materials([GEL, GEL])
    with pytest.raises(ValueError, match="unique"):
        Solid(mesh.points, [Block(mesh.cells[:half], el, GEL), Block(mesh.cells[half:], el, GEL)])


def test_newton_reports_how_it_ended_as_a_status():
    from hydrojam.fem import NewtonStatus

    mesh = rectangle(1.0, 1.0, 0.5, order=2)
    S = solid(mesh, GEL.at(0.0, 280.0))
    free = Problem(mesh.points, lambda s: [S], [fixed(mesh.group_nodes("bottom"), 2)]).free_mask()
    ok = minimize([S], mesh.points, free, GEL.shear_modulus_ref)
    assert ok.status.converged and ok.converged
    short = minimize([S], mesh.points, free, GEL.shear_modulus_ref, NewtonOptions(max_iter=1))
    assert short.status is NewtonStatus.MAX_ITERATIONS and not short.converged
    assert "no convergence in 1 iterations" in short.message
    crushed = mesh.points * np.array([1.0, -1.0])  # every cell inverted: infinite energy
    bad = minimize([S], crushed, free, GEL.shear_modulus_ref)
    assert bad.status is NewtonStatus.INADMISSIBLE_START and not bad.converged


def test_a_retried_direction_reassembles_only_the_projected_terms():
    """The adaptive fallback re-assembles the Hessian of the terms that ask for projection
    (project=True) and reuses every other term's Hessian of the iteration, the same matrices as
    re-assembling them: counted calls, and the direction compared with the direction from a
    Hessian summed afresh."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.newton import _direction
    from hydrojam.fem.terms import EnergyTerm

    calls = []

    class Counted(EnergyTerm):
        def __init__(self, H, name, fallback):
            self.H, self.name, self.fallback_projection = H, name, fallback

        def energy(self, x):
            return 0.0

        def gradient(self, x):
            return np.zeros(x.size)

        def hessian(self, x, project=False):
            calls.append((self.name, project))
            return sp.csr_matrix(np.abs(self.H) if project else self.H)

    n = 4
    solid_H = np.diag([2.0, 2.0, 2.0, 2.0])
    contact_H = np.array([[0, 0, 0, 0], [0, -5.0, 5.0, 0], [0, 5.0, -5.0, 0], [0, 0, 0, 0]])
    terms = [Counted(solid_H, "solid", False), Counted(contact_H, "contact", True)]
    x = np.zeros((2, 2))
    fidx = np.arange(n)
    hessians = [t.hessian(x) for t in terms]
    Hff = sp.csr_matrix(sum(hessians))[fidx][:, fidx]
    g = np.array([0.0, 1.0, -0.5, 0.0])  # the exact Hessian's step climbs along (0, 1, -1, 0)
    calls.clear()
    opts = NewtonOptions()
    dx, slope, _, projected, _ = _direction(terms, x, hessians, Hff, np.abs(Hff.diagonal()), g, np.linalg.norm(g),
                                            0.0, fidx, LinearSolver("scipy"), opts)
    assert projected
    assert calls == [("contact", True)]
    assert slope < 0
    K = sp.csr_matrix(solid_H + np.abs(contact_H)) + sp.diags(opts.regularisation * np.abs(Hff.diagonal()).mean() * np.ones(n))
    assert np.allclose(dx, sp.linalg.spsolve(K.tocsc(), -g), rtol=1e-12, atol=0)
