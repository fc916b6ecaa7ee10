"""Where a load path loses stability (hydrojam.fem.solver.path, StepRecord.negative_eigenvalues): the
detector against problems whose critical load is known analytically, and stable problems on
which it must stay silent."""

import dataclasses
import math

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import brentq

from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem.solver.linsolve import _pardiso_available
from hydrojam.fem.meshing import quarter_disk, rectangle
from hydrojam.fem.solver.release import ReleaseOptions
from hydrojam.fem import NewtonOptions, PathOptions, Problem, fixed, solve_path
from hydrojam.fem.terms import EnergyTerm, LinearTerm, ScaledTerm, ViscousStabilisation, surface_load
from hydrojam.materials.energies import Hydrogel, HydrogelParams, NeoHookean

pytestmark = pytest.mark.skipif(not _pardiso_available(), reason="the inertia comes from PARDISO (MKL)")


class SpringColumn(EnergyTerm):
    """A rigid-jointed column: node 0 (the base, held) and node 1 (the tip) joined by an axial
    spring ``axial`` [N/mm] of rest length ``length`` [mm] and a rotational spring
    ``rotational`` [N mm/rad] on the angle theta of the column from the z axis:
    E = axial/2 (r - L)^2 + rotational/2 theta^2."""

    name = "column"

    def __init__(self, length, axial, rotational):
        self.L, self.ka, self.kt = length, axial, rotational

    def _parts(self, x):
        d = x[1] - x[0]
        r = float(np.hypot(*d))
        a, b = d
        theta = math.atan2(a, b)
        e = d / r
        dtheta = np.array([b, -a]) / r**2
        d2theta = np.array([[-2 * a * b, a * a - b * b], [a * a - b * b, 2 * a * b]]) / r**4
        return r, e, theta, dtheta, d2theta

    def energy(self, x):
        r, _, theta, _, _ = self._parts(x)
        return 0.5 * self.ka * (r - self.L) ** 2 + 0.5 * self.kt * theta**2

    def gradient(self, x):
        r, e, theta, dtheta, _ = self._parts(x)
        g = self.ka * (r - self.L) * e + self.kt * theta * dtheta
        return np.concatenate([-g, g])

    def hessian(self, x, project=False):
        r, e, theta, dtheta, d2theta = self._parts(x)
        H = self.ka * (np.outer(e, e) + (r - self.L) / r * (np.eye(2) - np.outer(e, e)))
        H = H + self.kt * (np.outer(dtheta, dtheta) + theta * d2theta)
        if project:
            lam, Q = np.linalg.eigh(H)
            H = (Q * np.maximum(lam, 0.0)) @ Q.T
        return sp.csr_matrix(np.block([[H, -H], [-H, H]]))


class DoubleWell(EnergyTerm):
    """One degree of freedom u [mm] in a double well, E = k (u^4/4 - u^2/2) [mJ]: wells at
    u = -1 and 1, concave for |u| < 1/sqrt(3)."""

    name = "well"

    def __init__(self, k):
        self.k = k

    def energy(self, x):
        u = float(x[0, 0])
        return self.k * (u**4 / 4 - u**2 / 2)

    def gradient(self, x):
        u = float(x[0, 0])
        return np.array([self.k * (u**3 - u)])

    def hessian(self, x, project=False):
        u = float(x[0, 0])
        h = self.k * (3 * u * u - 1)
        return sp.csr_matrix([[max(h, 0.0) if project else h]])


def _fd_check(term, x, h=1e-6):
    """Central differences of the energy and the gradient at x."""
    flat = x.ravel()
    g, H = term.gradient(x), term.hessian(x).toarray()
    for i in range(flat.size):
        dx = np.zeros_like(flat)
        dx[i] = h
        xp, xm = (flat + dx).reshape(x.shape), (flat - dx).reshape(x.shape)
        assert (term.energy(xp) - term.energy(xm)) / (2 * h) == pytest.approx(g[i], rel=1e-6, abs=1e-8)
        assert np.allclose((term.gradient(xp) - term.gradient(xm)) / (2 * h), H[:, i], rtol=1e-5, atol=1e-7)


def test_the_toy_energies_have_consistent_derivatives():
    """The two toy terms' gradients and Hessians against central differences of their energies."""
    _fd_check(SpringColumn(10.0, 100.0, 1.0), np.array([[0.1, -0.2], [1.3, 9.1]]))
    _fd_check(DoubleWell(2.0), np.array([[-0.3]]))


