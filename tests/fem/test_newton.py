"""Pieces of the Newton solver (hydrojam.fem.solver.newton) checked on their own."""

import numpy as np
import pytest
import scipy.sparse as sp

from hydrojam.fem.solver.linsolve import _pardiso_available
from hydrojam.fem.solver.total import sum_hessians as _sum_hessians
from hydrojam.fem.terms import EnergyTerm


def _random(n, density, seed, zeros=0):
    A = sp.random(n, n, density=density, random_state=np.random.default_rng(seed), format="csr")
    A = (A + A.T).tocsr()
    if zeros:  # stored entries whose value is exactly 0 (SciPy's addition drops them)
        A.data[:zeros] = 0.0
    return A


@pytest.mark.parametrize("count", [1, 2, 3, 4])
def test_the_hessian_sum_has_the_values_and_entries_of_pythons_sum(count):
    """With a stiffness that stores exact zeros, a contact-like coupling, a stabilisation at scale
    0 (a zero diagonal) and one at a positive scale: the same values to the bit and the same
    stored entries as sum(), which the linear solver's pattern (hence its round-off) follows."""
    n = 60
    mats = [_random(n, 0.1, 1, zeros=5), _random(n, 0.02, 2), sp.diags(np.zeros(n), format="csr"),
            sp.diags(np.linspace(0.5, 1.0, n), format="csr")][:count]
    got, ref = _sum_hessians(mats), sum(mats)
    assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
    assert np.array_equal(got.data, ref.data)
    assert got is not mats[0]


@pytest.mark.parametrize("sort", [True, False])
def test_the_free_block_is_scipys_fancy_index(sort):
    """The free DOFs' block of a matrix with stored zeros: the same entries, in the same order,
    with the same values as SciPy's H[fidx][:, fidx] (rows with unsorted indices take SciPy's
    route)."""
    from hydrojam.fem.solver.total import free_block as _free_block

    H = _random(80, 0.1, 3, zeros=7)
    if not sort:  # every row's entries reversed: unsorted rows
        order = np.concatenate([np.arange(a, b)[::-1] for a, b in zip(H.indptr[:-1], H.indptr[1:])])
        H = sp.csr_matrix((H.data[order], H.indices[order], H.indptr), shape=H.shape)
        assert not H.has_sorted_indices
    fidx = np.flatnonzero(np.random.default_rng(4).random(80) < 0.7)
    got, ref = _free_block(H, fidx), H[fidx][:, fidx]
    assert got.shape == ref.shape
    assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
    assert np.array_equal(got.data, ref.data)


@pytest.mark.parametrize("count", [1, 2, 3, 4])
def test_the_free_block_of_the_sum_is_the_block_of_scipys_sum(count):
    """The compiled sum-and-block: with stored zeros, entries that cancel to exactly 0 (SciPy's
    addition drops them), a stabilisation at scale 0 and one at a positive scale, the same
    entries, in the same order, with the same values as the block of the summed Hessians; and
    the same where a matrix is not canonical (SciPy's route)."""
    from hydrojam.fem.solver.total import free_block as _free_block, free_sum as _free_sum

    n = 80
    stiff, coupling = _random(n, 0.1, 5, zeros=6), _random(n, 0.03, 6)
    cancel = sp.csr_matrix(stiff.multiply(sp.random(n, n, density=0.3, random_state=np.random.default_rng(7)) > 0))
    coupling = (coupling - cancel - cancel.T).tocsr()  # cancels some of stiff's entries exactly
    mats = [stiff, coupling, sp.diags(np.zeros(n), format="csr"), sp.diags(np.linspace(0.5, 1.0, n), format="csr")]
    fidx = np.flatnonzero(np.random.default_rng(8).random(n) < 0.7)
    unsorted = sp.csr_matrix((stiff.data[::-1], stiff.indices[::-1], stiff.indptr), shape=stiff.shape)
    for ms in (mats[:count], [unsorted, *mats[1:count]]):
        ref = _free_block(_sum_hessians(ms), fidx)
        got = _free_sum(ms, fidx)
        assert got.shape == ref.shape
        assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
        assert np.array_equal(got.data, ref.data)
    assert count < 2 or (stiff + coupling).nnz < stiff.nnz + coupling.nnz - 10  # entries did cancel


