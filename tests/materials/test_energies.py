"""Verification of the hyperelastic materials (docs/model.md).

Every test compares the implementation with something computed independently of it: finite
differences of its own energy, analytic closed forms coded here from docs/model.md, linear elasticity,
or exact invariance properties (objectivity, plane strain).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pydantic import ValidationError

from hydrojam import Hydrogel, HydrogelParams, NeoHookean, Yeoh
from hydrojam.materials.energies import Material

PARAMS = HydrogelParams()
KT_OVER_NU = 40.0  # MPa, docs/decisions.md, "Units" (typed here, not imported)
A0, B0, A1, B1 = -12.947, 0.04496, 17.92, -0.0569  # docs/model.md, "Hydrogel"


def _gel(mu=None, T=None):
    return Hydrogel(PARAMS, mu, T)


# name -> factory (factories so that mu0 is derived lazily and each test gets a fresh object)
MATERIALS = {
    "neohookean": lambda: NeoHookean(),
    "neohookean_stiff": lambda: NeoHookean(shear_modulus=1.3, poisson_ratio=0.3),
    "yeoh": lambda: Yeoh(c10=0.0115, c20=0.002, c30=0.0004, poisson_ratio=0.45),
    "gel_ref": lambda: _gel(),  # (mu0, T0): the as-prepared state is stress-free
    "gel_cold": lambda: _gel(0.0, 275.0),  # swollen branch
    "gel_warm": lambda: _gel(0.0, 310.0),  # collapsed branch
}
GELS = ("gel_ref", "gel_cold", "gel_warm")


def _random_F(rng, d, n, noise, min_det=0.5):
    """n random gradients I + noise * N(0, 1) with det F > min_det (so gels stay admissible)."""
    out = []
    while len(out) < n:
        F = np.eye(d) + noise * rng.standard_normal((d, d))
        if np.linalg.det(F) > min_det:
            out.append(F)
    return np.array(out)


def _random_rotation(rng, d):
    Q, R = np.linalg.qr(rng.standard_normal((d, d)))
    Q = Q * np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1.0
    return Q


def _embed(F2):
    """Plane strain: F_3D = diag(F_2D, 1)."""
    F3 = np.zeros(F2.shape[:-2] + (3, 3))
    F3[..., :2, :2] = F2
    F3[..., 2, 2] = 1.0
    return F3


def _fd_derivative(fun, F, h):
    """Fourth-order central differences of fun (values of shape (b,) + S) w.r.t. every F_kL.

    Returns shape (b,) + S + (d, d). Stencil (-f(+2h) + 8 f(+h) - 8 f(-h) + f(-2h)) / (12 h):
    truncation O(h^4), so h can be large enough to keep round-off far below the tolerance.
    """
    d = F.shape[-1]
    cols = []
    for k in range(d):
        for L in range(d):
            E = np.zeros((d, d))
            E[k, L] = h

            def f(s):
                return np.asarray(fun(F + s * E))

            cols.append((-f(2) + 8 * f(1) - 8 * f(-1) + f(-2)) / (12 * h))
    D = np.stack(cols, axis=-1)
    return D.reshape(D.shape[:-1] + (d, d))


def _rel_err(approx, exact):
    """Per-sample relative error ||approx - exact|| / ||exact|| (Frobenius over trailing axes)."""
    b = exact.shape[0]
    num = np.linalg.norm((approx - exact).reshape(b, -1), axis=1)
    den = np.linalg.norm(exact.reshape(b, -1), axis=1)
    return num / den


# --------------------------------------------------------------------------------------------
# 1. Derivatives against finite differences


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("noise", [1e-3, 0.3], ids=["near_I", "far_from_I"])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_stress_and_tangent_match_finite_differences(name, noise, d):
    """P against central differences of W, A against central differences of P (relative to |P|, |A|)."""
    mat = MATERIALS[name]()
    rng = np.random.default_rng([list(MATERIALS).index(name), int(noise * 1e4), d])
    F = _random_F(rng, d, 6, noise)
    res = mat.evaluate(F, tangent=True)
    assert np.all(np.isfinite(res.energy))

    h = 1e-4
    P_fd = _fd_derivative(mat.energy, F, h)
    A_fd = _fd_derivative(lambda G: mat.evaluate(G, tangent=False).stress, F, h)

    assert res.stress.shape == F.shape
    assert res.tangent.shape == F.shape + (d, d)
    # FD round-off: 1.5 eps x the gel's energy terms (kT/nu / lambda0^3 = 12 MPa) / h = 4e-11 MPa against
    # |P| ~ 2e-3 MPa of the gel near I: 2e-8 relative (measured 2.1e-8); truncation O(h^4) ~ 1e-16
    assert _rel_err(P_fd, res.stress).max() < 1e-5
    assert _rel_err(A_fd, res.tangent).max() < 1e-6
    # the energy called alone agrees with the energy from evaluate
    np.testing.assert_allclose(mat.energy(F), res.energy, rtol=1e-14, atol=1e-14)
    # the tangent is a second derivative: major symmetry A_iJkL = A_kLiJ
    At = np.transpose(res.tangent, (0, 3, 4, 1, 2))
    assert _rel_err(At, res.tangent).max() < 1e-12


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_evaluate_without_tangent(name, d):
    """tangent=False returns the same W and P and no tangent."""
    mat = MATERIALS[name]()
    F = _random_F(np.random.default_rng(3), d, 4, 0.2)
    full = mat.evaluate(F)
    part = mat.evaluate(F, tangent=False)
    assert part.tangent is None
    np.testing.assert_array_equal(part.energy, full.energy)
    np.testing.assert_array_equal(part.stress, full.stress)


# --------------------------------------------------------------------------------------------
# 2. The as-prepared state is stress-free at (mu0, T0)


@pytest.mark.parametrize("d", [2, 3])
def test_gel_as_prepared_state_is_stress_free(d):
    """P(I) = 0 at (mu0, T0) (docs/model.md: mu0 is derived from this condition); W(I) = 0 by shift."""
    gel = _gel()
    res = gel.evaluate(np.eye(d)[None])
    assert np.abs(res.stress).max() < 1e-10
    assert abs(res.energy[0]) < 1e-12
    # ... but not at another stimulus (the check above is not vacuous)
    assert np.abs(_gel(0.0, 275.0).evaluate(np.eye(d)[None]).stress).max() > 1e-2


def test_elastomers_stress_free_at_identity():
    """W(I) = 0 and P(I) = 0 for the elastomers (Abaqus forms vanish at the reference)."""
    for name in ("neohookean", "yeoh"):
        for d in (2, 3):
            res = MATERIALS[name]().evaluate(np.eye(d)[None])
            assert abs(res.energy[0]) < 1e-15
            assert np.abs(res.stress).max() < 1e-15


# --------------------------------------------------------------------------------------------
# 3. Objectivity


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_objectivity(name, d):
    """W(QF) = W(F) and P(QF) = Q P(F) for random rotations Q (frame indifference)."""
    mat = MATERIALS[name]()
    rng = np.random.default_rng(11 + d)
    F = _random_F(rng, d, 5, 0.3)
    Q = np.array([_random_rotation(rng, d) for _ in range(len(F))])
    QF = Q @ F
    r0 = mat.evaluate(F)
    r1 = mat.evaluate(QF)
    scale_W = np.abs(r0.energy).max() + 1e-3
    np.testing.assert_allclose(r1.energy, r0.energy, rtol=0, atol=1e-12 * scale_W)
    assert _rel_err(r1.stress, Q @ r0.stress).max() < 1e-12
    # tangent: A(QF)_iJkL = Q_ia Q_kb A(F)_aJbL
    A_rot = np.einsum("nia,nkb,najbl->nijkl", Q, Q, r0.tangent)
    assert _rel_err(r1.tangent, A_rot).max() < 1e-12


# --------------------------------------------------------------------------------------------
# 4. Plane strain consistency


@pytest.mark.parametrize("name", list(MATERIALS))
def test_plane_strain_is_3d_with_unit_out_of_plane_stretch(name):
    """W_2D(F) = W_3D(diag(F, 1)); P_2D and A_2D are the in-plane blocks of P_3D and A_3D."""
    mat = MATERIALS[name]()
    F2 = _random_F(np.random.default_rng(5), 2, 6, 0.3)
    r2 = mat.evaluate(F2)
    r3 = mat.evaluate(_embed(F2))
    np.testing.assert_allclose(r2.energy, r3.energy, rtol=1e-12, atol=1e-14)
    assert _rel_err(r2.stress, r3.stress[:, :2, :2]).max() < 1e-12
    assert _rel_err(r2.tangent, r3.tangent[:, :2, :2, :2, :2]).max() < 1e-12


# --------------------------------------------------------------------------------------------
# 5. Inadmissible deformation gradients


def _inadmissible_batch(d, gel):
    eye = np.eye(d)
    refl = eye.copy()
    refl[0, 0] = -1.0
    bad = [refl, np.zeros((d, d)), np.diag([1.0] * (d - 1) + [0.0]), np.diag([-2.0] + [1.5] * (d - 1)), np.diag([2.0] * (d - 1) + [-1e-3])]
    if gel:
        lam0 = PARAMS.lambda0
        bad += [
            np.diag([1.0] * (d - 1) + [1.0 / lam0**3]),  # J_dry = 1 exactly (no water at all)
            np.diag([1.0] * (d - 1) + [0.5 / lam0**3]),  # 0 < J_dry < 1
            (0.99 / lam0) * eye if d == 3 else np.diag([0.99 / lam0**1.5, 0.99 / lam0**1.5]),
        ]
    return np.array(bad)


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_inadmissible_states_have_infinite_energy_and_no_nan(name, d):
    """det F <= 0 (and gel J_dry <= 1) -> W = +inf, P = A = 0; no NaN, no exception, in a mixed batch."""
    mat = MATERIALS[name]()
    bad = _inadmissible_batch(d, name in GELS)
    good = _random_F(np.random.default_rng(2), d, len(bad), 0.1, min_det=0.8)
    batch = np.empty((2 * len(bad), d, d))
    batch[0::2] = bad
    batch[1::2] = good
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning (overflow, invalid value, log of 0) either
        res = mat.evaluate(batch)
        W_only = mat.energy(batch)
        res_no_tangent = mat.evaluate(batch, tangent=False)

    for arr in (res.energy, res.stress, res.tangent, W_only, res_no_tangent.stress):
        assert not np.isnan(arr).any()
    assert np.all(res.energy[0::2] == np.inf)
    assert np.all(W_only[0::2] == np.inf)
    assert np.all(res.stress[0::2] == 0.0)
    assert np.all(res.tangent[0::2] == 0.0)
    assert np.all(res_no_tangent.stress[0::2] == 0.0)
    # admissible entries are untouched by their inadmissible neighbours
    ref = mat.evaluate(good)
    assert np.all(np.isfinite(res.energy[1::2]))
    np.testing.assert_array_equal(res.energy[1::2], ref.energy)
    np.testing.assert_array_equal(res.stress[1::2], ref.stress)
    np.testing.assert_array_equal(res.tangent[1::2], ref.tangent)


def test_gel_admissibility_boundary_is_J_dry_equal_one():
    """Just above J_dry = 1 the gel energy is finite, at or below it +inf (docs/model.md, "Hydrogel")."""
    gel = _gel()
    lam0 = PARAMS.lambda0
    F = np.array([np.diag([1.0, 1.0, t / lam0**3]) for t in (1.0 + 1e-6, 1.0, 1.0 - 1e-6)])
    W = gel.energy(F)
    assert np.isfinite(W[0]) and W[1] == np.inf and W[2] == np.inf


# --------------------------------------------------------------------------------------------
# 6. Small-strain limit


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("G, nu", [(0.023, 0.45), (1.0, 0.3), (2.5, 0.0)])
def test_neohookean_small_strain_is_linear_elasticity(G, nu, d):
    """P(I + eps H) = 2 G eps_sym + lambda tr(eps) I, lambda = 2 G nu / (1 - 2 nu) (linear elasticity)."""
    mat = NeoHookean(shear_modulus=G, poisson_ratio=nu)
    lam = 2.0 * G * nu / (1.0 - 2.0 * nu)
    rng = np.random.default_rng(7)
    H = rng.standard_normal((5, d, d))
    H = 0.5 * (H + np.swapaxes(H, -1, -2))
    eps = 1e-6
    P = mat.evaluate(np.eye(d) + eps * H, tangent=False).stress
    sigma = 2.0 * G * eps * H + lam * eps * np.trace(H, axis1=-2, axis2=-1)[:, None, None] * np.eye(d)
    assert _rel_err(P, sigma).max() < 1e-4
    # and the tangent at F = I is the isotropic elasticity tensor (minor-symmetrised)
    A = mat.evaluate(np.eye(d)[None]).tangent[0]
    I = np.eye(d)
    C_lin = lam * np.einsum("ij,kl->ijkl", I, I) + G * (np.einsum("ik,jl->ijkl", I, I) + np.einsum("il,jk->ijkl", I, I))
    np.testing.assert_allclose(np.einsum("ijkl,kl->ij", A, H[0]), np.einsum("ijkl,kl->ij", C_lin, H[0]), rtol=1e-12, atol=1e-14 * G)


def test_yeoh_with_only_c10_is_neohookean():
    """Yeoh(c10, 0, 0, nu) equals NeoHookean(2 c10, nu) exactly (energy, stress, tangent)."""
    c10, nu = 0.0173, 0.42
    yeoh = Yeoh(c10=c10, poisson_ratio=nu)
    nh = NeoHookean(shear_modulus=2 * c10, poisson_ratio=nu)
    assert yeoh.bulk_modulus == nh.bulk_modulus
    assert yeoh.shear_modulus_ref == nh.shear_modulus_ref
    for d in (2, 3):
        F = _random_F(np.random.default_rng(d), d, 5, 0.3)
        ry, rn = yeoh.evaluate(F), nh.evaluate(F)
        np.testing.assert_array_equal(ry.energy, rn.energy)
        np.testing.assert_array_equal(ry.stress, rn.stress)
        np.testing.assert_array_equal(ry.tangent, rn.tangent)


def test_yeoh_higher_terms_change_the_response():
    """c20 and c30 matter at finite strain (the FD test would not notice them being ignored)."""
    F = np.array([np.diag([1.6, 0.8, 0.9])])
    base = Yeoh(c10=0.0115).evaluate(F, tangent=False)
    stiff = Yeoh(c10=0.0115, c20=0.002, c30=0.0004).evaluate(F, tangent=False)
    # W difference = c20 x^2 + c30 x^3 with x = I1bar - 3, coded independently
    J = np.linalg.det(F[0])
    x = J ** (-2 / 3) * np.sum(F[0] ** 2) - 3.0
    np.testing.assert_allclose(stiff.energy - base.energy, 0.002 * x**2 + 0.0004 * x**3, rtol=1e-12)


def test_neohookean_energy_closed_form():
    """W = G/2 (J^(-2/3) I1 - 3) + K/2 (J - 1)^2 with K = 2G(1+nu)/(3(1-2nu)), coded independently."""
    G, nu = 0.023, 0.45
    K = 2 * G * (1 + nu) / (3 * (1 - 2 * nu))
    F = _random_F(np.random.default_rng(9), 3, 5, 0.3)
    J = np.linalg.det(F)
    I1 = np.einsum("nij,nij->n", F, F)
    W = G / 2 * (J ** (-2 / 3) * I1 - 3) + K / 2 * (J - 1) ** 2
    np.testing.assert_allclose(NeoHookean().energy(F), W, rtol=1e-12)
    assert NeoHookean().bulk_modulus == pytest.approx(K, rel=1e-14)


# --------------------------------------------------------------------------------------------
# 7. Gel principal stresses against the closed form of docs/model.md


def _gel_principal_stress(lams, mu, T, n=0.01, lam0=1.5):
    """(kT/nu) s_i(lam0 * lams) / lam0^2 with s_i from docs/model.md (independent code)."""
    l = lam0 * np.asarray(lams, dtype=float)
    J = np.prod(l)
    chi0 = A0 + B0 * T
    chi1 = A1 + B1 * T
    g = np.log(1.0 - 1.0 / J) + 1.0 / J + (chi0 - chi1) / J**2 + 2.0 * chi1 / J**3 - mu
    s = n * (l - 1.0 / l) + (J / l) * g
    return KT_OVER_NU * s / lam0**2


def _gel_energy(lams, mu, T, n=0.01, lam0=1.5):
    """(kT/nu) [w(lam0 F) - w(lam0 I)] / lam0^3 for F = diag(lams), docs/model.md (independent)."""

    def w(l):
        J = np.prod(l)
        chi = A0 + B0 * T + (A1 + B1 * T) / J
        I1 = np.sum(l**2)
        return n / 2 * (I1 - 3 - 2 * np.log(J)) + (J - 1) * np.log(1 - 1 / J) + chi * (1 - 1 / J) - mu * (J - 1)

    return KT_OVER_NU * (w(lam0 * np.asarray(lams, float)) - w(lam0 * np.ones(3))) / lam0**3


GEL_STATES = [(None, 300.0), (0.0, 275.0), (0.0, 300.0), (0.0, 310.0), (-0.1, 290.0)]
DIAG_STRETCHES = [(1.0, 1.0, 1.0), (1.3, 0.9, 1.1), (0.7, 0.8, 1.05), (2.0, 1.5, 1.2), (1.6, 1.6, 0.45)]


@pytest.mark.parametrize("mu, T", GEL_STATES)
def test_gel_principal_stresses_closed_form(mu, T):
    """Diagonal F: P_ii = (kT/nu) s_i(lambda0 F_ii) / lambda0^2 (the closed form of docs/model.md), 2D and 3D."""
    gel = _gel(mu, T)
    mu_val = gel.mu
    for lams in DIAG_STRETCHES:
        lams = np.array(lams)
        # 3D
        r = gel.evaluate(np.diag(lams)[None])
        expected = _gel_principal_stress(lams, mu_val, T)
        scale = np.abs(expected).max() + 1.0  # MPa floor: the stress-free state is exactly 0
        np.testing.assert_allclose(np.diag(r.stress[0]), expected, rtol=0, atol=1e-10 * scale)
        off = r.stress[0] - np.diag(np.diag(r.stress[0]))
        assert np.abs(off).max() <= 1e-12 * scale
        np.testing.assert_allclose(r.energy[0], _gel_energy(lams, mu_val, T), rtol=1e-10, atol=1e-12)
        # 2D plane strain: the third stretch is 1 relative to the as-prepared state
        l2 = np.array([lams[0], lams[1], 1.0])
        r2 = gel.evaluate(np.diag(l2[:2])[None])
        exp2 = _gel_principal_stress(l2, mu_val, T)[:2]
        np.testing.assert_allclose(np.diag(r2.stress[0]), exp2, rtol=0, atol=1e-10 * (np.abs(exp2).max() + 1.0))
        np.testing.assert_allclose(r2.energy[0], _gel_energy(l2, mu_val, T), rtol=1e-10, atol=1e-12)


def test_gel_default_stimulus_and_at():
    """Hydrogel() sits at (mu0, T0); .at(mu, T) changes only the stimulus."""
    gel = Hydrogel()
    assert gel.T == 300.0
    assert gel.mu == pytest.approx(PARAMS.mu0, abs=0)
    g2 = gel.at(0.0, 280.0)
    assert (g2.mu, g2.T) == (0.0, 280.0) and g2.params == gel.params
    assert isinstance(gel, Material) and isinstance(NeoHookean(), Material) and isinstance(Yeoh(), Material)
    # shear modulus of the network in the as-prepared state: n kT/nu / lambda0
    assert gel.shear_modulus_ref == pytest.approx(0.01 * 40.0 / 1.5, rel=1e-14)
    # swelling ratio J_dry = lambda0^3 det F
    F = np.diag([1.1, 0.9, 1.2])[None]
    assert gel.swelling_ratio(F)[0] == pytest.approx(3.375 * 1.1 * 0.9 * 1.2, rel=1e-14)


# --------------------------------------------------------------------------------------------
# 8. Validation


@pytest.mark.parametrize(
    "factory, field",
    [
        (lambda: NeoHookean(shear_modulus=-1), "shear_modulus"),
        (lambda: NeoHookean(shear_modulus=0.0), "shear_modulus"),
        (lambda: NeoHookean(poisson_ratio=0.5), "poisson_ratio"),
        (lambda: NeoHookean(poisson_ratio=-0.1), "poisson_ratio"),
        (lambda: Yeoh(c10=0.0), "c10"),
        (lambda: Yeoh(poisson_ratio=0.5), "poisson_ratio"),
        (lambda: HydrogelParams(n=0), "n"),
        (lambda: HydrogelParams(lambda0=0.9), "lambda0"),
        (lambda: HydrogelParams(lambda0=1.0), "lambda0"),
        (lambda: HydrogelParams(kT_over_nu=-40.0), "kT_over_nu"),
        (lambda: NeoHookean(shear_modulu=0.1), "shear_modulu"),
        (lambda: Yeoh(c40=0.1), "c40"),
        (lambda: HydrogelParams(lambda_0=1.5), "lambda_0"),
    ],
)
def test_validation_errors_name_the_field(factory, field):
    """Out-of-range values and unknown keywords raise a pydantic ValidationError naming the field."""
    with pytest.raises(ValidationError) as exc:
        factory()
    locs = [err["loc"] for err in exc.value.errors()]
    assert any(field in loc for loc in locs), locs
    assert field in str(exc.value)


def test_parameter_models_are_frozen():
    """Materials are immutable (a solver may cache derived quantities)."""
    mat = NeoHookean()
    with pytest.raises(ValidationError):
        mat.shear_modulus = 1.0


# --------------------------------------------------------------------------------------------
# The compiled path: evaluate_compiled against the numpy evaluate (an independent implementation
# of the same formulas: vectorised numpy there, one numba loop per point here)


def _relative_gap(a, b):
    return np.abs(a - b).max() / np.abs(a).max()


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_compiled_evaluate_matches_numpy_up_to_round_off(name, d):
    """W, P, A of evaluate_compiled equal evaluate's to 1e-12 relative (round-off ~1e-16 times the
    conditioning of a gel near J_dry = 1, times > 100), in a batch mixed with inadmissible states,
    which get exactly W = +inf, P = A = 0 on both paths; orders 0 and 1 return the same W and P."""
    mat = MATERIALS[name]()
    rng = np.random.default_rng(7)
    good = _random_F(rng, d, 60, 0.3, min_det=0.8)
    bad = _inadmissible_batch(d, name in GELS)
    F = np.concatenate([good, bad])[rng.permutation(len(good) + len(bad))].reshape(1, -1, d, d)
    ref = mat.evaluate(F)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = mat.evaluate_compiled(F, 2)
        W0 = mat.evaluate_compiled(F, 0)
        r1 = mat.evaluate_compiled(F, 1)
    assert got.energy.shape == ref.energy.shape and got.tangent.shape == ref.tangent.shape
    ok = np.isfinite(ref.energy)
    assert 0 < ok.sum() < ok.size
    np.testing.assert_array_equal(np.isinf(got.energy), ~ok)
    assert np.all(got.stress[~ok] == 0.0) and np.all(got.tangent[~ok] == 0.0)
    assert _relative_gap(ref.energy[ok], got.energy[ok]) <= 1e-12
    assert _relative_gap(ref.stress, got.stress) <= 1e-12
    assert _relative_gap(ref.tangent, got.tangent) <= 1e-12
    np.testing.assert_array_equal(W0.energy, got.energy)
    assert W0.stress is None and W0.tangent is None and r1.tangent is None
    np.testing.assert_array_equal(r1.stress, got.stress)


def test_compiled_gel_admissibility_boundary_is_J_dry_equal_one():
    """The compiled path draws the J_dry = 1 line exactly where the numpy path does."""
    lam0 = PARAMS.lambda0
    F = np.array([np.diag([1.0, 1.0, t / lam0**3]) for t in (1.0 + 1e-6, 1.0, 1.0 - 1e-6)])
    W = _gel().evaluate_compiled(F, 0).energy
    assert np.isfinite(W[0]) and W[1] == np.inf and W[2] == np.inf


def test_compiled_evaluate_rejects_bad_input():
    with pytest.raises(ValueError, match="order"):
        NeoHookean().evaluate_compiled(np.eye(2)[None], 3)
    with pytest.raises(ValueError, match="2x2 or 3x3"):
        NeoHookean().evaluate_compiled(np.eye(4)[None])