def test_a_perfect_column_is_detected_past_its_critical_load():
    """A perfect spring column under a dead axial load P = s P_max stays straight (the Newton
    steps keep the symmetry), and the straight state is unstable beyond the critical load of the
    column, from the Hessian of E in the lateral direction on the straight branch (tip at
    r = L - P/k_a): k_t / r^2 - P / r = 0, i.e. P_cr (L - P_cr / k_a) = k_t, the smaller root
    P_cr = (k_a L - sqrt(k_a^2 L^2 - 4 k_a k_t)) / 2. The detector reports no negative eigenvalue
    below s_cr = P_cr / P_max and exactly one above it, so the first unstable state lies in
    (s_cr, s_cr + ds] for steps of ds."""
    L, ka, kt, p_max, ds = 10.0, 100.0, 1.0, 0.2, 0.02
    p_cr = (ka * L - math.sqrt((ka * L) ** 2 - 4 * ka * kt)) / 2
    s_cr = p_cr / p_max
    X = np.array([[0.0, 0.0], [0.0, L]])
    column = SpringColumn(L, ka, kt)
    load = LinearTerm(np.array([[0.0, 0.0], [0.0, -p_max]]), X)
    problem = Problem(X, lambda s: [column, ScaledTerm(load, s)], [fixed([0], 2)], force_scale=p_max)
    res = solve_path(problem, PathOptions(ds0=ds, ds_max=ds))
    assert res.converged, res.message
    assert abs(res.x[1, 0]) < 1e-12  # still straight: the perfect column stays on its trivial branch
    for h in res.history:
        assert h.negative_eigenvalues == (1 if h.s > s_cr else 0), (h.s, s_cr)
    assert s_cr < res.unstable_at_s <= s_cr + ds + 1e-12
    assert 0.3 < s_cr < 0.7  # the critical load is inside the path, not at an end


def test_a_snap_through_held_by_a_stabilisation_is_detected_past_its_limit_point():
    """A double well loaded by a dead force f = s f_max from its left well: the left branch ends
    at the limit point u = -1/sqrt(3), f_lim = 2k/(3 sqrt 3). With a viscous stabilisation
    c (u - u_n) of c = 2k > k (every step's energy convex), the path creeps through the snap,
    and states with |u| < 1/sqrt(3) are unstable for the physics alone. The detector leaves the
    stabilisation out ("stabilisation" is an unphysical term), so it fires exactly at the steps
    whose state, computed here by solving the stabilised step equation
    k (u^3 - u) - f + c (u - u_n) = 0 with brentq, lies in the concave region; never before the
    limit load. (The first comes several steps after it: near the limit point the force out of
    balance is small and the stabilisation lets the state creep; that lag is the
    stabilisation's, the same in the independent recursion.)"""
    k, f_max, ds = 1.0, 0.77, 0.02
    c = 2.0 * k
    f_lim = 2 * k / (3 * math.sqrt(3))
    s_lim = f_lim / f_max
    X = np.array([[-1.0]])
    well = DoubleWell(k)
    load = LinearTerm(np.array([[f_max]]), X)
    stab = ViscousStabilisation(np.array([1.0]), c, 1)
    problem = Problem(X, lambda s: [well, ScaledTerm(load, s), stab], [], force_scale=f_max)
    stabilised = dict(release=ReleaseOptions(each_step=False), extrapolate=False)  # the path's own states
    res = solve_path(problem, PathOptions(ds0=ds, ds_max=ds, newton=NewtonOptions(rtol=1e-10), **stabilised))
    assert res.converged, res.message
    u, expected = -1.0, []
    for h in res.history:
        f = h.s * f_max
        u_n = u
        u = brentq(lambda v: k * (v**3 - v) - f + c * (v - u_n), -3.0, 3.0)  # monotone: one root
        expected.append(1 if abs(u) < 1 / math.sqrt(3) else 0)
    assert [h.negative_eigenvalues for h in res.history] == expected
    assert s_lim < res.unstable_at_s < 1.0
    assert res.x[0, 0] > 1.0  # it snapped to the right well
    # with the stabilisation counted as physics, no state is unstable: what the choice is about
    counted = solve_path(problem, PathOptions(ds0=ds, ds_max=ds, newton=NewtonOptions(rtol=1e-10),
                                              unphysical_terms=(), **stabilised))
    assert counted.unstable_at_s is None