class _Quadratic(EnergyTerm):
    """``C + g0 . (x - x0) + |x - x0|^2 / 2`` [mJ] on every DOF of x (n, 1): gradient g0 at x0,
    Hessian I. ``finite_only_at_start``: the energy is infinite everywhere but at x0 (every move
    inadmissible). ``flux``: the forces in play reported for the tolerance [N] (rtol x flux)."""

    name = "quadratic"

    def __init__(self, x0, g0, C=0.0, flux=None, finite_only_at_start=False, hessian_scale=1.0):
        self.x0, self.g0, self.C, self.flux = np.asarray(x0, float).ravel(), np.asarray(g0, float), C, flux
        self.only_start, self.h = finite_only_at_start, hessian_scale

    def energy(self, x):
        u = x.ravel() - self.x0
        if self.only_start and np.any(u != 0):
            return np.inf
        return self.C + float(self.g0 @ u) + 0.5 * self.h * float(u @ u)

    def gradient(self, x):
        return self.g0 + self.h * (x.ravel() - self.x0)

    def hessian(self, x, project=False):
        return sp.diags(np.full(x.size, self.h), format="csr")

    def force_flux(self, x, gradient=None):
        return self.gradient(x) if self.flux is None else np.full(x.size, self.flux)


def _minimise(term, n=3):
    from hydrojam.fem.solver.newton import minimize

    return minimize([term], np.zeros((n, 1)), np.ones(n, dtype=bool), 1.0)


def test_each_newton_status_is_reached_on_a_small_problem():
    """Every way a minimisation can end, on a quadratic whose tolerance is set by its reported
    forces in play (flux 1e6 N: tol = rtol x |flux| ~ 1.7 N over three DOFs):

    - converged: a plain quadratic from 5 N away;
    - converged at the decrement's round-off: the same 5 N residual (within stall_factor of the
      tolerance) on an energy of 1e20 mJ, whose decrease 37.5 mJ is below 1e-14 of it;
    - converged with no descent left: within stall_factor, every move inadmissible;
    - line search failed: the same far from the tolerance (5000 N);
    - singular: a linear energy (zero Hessian), no damped solve gives a direction;
    - not finite: a NaN force;
    - inadmissible start: infinite energy at x0."""
    from hydrojam.fem.solver.newton import NewtonStatus

    g5, g5000 = np.full(3, 5.0), np.full(3, 5000.0)
    assert _minimise(_Quadratic(np.zeros(3), g5, flux=1e6)).status is NewtonStatus.CONVERGED
    assert _minimise(_Quadratic(np.zeros(3), g5, C=1e20, flux=1e6)).status is NewtonStatus.CONVERGED_DECREMENT
    out = _minimise(_Quadratic(np.zeros(3), g5, flux=1e6, finite_only_at_start=True))
    assert out.status is NewtonStatus.CONVERGED_NO_DESCENT and out.converged
    out = _minimise(_Quadratic(np.zeros(3), g5000, flux=1e6, finite_only_at_start=True))
    assert out.status is NewtonStatus.LINE_SEARCH_FAILED and not out.converged
    assert np.array_equal(out.x, np.zeros((3, 1)))  # the last admissible state is kept
    assert _minimise(_Quadratic(np.zeros(3), g5, hessian_scale=0.0)).status is NewtonStatus.SINGULAR
    nan_force = _Quadratic(np.zeros(3), g5)
    nan_force.gradient = lambda x: np.full(x.size, np.nan)
    assert _minimise(nan_force).status is NewtonStatus.NOT_FINITE
    assert _minimise(_Quadratic(np.ones(3), g5, finite_only_at_start=True)).status is NewtonStatus.INADMISSIBLE_START


def test_the_line_search_backtracks_to_the_first_sufficient_decrease():
    """On E = u^2/2 from u = 1 along the overshooting step -4 (slope -4): alpha 1 (u = -3) and
    1/2 (u = -1, no decrease) are rejected, 1/4 lands on the minimum; from a cap of 0.3 the
    first trial is the cap, and 0.3 (u = -0.2) is accepted."""
    from hydrojam.fem.solver.newton import NewtonOptions, _line_search

    term = _Quadratic(np.zeros(1), np.zeros(1))
    x, step = np.ones(1), np.array([-4.0])
    alpha, xn, En, trials = _line_search([term], x, 0.5, step, -4.0, (1, 1), 1.0, NewtonOptions())
    assert alpha == 0.25 and xn[0] == 0.0 and En == 0.0 and trials == 3
    alpha, xn, _, trials = _line_search([term], x, 0.5, step, -4.0, (1, 1), 0.3, NewtonOptions())
    assert trials == 1
    # 1 + 0.3 x (-4): two rounded operations on numbers of order 1
    assert alpha == 0.3 and xn[0] == pytest.approx(-0.2, abs=4 * np.finfo(float).eps)


class _Cusp(EnergyTerm):
    """E = C + (2/3) |u|^(3/2) [mJ], u = x - x_star on one DOF: convex, with gradient sign(u)
    sqrt|u| and Hessian 1 / (2 sqrt|u|), so the Newton step from any u lands on -u, at the same
    energy and the same residual. C stands for the large, cancelling energy of a swollen gel,
    whose round-off slack (``energy_slack`` x |E|) then exceeds every energy change near the
    minimum. Forces in play 1 N: tol = rtol x 1 N."""

    name = "cusp"

    def __init__(self, x_star, C):
        self.x_star, self.C = x_star, C

    def energy(self, x):
        return self.C + 2.0 / 3.0 * abs(x[0, 0] - self.x_star) ** 1.5

    def gradient(self, x):
        u = x[0, 0] - self.x_star
        return np.array([np.sign(u) * np.sqrt(abs(u))])

    def hessian(self, x, project=False):
        return sp.csr_matrix([[0.5 / np.sqrt(abs(x[0, 0] - self.x_star))]])

    def force_flux(self, x, gradient=None):
        return np.ones(1)


@pytest.mark.parametrize("C", [1.0, 10.0])
def test_a_step_the_energy_cannot_judge_must_lower_the_residual(C):
    """On the cusp from u = 1e-8 (residual 1e-4 N, within stall_factor of the 1e-6 N tolerance)
    the Newton step lands on -u: the decrease Armijo asks of it (2e-16 mJ) is below the energy's
    slack (1e-12 C) and its round-off, while the Newton decrement (2e-12 mJ) stays above its
    round-off exit (1e-14 C). Without ``residual_search`` Newton bounces between u and -u until it
    runs out of iterations; with it the bounce is refused (the residual does not fall), the half
    step lands on the minimum, and the minimisation converges within the tolerance in a few
    iterations (|u| <= tol^2, since the residual is sqrt|u|)."""
    from hydrojam.fem.solver.newton import NewtonOptions, NewtonStatus, minimize

    x_star = 1.0
    x0 = np.array([[x_star + 1e-8]])
    free = np.ones(1, dtype=bool)
    bounced = minimize([_Cusp(x_star, C)], x0, free, 1.0, NewtonOptions(linear_solver="scipy"))
    assert bounced.status is NewtonStatus.MAX_ITERATIONS
    out = minimize([_Cusp(x_star, C)], x0, free, 1.0, NewtonOptions(linear_solver="scipy", residual_search=True))
    tol = NewtonOptions().rtol * 1.0
    assert out.status is NewtonStatus.CONVERGED and out.iterations <= 3
    assert out.residual <= tol and abs(out.x[0, 0] - x_star) <= tol**2


def test_the_marquardt_damping_grows_on_short_steps_and_decays_on_full_ones():
    """From 0, a short step (< 0.1) starts the damping at MARQUARDT_MIN, each further one grows it
    10x up to MARQUARDT_MAX; a middling step keeps it; a full step divides it by 10, and one at or
    below the cutoff drops it to 0."""
    from hydrojam.fem.solver.newton import MARQUARDT_CUTOFF, MARQUARDT_MAX, MARQUARDT_MIN, _marquardt_update

    lm = _marquardt_update(0.0, 0.05)
    assert lm == MARQUARDT_MIN
    assert _marquardt_update(lm, 0.05) == pytest.approx(10 * MARQUARDT_MIN)
    assert _marquardt_update(MARQUARDT_MAX, 0.01) == MARQUARDT_MAX
    assert _marquardt_update(1e-3, 0.5) == 1e-3
    assert _marquardt_update(1e-3, 1.0) == pytest.approx(1e-4)
    assert _marquardt_update(MARQUARDT_CUTOFF, 1.0) == 0.0