def test_a_released_path_reports_only_equilibria_of_the_physics_through_a_snap():
    """The same double well and stabilisation, the path releasing it at every step (the default,
    ReleaseOptions.each_step): every accepted state is an equilibrium of the physics alone,
    k (u^3 - u) = f, within the Newton tolerance, and a stable one: on the left branch
    (u < -1/sqrt 3, the root brentq finds there) while that branch exists (s < s_lim), on the
    right one (u > 1/sqrt 3) after the snap. No state is unstable, as no state is held by the
    stabilisation. rtol 1e-4: a tolerance well above the residual at which this energy's
    round-off (1e-14 of 0.25 mJ, a decrement r^2/2k: r about 7e-8 N against forces of 0.02-0.8 N)
    lets Newton stop short of it (NewtonStatus.CONVERGED_DECREMENT)."""
    k, f_max, ds = 1.0, 0.77, 0.02
    f_lim = 2 * k / (3 * math.sqrt(3))
    s_lim = f_lim / f_max
    X = np.array([[-1.0]])
    stab = ViscousStabilisation(np.array([1.0]), 2.0 * k, 1)
    problem = Problem(X, lambda s: [DoubleWell(k), ScaledTerm(LinearTerm(np.array([[f_max]]), X), s), stab], [],
                      force_scale=f_max)
    res = solve_path(problem, PathOptions(ds0=ds, ds_max=ds, newton=NewtonOptions(rtol=1e-4)))
    assert res.converged, res.message
    assert any(h.release_rounds > 0 for h in res.history)  # the snap's steps needed the release
    states = []
    solve_path(problem, PathOptions(ds0=ds, ds_max=ds, newton=NewtonOptions(rtol=1e-4)),
               callback=lambda s, x, rec: states.append((s, float(x[0, 0]), rec)))
    for s, u, rec in states:
        f = s * f_max
        assert rec.residual <= rec.tolerance and abs(k * (u**3 - u) - f) <= rec.tolerance
        if s < s_lim:
            expected = brentq(lambda v: k * (v**3 - v) - f, -3.0, -1 / math.sqrt(3))
        else:
            expected = brentq(lambda v: k * (v**3 - v) - f, 1 / math.sqrt(3), 3.0)
        # the tolerance over the curvature k (3 u^2 - 1) bounds the distance to the root
        assert abs(u - expected) <= 10 * rec.tolerance / (k * (3 * expected**2 - 1)), (s, u, expected)
        assert rec.negative_eigenvalues == 0


def test_stable_problems_never_report_an_instability():
    """A slender cantilever under a tip load (stable: Euler-Bernoulli's regime) and a freely
    swelling gel disk (stable: the global minimum of the gel's energy; each gel element alone
    is non-convex under lateral constraint, the assembly is not): no negative eigenvalue at any
    accepted state."""
    mesh = rectangle(100.0, 4.0, 2.0, order=2, structured=True)
    mat = NeoHookean(shear_modulus=0.023, poisson_ratio=0.45)
    S = Solid(mesh.points, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), mat, "body")])
    load = surface_load(mesh.points, mesh.facet_groups["right"], [0.0, -1e-4])
    prob = Problem(mesh.points, lambda s: [S, ScaledTerm(load, s)], [fixed(mesh.group_nodes("left"), 2)],
                   force_scale=0.023 * 4.0)
    res = solve_path(prob, PathOptions(ds0=0.5))
    assert res.converged and res.history
    assert all(h.negative_eigenvalues == 0 for h in res.history) and res.unstable_at_s is None

    params = HydrogelParams()
    gel = Hydrogel(params)
    disk = quarter_disk(2.0, 0.5, order=2)
    G = Solid(disk.points, [Block(disk.cells, element_for_meshio_type(disk.cell_type), gel, "body")])
    g = disk.group_nodes

    def terms(s):
        return [G.with_materials({"body": gel.at(params.mu0 * (1 - s), params.T0 + s * (275.0 - params.T0))})]

    prob = Problem(disk.points, terms, [fixed(g("xsym"), 2, [0]), fixed(g("zsym"), 2, [1])],
                   force_scale=gel.shear_modulus_ref * 2.0)
    res = solve_path(prob)
    assert res.converged and res.history
    assert all(h.negative_eigenvalues == 0 for h in res.history) and res.unstable_at_s is None


def test_the_check_can_be_switched_off():
    """stability_check=False: no extra factorisation, every record says None."""
    X = np.array([[-1.0]])
    problem = Problem(X, lambda s: [DoubleWell(1.0), ScaledTerm(LinearTerm(np.array([[0.1]]), X), s)], [])
    res = solve_path(problem, PathOptions(stability_check=False))
    assert res.converged and all(h.negative_eigenvalues is None for h in res.history)
    assert res.unstable_at_s is None




class Piece(EnergyTerm):
    """``-a u^2/2 + c u^4/4`` [mJ] on DOF ``dof`` of x (n, 1) [mm] (u = x[dof]), projected to a
    non-negative curvature alone, as an element Hessian is. A concave piece (a = 1) and a quartic
    one (c = 1) sum to a saddle at u = 0 and stable minima at u = +-1 of curvature 2; there the
    projected Hessian (3, the concave piece dropped) overestimates the true one, and projected
    Newton converges only linearly, at the rate 1/3 per iteration."""

    def __init__(self, name, a=0.0, c=0.0, dof=0):
        self.name, self.a, self.c, self.dof = name, a, c, dof

    def energy(self, x):
        u = float(x.ravel()[self.dof])
        return -0.5 * self.a * u**2 + 0.25 * self.c * u**4

    def gradient(self, x):
        g = np.zeros(x.size)
        u = float(x.ravel()[self.dof])
        g[self.dof] = -self.a * u + self.c * u**3
        return g

    def hessian(self, x, project=False):
        u = float(x.ravel()[self.dof])
        h = -self.a + 3 * self.c * u * u
        H = sp.lil_matrix((x.size, x.size))
        H[self.dof, self.dof] = max(h, 0.0) if project else h
        return H.tocsr()