class _SaddleValley(EnergyTerm):
    """E = a^4 / 4 + (u^4 / 4 - u^2 / 2) + k v^2 / 2 [mJ] on x = (a, y, z), u = (y + z) / sqrt 2,
    v = (y - z) / sqrt 2: a slow quartic in a beside a double well in u, whose saddle is at u = 0
    and minima at u = +-1, its negative mode spread over two DOFs (so no diagonal entry of the
    Hessian is its eigenvalue)."""

    name = "saddle_valley"
    k = 10.0
    R = np.array([[1.0, 1.0], [1.0, -1.0]]) / np.sqrt(2.0)  # (y, z) -> (u, v), its own inverse

    def energy(self, x):
        a, (u, v) = x[0, 0], self.R @ x[1:, 0]
        return a**4 / 4 + u**4 / 4 - u**2 / 2 + self.k * v**2 / 2

    def gradient(self, x):
        a, (u, v) = x[0, 0], self.R @ x[1:, 0]
        return np.concatenate([[a**3], self.R @ [u**3 - u, self.k * v]])

    def hessian(self, x, project=False):
        a, (u, _) = x[0, 0], self.R @ x[1:, 0]
        H = np.zeros((3, 3))
        H[0, 0] = 3 * a**2
        H[1:, 1:] = self.R @ np.diag([3 * u**2 - 1, self.k]) @ self.R
        return sp.csr_matrix(H)

    def force_flux(self, x, gradient=None):
        return np.ones(x.size)  # tol = rtol x sqrt(3) N


@pytest.mark.skipif(not _pardiso_available(), reason="the inertia comes from PARDISO")
def test_the_inertia_correction_heads_for_the_minimum_where_newton_reaches_the_saddle():
    """From a = 1, u = 0.1 (negative curvature along u), plain Newton's step descends overall
    (the quartic's decrease outweighs its climb along u) and converges quadratically in u onto
    the saddle u = 0 while a converges linearly: an equilibrium with the Hessian's eigenvalue -1.
    With ``definite``, every step is taken on a positive definite K, so the energy falls along u
    too and Newton ends in the minimum u = 1 (u'' = 2 > 0). Both within the residual tolerance:
    |u - u*| <= tol / curvature, checked at ten times that."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.newton import NewtonOptions, minimize

    x0 = np.array([[1.0], [0.1 / np.sqrt(2)], [0.1 / np.sqrt(2)]])
    term = _SaddleValley()
    tol = 1e-6 * np.sqrt(3)
    out = {}
    for definite in (False, True):
        res = minimize([term], x0, np.ones(3, dtype=bool), 1.0, NewtonOptions(max_iter=100, definite=definite),
                       LinearSolver("pardiso"))
        assert res.converged, res.message
        out[definite] = res
    u_plain = (term.R @ out[False].x[1:, 0])[0]
    u_definite = (term.R @ out[True].x[1:, 0])[0]
    assert abs(u_plain) <= 10 * tol / 1.0  # the saddle, curvature -1 there
    assert np.linalg.eigvalsh(term.hessian(out[False].x).toarray()).min() < -0.9
    assert abs(u_definite - 1.0) <= 10 * tol / 2.0  # the minimum, curvature 2 there
    assert np.linalg.eigvalsh(term.hessian(out[True].x).toarray())[1:].min() > 1.9  # a: quartic, ~0 at 0


def _spd(n, seed):
    """A sparse symmetric positive definite matrix: a graph Laplacian plus I (eigenvalues >= 1)."""
    A = abs(_random(n, 0.05, seed))
    L = sp.diags(np.asarray(A.sum(axis=1)).ravel()) - A
    return (L + sp.identity(n)).tocsr()


@pytest.mark.parametrize("method", ["scipy", "pardiso"])
def test_conjugate_gradients_solve_the_full_system_preconditioned_by_a_nearby_one(method):
    """K = M + c w w^T (c > 0) preconditioned by M's factorisation: M^-1 K is the identity but for
    one eigenvalue, so the conjugate gradients reach ||K x + g|| <= linear_residual ||g|| within
    a few iterations and x is K^-1 (-g) to that accuracy (x's error <= residual / lambda_min(K),
    and lambda_min(K) >= lambda_min(M) >= 1)."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.newton import NewtonOptions, _conjugate_gradients

    if method == "pardiso" and not _pardiso_available():
        pytest.skip("PARDISO is not available")
    n = 80
    M = _spd(n, 3)
    rng = np.random.default_rng(4)
    w, g = rng.standard_normal(n), rng.standard_normal(n)
    K = (M + 5.0 * sp.csr_matrix(np.outer(w, w))).tocsr()
    solver = LinearSolver(method)
    solver.solve(M, -g)
    options = NewtonOptions()
    r = float(np.linalg.norm(g))
    x, negative = _conjugate_gradients(K, g, r, solver, 20, options)
    assert x is not None and negative is None
    assert np.linalg.norm(K @ x + g) <= options.linear_residual * r
    exact = np.linalg.solve(K.toarray(), -g)
    assert np.linalg.norm(x - exact) <= options.linear_residual * r / 1.0
    assert g @ x < 0


@pytest.mark.parametrize("method", ["scipy", "pardiso"])
def test_an_undamped_step_solves_the_hessian_without_the_regularisation(method):
    """H with two eigenvalues (1e-3 and 1e-2) below the shift eps = 0.05 that the factorisation
    carries, the rest in [1, 10]: the regularised solution is short in those modes by
    eps/(lambda + eps) (0.98, 0.83), and the conjugate gradients preconditioned by that
    factorisation ((H + eps I)^-1 H has its spectrum in [0.95, 1] but for those two modes) reach
    H^-1 (-g) to linear_residual x ||g|| within the allowed steps (x's error <= residual / 1e-3).
    Where H is singular and g has a component in its null space, no step solves H: the
    regularised one is kept."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.newton import NewtonOptions, _unshifted

    if method == "pardiso" and not _pardiso_available():
        pytest.skip("PARDISO is not available")
    n = 60
    rng = np.random.default_rng(7)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    lam = np.concatenate([[1e-3, 1e-2], np.linspace(1.0, 10.0, n - 2)])
    H = sp.csr_matrix((Q * lam) @ Q.T)
    g = rng.standard_normal(n)
    options = NewtonOptions()
    r = float(np.linalg.norm(g))
    solver = LinearSolver(method)
    shift = 0.05 * sp.identity(n, format="csr")
    shifted = solver.solve(H + shift, -g)
    dx = _unshifted(H, shifted, g, r, solver, options)
    exact = np.linalg.solve(H.toarray(), -g)
    assert np.linalg.norm(shifted - exact) > 0.5 * np.linalg.norm(exact)
    assert np.linalg.norm(H @ dx + g) <= options.linear_residual * r
    assert np.linalg.norm(dx - exact) <= options.linear_residual * r / 1e-3
    lam[0] = 0.0  # a rigid mode, and a force along it that no step can balance
    H = sp.csr_matrix((Q * lam) @ Q.T)
    solver.solve(H + shift, -g)
    assert _unshifted(H, shifted, g, r, solver, options) is shifted


def test_conjugate_gradients_refuse_a_system_with_negative_curvature():
    """K = M - c w w^T with c w^T M^-1 w > 1 has one negative eigenvalue, and the preconditioned
    Krylov space holds it after two iterations: K's restriction to the conjugate directions is
    diagonal, so by Sylvester's law one of their curvatures p.K.p is negative, and the conjugate
    gradients return no step, and the direction of that curvature, instead of the saddle's
    Newton step."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.newton import NewtonOptions, _conjugate_gradients

    n = 80
    M = _spd(n, 5)
    rng = np.random.default_rng(6)
    w, g = rng.standard_normal(n), rng.standard_normal(n)
    c = 2.0 / float(w @ np.linalg.solve(M.toarray(), w))
    K = (M - c * sp.csr_matrix(np.outer(w, w))).tocsr()
    assert np.linalg.eigvalsh(K.toarray()).min() < 0
    solver = LinearSolver("scipy")
    solver.solve(M, -g)
    options = NewtonOptions()
    x, p = _conjugate_gradients(K, g, float(np.linalg.norm(g)), solver, options.detect_iterations, options)
    assert x is None and p is not None
    assert float(p @ (K @ p)) <= 0


class _SymmetricQuadratic(EnergyTerm):
    """E = x.A x / 2 [mJ] over the flat x for a fixed symmetric A; with ``fallback_projection`` its
    projected Hessian is ``projected``."""

    name = "quadratic"

    def __init__(self, A, projected=None):
        self.A, self.projected = sp.csr_matrix(A), projected
        self.fallback_projection = projected is not None

    def energy(self, x):
        return 0.5 * float(x.ravel() @ (self.A @ x.ravel()))

    def gradient(self, x):
        return (self.A @ x.ravel()).reshape(x.shape)

    def hessian(self, x, project=False):
        return sp.csr_matrix(self.projected) if project and self.projected is not None else self.A