def test_a_saddle_is_settled_to_the_analytic_minimum_with_a_full_newton_finish():
    """``settle`` from the saddle u = 0 of two :class:`Piece` terms reaches a minimum u = +-1,
    within the residual over the curvature 2, reported stable; its full-Newton finish takes fewer
    iterations than projected Newton from the same nudge (linear at the rate 1/3)."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.newton import minimize
    from hydrojam.fem.solver.stability import settle

    terms = [Piece("concave", a=1.0), Piece("quartic", c=1.0)]
    x = np.array([[0.0], [1.0]])  # DOF 1 held: it gives the bounding box its size, 1 mm
    free = np.array([True, False])
    from hydrojam.fem.solver.path import SETTLE_PERTURBATION

    options = PathOptions()
    out = settle(terms, x, free, 1.0, options.newton, LinearSolver(), LinearSolver(), SETTLE_PERTURBATION)
    assert out.negative == 0
    assert out.residual <= out.tolerance
    assert abs(abs(out.x[0, 0]) - 1.0) <= out.residual / 2.0 * 1.5
    # settle's first nudge: the seeded vector of SETTLE_PERTURBATION x the bounding box diagonal;
    # projected Newton (IPC's: every term's Hessian projected to PSD) from there
    nudge = SETTLE_PERTURBATION * np.random.default_rng(0).standard_normal(x.shape) * free.reshape(x.shape)
    projected = minimize([_Projected(t) for t in terms], x + nudge, free, 1.0,
                         dataclasses.replace(options.newton, max_iter=400), LinearSolver())
    assert projected.converged and abs(abs(projected.x[0, 0]) - 1.0) <= projected.residual / 2.0 * 1.5
    assert out.iterations < projected.iterations


class _Projected(EnergyTerm):
    """Another term with its Hessian always projected to positive semi-definite (IPC's Newton)."""

    def __init__(self, term):
        self.term, self.name = term, term.name

    def energy(self, x):
        return self.term.energy(x)

    def gradient(self, x):
        return self.term.gradient(x)

    def hessian(self, x, project=False):
        return self.term.hessian(x, True)


class Well(EnergyTerm):
    """``k |x - x0|^2 / 2`` [mJ] over the DOFs of ``mask``: a convex well (curvature k)."""

    name = "well"

    def __init__(self, x0, mask, k=1.0):
        self.x0, self.mask, self.k = np.asarray(x0, dtype=float), np.asarray(mask, dtype=float), k

    def energy(self, x):
        return 0.5 * self.k * float(np.sum(self.mask * (x - self.x0) ** 2))

    def gradient(self, x):
        return (self.k * self.mask * (x - self.x0)).ravel()

    def hessian(self, x, project=False):
        return sp.diags(self.k * self.mask.ravel(), format="csr")


def _saddle_in_many_dofs(n=60):
    """DOF 0: the Piece saddle u = 0 (curvature -1; minima u = +-1); DOFs 1 .. n-1: convex wells
    of curvatures 0.5 .. 5 at their minima; the last DOF held."""
    x = np.linspace(0.0, 1.0, n).reshape(-1, 1)
    x[0, 0] = 0.0
    mask = np.ones_like(x)
    mask[0] = 0.0
    k = np.linspace(0.5, 5.0, n).reshape(-1, 1)
    terms = [Piece("concave", a=1.0), Piece("quartic", c=1.0), Well(x.copy(), mask * k)]
    free = np.ones(n, dtype=bool)
    free[-1] = False
    return terms, x, free


def test_the_lowest_mode_of_a_saddle_is_its_unstable_direction():
    """LOBPCG (60 free DOFs, preconditioned by the projected Hessian) finds the eigenvalue -1 of
    the saddle's DOF and its mode, within its residual tolerance over the gap to the next
    eigenvalue (0.5), and scales the mode to a largest nodal move of 1."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.stability import lowest_mode

    terms, x, free = _saddle_in_many_dofs()
    value, mode = lowest_mode(terms, x, free, LinearSolver())
    mean_diag = np.mean(np.r_[1.0, np.linspace(0.5, 5.0, 60)[1:-1]])  # |diag H| over the free DOFs
    r = 1e-5 * mean_diag  # lowest_mode's residual norm bound (_MODE_TOLERANCE x mean|diag H|)
    assert abs(value - (-1.0)) <= r**2 / 1.5 + 1e-9 * mean_diag  # Rayleigh quotient: second order, + the shift
    assert abs(abs(mode[0, 0]) - 1.0) <= r / 1.5 and np.abs(mode[1:]).max() <= r / 1.5
    assert mode[-1, 0] == 0.0


def test_a_saddle_among_many_dofs_is_settled_along_its_mode():
    """From the saddle, ``settle`` moves along the mode and reaches the minimum u = +-1 (within the
    residual over the curvature 2), the wells' DOFs where they were (within the residual over
    their curvature), reported stable."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.stability import settle

    terms, x, free = _saddle_in_many_dofs()
    out = settle(terms, x, free, 1.0, PathOptions().newton, LinearSolver(), LinearSolver())
    assert out.negative == 0 and out.residual <= out.tolerance
    assert abs(abs(out.x[0, 0]) - 1.0) <= out.residual / 2.0 * 1.5
    assert np.abs(out.x[1:] - x[1:]).max() <= out.residual / 0.5 * 1.5


def test_the_lowest_mode_is_found_beside_many_soft_modes():
    """60 soft DOFs (curvature 1e-6, as rattling particles), the rest stiff (5), and DOF 100 unstable:
    a convex well of 2 and a concave piece of 3 (H = -1; projected alone, the concave piece drops
    out, so the preconditioner sees +2 there). LOBPCG must not stop on the soft cluster, whose
    residuals are below its tolerance: it finds -1 at DOF 100 (within the tolerance's square over
    the gap) and the mode points there."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.stability import lowest_mode

    n = 200
    x = np.zeros((n, 1))
    free = np.ones(n, dtype=bool)
    free[-1] = False
    k = np.full((n, 1), 5.0)
    k[:60], k[100] = 1e-6, 2.0
    value, mode = lowest_mode([Well(x.copy(), k), Piece("concave", a=3.0, dof=100)], x, free, LinearSolver())
    diag = k[:-1, 0].copy()  # |diag H| over the free DOFs (DOF 100: |-1|)
    diag[100] = 1.0
    r = 1e-5 * diag.mean()  # lowest_mode's LOBPCG residual bound
    assert abs(value + 1.0) <= r**2 / 1.0 + 1e-9 * diag.mean()  # gap to the next eigenvalue (1e-6): 1
    assert int(np.argmax(np.abs(mode))) == 100 and abs(mode[100, 0]) == 1.0