@pytest.mark.skipif(not _pardiso_available(), reason="the inertia comes from PARDISO")
@pytest.mark.parametrize("cholesky", [False, True])
@pytest.mark.parametrize("full_first", [False, True])
@pytest.mark.parametrize("c", [0.5, 4.0])
def test_krylov_detect_takes_the_full_step_where_its_conjugate_gradients_meet_no_negative_curvature(
        c, full_first, cholesky, monkeypatch):
    """An SPD A beside a term -c W W^T (W: three orthonormal columns) whose projection is 0: the
    projected K = A preconditions conjugate gradients on the full K = A - c W W^T, whose
    preconditioned operator has four distinct eigenvalues, so a single iteration converges on
    neither. With lambda_min(A) = 1, c = 0.5 leaves K definite: "krylov_detect" factorises it after
    one step that met no negative curvature and takes its exact solution (within linear_residual
    of ||g|| over lambda_min(K) >= 0.5). c = 4 makes K indefinite: the step is the projected K's.
    ``full_first`` (the last iteration took the full step) gives the same directions, the definite
    one by one factorisation and no conjugate gradient. With ``cholesky`` the definite solves are
    single-precision Cholesky factorisations (a dense pattern: 3D), which refuse an indefinite K;
    without, LDL^T factorisations in double (2D), whose inertia shows it."""
    from hydrojam.fem.solver.linsolve import LinearSolver, _Pardiso
    from hydrojam.fem.solver.newton import NewtonOptions, _direction
    from hydrojam.fem.solver.total import free_block as _free_block, sum_hessians as _sum_hessians

    monkeypatch.setattr(_Pardiso, "dense_row", 0.5 if cholesky else 1e9)

    n = 60
    rng = np.random.default_rng(8)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    A = (Q * np.linspace(1.0, 10.0, n)) @ Q.T
    W, _ = np.linalg.qr(rng.standard_normal((n, 3)))
    B = -c * (W * [1.0, 0.7, 0.4]) @ W.T
    terms = [_SymmetricQuadratic(A), _SymmetricQuadratic(B, projected=np.zeros((n, n)))]
    xs = rng.standard_normal((n, 1))
    fidx = np.arange(n)
    hessians = [t.hessian(xs) for t in terms]
    Hff = _free_block(_sum_hessians(hessians), fidx)
    g = sum(t.gradient(xs) for t in terms).ravel()
    r = float(np.linalg.norm(g))
    options = NewtonOptions(definite=True, fallback_start="krylov_detect", detect_iterations=1, regularisation=0.0)
    solver = LinearSolver("pardiso")
    resolves = []
    resolve = solver.resolve
    solver.resolve = lambda b, **kw: resolves.append(1) or resolve(b, **kw)
    dx, slope, tau, projected, _ = _direction(terms, xs, hessians, Hff, abs(Hff.diagonal()), g, r, 0.0, fidx,
                                              solver, options, full_first=full_first)
    full_definite = np.linalg.eigvalsh(A + B).min() > 0
    if full_first and full_definite:
        assert (solver.calls, len(resolves)) == (1, 0)
    assert full_definite == (c < 1)
    expected = np.linalg.solve(A + B if full_definite else A, -g)
    assert projected is not full_definite
    assert np.linalg.norm(dx - expected) <= options.linear_residual * r / 0.5
    assert slope < 0


class _ProjectableSaddleValley(_SaddleValley):
    """The saddle valley as a term with ``fallback_projection`` (as contact is): its projected
    Hessian has the negative eigenvalues clipped to 0."""

    fallback_projection = True

    def hessian(self, x, project=False):
        H = super().hessian(x).toarray()
        if project:
            w, V = np.linalg.eigh(H)
            H = (V * np.maximum(w, 0.0)) @ V.T
        return sp.csr_matrix(H)


@pytest.mark.skipif(not _pardiso_available(), reason="the inertia comes from PARDISO")
@pytest.mark.parametrize("cholesky", [False, True])
@pytest.mark.parametrize("start", ["full", "krylov_detect"])
def test_every_fallback_start_heads_for_the_minimum(start, cholesky, monkeypatch):
    """With the inertia correction, wherever the projectable term starts (its full Hessian, or the
    conjugate gradients on the full Hessian preconditioned by the projected one that detect its
    negative curvature), Newton ends in the minimum u = 1, not on the saddle
    u = 0 that plain Newton reaches from there (the test above); within ten times the residual
    tolerance over the curvature there. With ``cholesky`` the pattern counts as dense (3D), so
    the definite solves are Cholesky factorisations, which refuse an indefinite K."""
    from hydrojam.fem.solver.linsolve import LinearSolver, _Pardiso
    from hydrojam.fem.solver.newton import NewtonOptions, minimize

    if cholesky:
        monkeypatch.setattr(_Pardiso, "dense_row", 0.5)
    x0 = np.array([[1.0], [0.1 / np.sqrt(2)], [0.1 / np.sqrt(2)]])
    term = _ProjectableSaddleValley()
    res = minimize([term], x0, np.ones(3, dtype=bool), 1.0,
                   NewtonOptions(max_iter=100, definite=True, fallback_start=start), LinearSolver("pardiso"))
    assert res.converged, res.message
    assert abs((term.R @ res.x[1:, 0])[0] - 1.0) <= 10 * 1e-6 * np.sqrt(3) / 2.0


def test_an_unknown_fallback_start_is_refused():
    from hydrojam.fem.solver.newton import NewtonOptions, minimize

    with pytest.raises(ValueError, match="fallback_start"):
        minimize([_SaddleValley()], np.zeros((3, 1)), np.ones(3, dtype=bool), 1.0,
                 NewtonOptions(fallback_start="sometimes"))


def _blas_threads():
    """The thread counts of the BLAS libraries numpy and SciPy loaded (threadpoolctl's view)."""
    from threadpoolctl import threadpool_info

    return [i["num_threads"] for i in threadpool_info() if i["internal_api"] in ("openblas", "blis", "flexiblas")]


class _ThreadRecorder(_Quadratic):
    """A quadratic that records the BLAS thread counts whenever its gradient is asked."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.seen = []

    def gradient(self, x):
        self.seen.append(_blas_threads())
        return super().gradient(x)


@pytest.mark.parametrize("setting, expected", [(None, 1), ("2", 2)])
def test_blas_runs_on_the_set_threads_inside_a_minimisation_and_as_before_after(monkeypatch, setting, expected):
    """numpy's and SciPy's BLAS run on HYDROJAM_BLAS_THREADS threads (default 1) while Newton
    minimises (docs/solver.md, "3D: ordering, threads": OpenBLAS's own threads beside another busy process
    slowed two 3D runs at once 1.8x), and the process's own setting is back afterwards."""
    from threadpoolctl import threadpool_limits

    if not _blas_threads():
        pytest.skip("no OpenBLAS, BLIS or FlexiBLAS loaded")
    if setting is None:
        monkeypatch.delenv("HYDROJAM_BLAS_THREADS", raising=False)
    else:
        monkeypatch.setenv("HYDROJAM_BLAS_THREADS", setting)
    with threadpool_limits(limits=3, user_api="blas"):
        term = _ThreadRecorder(np.zeros(3), np.full(3, 5.0))
        assert _minimise(term).converged
        after = _blas_threads()
    assert term.seen and all(t == expected for seen in term.seen for t in seen), term.seen
    assert all(t == 3 for t in after), after


@pytest.mark.parametrize("value", ["abc", "0", "-1", ""])
def test_invalid_blas_thread_counts_are_refused_by_name(monkeypatch, value):
    monkeypatch.setenv("HYDROJAM_BLAS_THREADS", value)
    with pytest.raises(ValueError, match="HYDROJAM_BLAS_THREADS must be a positive integer"):
        _minimise(_Quadratic(np.zeros(3), np.full(3, 5.0)))


class _Spring(EnergyTerm):
    """E = |x|^2 / 2 [mJ]: unit stiffness on every DOF."""

    name = "spring"

    def energy(self, x):
        return 0.5 * float(x.ravel() @ x.ravel())

    def gradient(self, x):
        return x.ravel().copy()

    def hessian(self, x, project=False):
        return sp.identity(x.size, format="csr")

    def force_flux(self, x, gradient=None):
        return np.ones(x.size)


class _Softening(EnergyTerm):
    """E = -c u^2 / 2 + u^4 / 4 [mJ] on the first DOF u, with ``fallback_projection`` (as contact
    is): its projected Hessian clips -c + 3 u^2 at 0. Beside :class:`_Spring` (c = 2) the total
    along u is -u^2 / 2 + u^4 / 4: a hump at u = 0, minima at u = +-1. Newton's step on the
    projected K (curvature 1 along u) takes u to u + u - u^3, about doubling it, while the full
    K's curvature there is -1 + 3 u^2 < 0. An optional wall: energy inf beyond u = ``wall``,
    whose ``max_step`` is the exact fraction of a step that reaches it."""

    name = "softening"
    fallback_projection = True
    c = 2.0

    def __init__(self, wall=np.inf):
        self.wall = wall

    def energy(self, x):
        u = x.ravel()[0]
        return np.inf if u > self.wall else -self.c * u**2 / 2 + u**4 / 4

    def gradient(self, x):
        g = np.zeros(x.size)
        g[0] = -self.c * x.ravel()[0] + x.ravel()[0] ** 3
        return g

    def hessian(self, x, project=False):
        h = -self.c + 3 * x.ravel()[0] ** 2
        H = np.zeros((x.size, x.size))
        H[0, 0] = max(h, 0.0) if project else h
        return sp.csr_matrix(H)

    def max_step(self, x, dx):
        u, du = x.ravel()[0], dx.ravel()[0]
        return 1.0 if du <= 0 or u + du <= self.wall else (self.wall - u) / du

    def force_flux(self, x, gradient=None):
        return np.ones(x.size)


@pytest.mark.skipif(not _pardiso_available(), reason="the inertia comes from PARDISO")
def test_the_curvature_step_travels_the_negative_curvature_that_the_projection_hides():
    """From u = 1e-3 on the hump of spring + softening, "krylov_detect" meets the full K's negative
    curvature and steps on the projected K, which about doubles u an iteration: at least
    log2(0.5 / 1e-3) ~ 9 iterations before u nears the minimum. With ``curvature_step`` each
    iteration goes on along the negative-curvature direction, doubling while the energy falls,
    so it gets there in fewer than half as many. Both end in the minimum u = 1, v = 0, within ten
    times the residual tolerance over the curvature there (2)."""
    from hydrojam.fem.solver.linsolve import LinearSolver
    from hydrojam.fem.solver.newton import NewtonOptions, minimize

    x0 = np.array([[1e-3], [0.3]])
    runs = {}
    for step in (0.0, 1.0):
        options = NewtonOptions(max_iter=100, definite=True, fallback_start="krylov_detect", curvature_step=step)
        res = minimize([_Spring(), _Softening()], x0, np.ones(2, dtype=bool), 1.0, options, LinearSolver("pardiso"))
        assert res.converged, res.message
        assert abs(res.x[0, 0] - 1.0) <= 10 * 1e-6 * np.sqrt(2) / 2.0 and abs(res.x[1, 0]) <= 10 * 1e-6 * np.sqrt(2)
        runs[step] = res.iterations
    assert runs[0.0] >= 9
    assert runs[1.0] < runs[0.0] / 2


def test_the_curvature_step_doubles_while_the_energy_falls_and_stays_within_the_cap():
    """From u = 0.1 after an accepted step of 0.05 along u: trials at 1, 2, 4, 8 times 0.05, where
    -u^2 / 2 + u^4 / 4 falls all the way to u = 0.5 (no wall) and, with a wall at u = 0.25 that
    caps the longest trial at 0.15 / 0.4 of it, the last trial within the cap is u = 0.2. The sign
    descends whichever way p points."""
    from hydrojam.fem.solver.newton import NewtonOptions, _curvature_step

    x = np.array([0.1, 0.0])
    g = np.array([-0.1 + 0.1**3])  # the free gradient at the iterate, u only (v fixed)
    options = NewtonOptions(curvature_step=1.0, curvature_doublings=3)
    for wall, expected in ((np.inf, 0.5), (0.25, 0.2)):
        for sign in (1.0, -1.0):
            terms = [_Spring(), _Softening(wall)]
            E0 = sum(t.energy(x.reshape(2, 1)) for t in terms)
            xn, En = _curvature_step(terms, x, E0, np.array([sign * 3.0]), g, np.array([0]), np.array([0.05, 0.0]),
                                     (2, 1), options)
            assert xn[0] == pytest.approx(expected, abs=1e-12) and xn[1] == 0.0
            assert En == pytest.approx(-expected**2 / 2 + expected**4 / 4, rel=1e-12) and En < E0
