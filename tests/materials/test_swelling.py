"""Verification of material-point swelling of the PNIPAM gel (docs/model.md, "Swelling analysis").

The free energy, the stationarity condition and the principal nominal stresses are coded again
here, independently of hydrojam (from the formulas of docs/model.md), and the library's equilibria are
checked against them: stationarity residuals, brute-force global minimisation on dense grids, and
the paper's reference chemical potential.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from hydrojam import (
    HydrogelParams,
    constrained_swelling,
    free_swelling,
    nominal_stresses,
    reference_chemical_potential,
    swelling_curve,
    transition_temperature,
)
from hydrojam.materials.swelling import equilibrium_stretches

# docs/model.md, "Hydrogel", typed here so that a wrong default in the library is caught
N = 0.01
LAM0 = 1.5
T0 = 300.0
A0, B0, A1, B1 = -12.947, 0.04496, 17.92, -0.0569

PARAMS = HydrogelParams()
TEMPS = np.arange(275.0, 315.0 + 1e-9, 5.0)


# ------------------------------------------------------------------------------------------------
# Independent implementation of the model


def chi(T, J):
    return A0 + B0 * T + (A1 + B1 * T) / J


def w_free(lam, mu, T, n=N):
    """Free-swelling energy per dry volume w(lambda) [kT/nu], F = lambda I."""
    lam = np.asarray(lam, dtype=float)
    J = lam**3
    return (
        n / 2 * (3 * lam**2 - 3 - 6 * np.log(lam))
        + (J - 1) * np.log(1 - 1 / J)
        + chi(T, J) * (1 - 1 / J)
        - mu * (J - 1)
    )


def stationarity_residual(lam, mu, T, n=N):
    """RHS - mu of the docs/model.md condition mu = ln(1-phi) + phi + chi phi^2 - chi1 phi^2 (1-phi) + n(1/l - 1/l^3).

    dw/dlambda = 3 lambda^2 * residual, so its sign changes from - to + mark the local minima.
    """
    lam = np.asarray(lam, dtype=float)
    phi = 1 / lam**3
    J = lam**3
    rhs = (
        np.log(1 - phi)
        + phi
        + chi(T, J) * phi**2
        - (A1 + B1 * T) * phi**2 * (1 - phi)
        + n * (1 / lam - 1 / lam**3)
    )
    return rhs - mu


def g_mix(J, mu, T):
    chi0 = A0 + B0 * T
    chi1 = A1 + B1 * T
    return np.log(1 - 1 / J) + 1 / J + (chi0 - chi1) / J**2 + 2 * chi1 / J**3 - mu


def principal_stresses(lams, mu, T, n=N):
    """s_i = n (l_i - 1/l_i) + (J/l_i) g(J) [kT/nu], dry reference."""
    lams = np.asarray(lams, dtype=float)
    J = np.prod(lams)
    return n * (lams - 1 / lams) + (J / lams) * g_mix(J, mu, T)


# The paper's mu0 (docs/model.md), computed from the stationarity condition at (lambda0, T0)
MU0_INDEP = float(stationarity_residual(LAM0, 0.0, T0))

# Dense grid for brute-force minimisation over lambda in (1, 10]
LAM_GRID = np.linspace(1.0, 10.0, 450_001)[1:]
DLAM = LAM_GRID[1] - LAM_GRID[0]


def grid_minima(mu, T):
    """Local minima (lambda, w) of w on the grid (dw/dlambda from - to +), and the global grid minimiser."""
    w = w_free(LAM_GRID, mu, T)
    r = stationarity_residual(LAM_GRID, mu, T)
    idx = np.nonzero((r[:-1] < 0) & (r[1:] >= 0))[0]
    local = [(LAM_GRID[i], w[i]) for i in idx]
    k = int(np.argmin(w))
    return local, LAM_GRID[k], w[k]


# ------------------------------------------------------------------------------------------------
# 1. The reference chemical potential


def test_defaults_match_design():
    """HydrogelParams defaults are the docs/model.md values (n, lambda0, T0, chi fit, kT/nu)."""
    p = PARAMS
    assert (p.n, p.lambda0, p.T0, p.A0, p.B0, p.A1, p.B1, p.kT_over_nu) == (N, LAM0, T0, A0, B0, A1, B1, 40.0)
    assert p.chi_coefficients(290.0) == pytest.approx((A0 + B0 * 290.0, A1 + B1 * 290.0), rel=1e-15)


def test_reference_chemical_potential_is_the_papers_value():
    """mu0 = -0.0343 kT (the paper's value) for lambda0 = 1.5, T0 = 300 K, n = 0.01."""
    mu0 = reference_chemical_potential(PARAMS)
    assert mu0 == pytest.approx(-0.0343, abs=1e-4)
    assert PARAMS.mu0 == mu0
    # and exactly the independent stationarity condition at (lambda0, T0)
    # terms ~0.5 in kT, with chi0, chi1 = A + B T cancelling 13-18 to 0.5-0.9: round-off ~1e-15
    assert mu0 == pytest.approx(MU0_INDEP, abs=1e-12)


def test_reference_chemical_potential_other_params():
    """mu0 follows lambda0, T0 and n (independent stationarity condition)."""
    p = HydrogelParams(lambda0=2.0, T0=290.0, n=0.02)
    # as above: round-off ~1e-15 kT
    assert reference_chemical_potential(p) == pytest.approx(float(stationarity_residual(2.0, 0.0, 290.0, n=0.02)), abs=1e-12)


def test_free_swelling_at_reference_state_is_lambda0():
    """free_swelling(params, mu0, T0) returns the as-prepared state lambda0 = 1.5."""
    st = free_swelling(PARAMS, PARAMS.mu0, PARAMS.T0)
    assert st.stretch == pytest.approx(LAM0, abs=1e-8)
    assert st.stretch_rel == pytest.approx(1.0, abs=1e-8)
    assert st.J == pytest.approx(LAM0**3, rel=1e-8)


# ------------------------------------------------------------------------------------------------
# 2-3. Free swelling: stationarity and global minimum


MUS = [0.0, MU0_INDEP, -0.1]


@pytest.fixture(scope="module")
def curves():
    """swelling_curve over TEMPS for each mu (one transition search per mu)."""
    return {mu: swelling_curve(PARAMS, mu, TEMPS) for mu in MUS}


@pytest.mark.parametrize("mu", MUS, ids=["mu=0", "mu=mu0", "mu=-0.1"])
def test_free_swelling_is_stationary(curves, mu):
    """Each state satisfies the docs/model.md stationarity condition (independent code) to 1e-9."""
    _, states = curves[mu]
    assert len(states) == len(TEMPS)
    for T, st in zip(TEMPS, states):
        assert st.T == T and st.mu == mu
        assert abs(stationarity_residual(st.stretch, mu, T)) < 1e-9
        # consistency of the reported fields
        assert st.J == pytest.approx(st.stretch**3, rel=1e-12)
        assert st.stretch_rel == pytest.approx(st.stretch / LAM0, rel=1e-14)
        assert st.energy == pytest.approx(float(w_free(st.stretch, mu, T)), rel=1e-10, abs=1e-12)
        # free_swelling gives the same state as swelling_curve
    st = free_swelling(PARAMS, mu, 290.0)
    assert st.stretch == pytest.approx(states[list(TEMPS).index(290.0)].stretch, rel=1e-12)


@pytest.mark.parametrize("mu", MUS, ids=["mu=0", "mu=mu0", "mu=-0.1"])
def test_free_swelling_is_global_minimum(curves, mu):
    """The reported stretch is the brute-force minimiser of w(lambda) on a dense grid in (1, 10]."""
    _, states = curves[mu]
    for T, st in zip(TEMPS, states):
        _, lam_grid, w_grid = grid_minima(mu, T)
        assert abs(st.stretch - lam_grid) <= 1.5 * DLAM, (T, st.stretch, lam_grid)
        # the true minimum lies at or below the grid minimum
        assert float(w_free(st.stretch, mu, T)) <= w_grid + 1e-13


def _bistable_temperatures(mu, Ts):
    return [T for T in Ts if len(grid_minima(mu, T)[0]) >= 2]


def test_bistable_window_picks_lower_minimum():
    """Inside the bistable window (two local minima on the grid), the lower-energy one is reported."""
    Ts = np.arange(302.0, 310.0, 0.5)
    bist = _bistable_temperatures(0.0, Ts)
    assert len(bist) >= 2, "expected a bistable window near the transition at mu = 0"
    tr = transition_temperature(PARAMS, 0.0)
    assert min(bist) < tr.T < max(bist)
    below = [T for T in bist if T < tr.T]
    above = [T for T in bist if T > tr.T]
    assert below and above
    for T in (below[0], below[-1], above[0], above[-1]):
        local, lam_grid, w_grid = grid_minima(0.0, T)
        assert len(local) == 2
        (l_lo, w_lo), (l_hi, w_hi) = sorted(local)
        # well separated energies at the chosen temperatures, so the grid decides unambiguously
        assert abs(w_lo - w_hi) > 1e-8
        st = free_swelling(PARAMS, 0.0, T, T_c=tr.T)
        assert st.bistable
        winner = l_lo if w_lo < w_hi else l_hi
        assert abs(st.stretch - winner) <= 1.5 * DLAM, (T, st.stretch, local)
        assert abs(st.stretch - lam_grid) <= 1.5 * DLAM
        assert st.branch == ("swollen" if winner == l_hi else "collapsed")
        assert st.branch == ("swollen" if T < tr.T else "collapsed")
        assert abs(stationarity_residual(st.stretch, 0.0, T)) < 1e-9


@pytest.mark.parametrize("T", [275.0, 295.0, 304.0, 305.5, 307.0, 315.0])
def test_equilibrium_stretches_are_every_local_minimum(T):
    """The one root finder (free gel, mu = 0): every local minimum of the brute-force grid, no
    other, each stationary (the independent stationarity residual; brentq's 1e-14 in lambda times
    a slope of order 10 is ~1e-13, so 1e-9 leaves room for any platform). In plane strain
    (out-of-plane stretch held at lambda0) each returned stretch zeroes the independent in-plane
    nominal stress, which rises through zero there."""
    local, _, _ = grid_minima(0.0, T)
    roots = equilibrium_stretches(PARAMS, 0.0, T)
    assert len(roots) == len(local) and np.all(np.diff(roots) > 0)
    for lam, (lam_grid, _) in zip(roots, sorted(local)):
        assert abs(lam - lam_grid) <= 1.5 * DLAM
        assert abs(stationarity_residual(lam, 0.0, T)) < 1e-9
    plane = equilibrium_stretches(PARAMS, 0.0, T, held=(LAM0,))
    assert len(plane) >= 1
    h = 1e-6
    for t in plane:
        assert abs(principal_stresses([LAM0, t, t], 0.0, T)[-1]) < 1e-9
        assert principal_stresses([LAM0, t - h, t - h], 0.0, T)[-1] < 0 < principal_stresses([LAM0, t + h, t + h], 0.0, T)[-1]
    assert constrained_swelling(PARAMS, 0.0, T, (LAM0,)).stretch in plane


def test_no_bistability_away_from_transition(curves):
    """Far from the transition only one local minimum exists, and it is reported as not bistable."""
    _, states = curves[0.0]
    for T, st in zip(TEMPS, states):
        n_min = len(grid_minima(0.0, T)[0])
        assert st.bistable == (n_min >= 2), (T, n_min)


# ------------------------------------------------------------------------------------------------
# 4. Temperature dependence and the volume phase transition


def test_swelling_increases_as_temperature_falls():
    """J rises monotonically as T falls (mu = 0); swollen below T_c, collapsed above."""
    Ts = np.arange(315.0, 274.9, -1.0)
    tr, states = swelling_curve(PARAMS, 0.0, Ts)
    J = np.array([s.J for s in states])
    assert np.all(np.diff(J) > 0)
    for T, st in zip(Ts, states):
        assert st.branch == ("swollen" if T < tr.T else "collapsed"), (T, st.branch)
    # the transition is a jump: the volume on either side of T_c differs by the coexisting J's
    i = int(np.nonzero(Ts < tr.T)[0][0])
    assert J[i] / J[i - 1] > 2.0
    assert transition_temperature(PARAMS, 0.0).T == tr.T


def test_transition_at_mu0_is_discontinuous_with_equal_energies():
    """mu = 0, n = 0.01: J_swollen > J_collapsed, both stationary local minima of equal energy at T_c."""
    tr = transition_temperature(PARAMS, 0.0)
    assert tr.discontinuous
    assert 300.0 < tr.T < 312.0  # the paper's PNIPAM collapses a little above 305 K
    assert tr.J_swollen > 2 * tr.J_collapsed
    ls, lc = tr.J_swollen ** (1 / 3), tr.J_collapsed ** (1 / 3)
    for lam in (ls, lc):
        assert abs(stationarity_residual(lam, 0.0, tr.T)) < 1e-9
        # local minimum: dw/dlambda = 3 lambda^2 R changes sign from - to +
        h = 1e-4
        assert stationarity_residual(lam - h, 0.0, tr.T) < 0 < stationarity_residual(lam + h, 0.0, tr.T)
    assert abs(float(w_free(ls, 0.0, tr.T) - w_free(lc, 0.0, tr.T))) < 1e-8
    # the two branches are the only local minima there, and they are the grid's global minima
    local, _, w_grid = grid_minima(0.0, tr.T)
    assert len(local) == 2
    assert abs(local[0][0] - lc) <= 1.5 * DLAM and abs(local[1][0] - ls) <= 1.5 * DLAM
    assert min(w_free(ls, 0.0, tr.T), w_free(lc, 0.0, tr.T)) <= w_grid + 1e-13


def test_transition_continuous_for_negative_mu():
    """At mu = -0.1 no temperature is bistable (grid scan): a smooth crossover at the steepest fall of J."""
    Ts = np.arange(280.0, 316.0, 1.0)
    assert _bistable_temperatures(-0.1, Ts) == []
    tr = transition_temperature(PARAMS, -0.1)
    assert not tr.discontinuous
    assert tr.J_swollen == tr.J_collapsed
    # steepest fall of ln J from the independent grid minimisers, 0.25 K apart
    Tf = np.arange(285.0, 310.0, 0.25)
    # a single root of the residual at each T (no bistability): bracketed and refined
    lnJ = np.array([3 * np.log(brentq(stationarity_residual, 1 + 1e-9, 10.0, args=(-0.1, T), xtol=1e-14)) for T in Tf])
    T_steep = Tf[int(np.argmin(np.gradient(lnJ, Tf)))]
    assert abs(tr.T - T_steep) < 1.0


# ------------------------------------------------------------------------------------------------
# 5. Constrained swelling


@pytest.mark.parametrize("mu, T", [(0.0, 280.0), (0.0, 295.0), (MU0_INDEP, 300.0), (-0.1, 285.0), (0.0, 312.0)])
def test_layer_on_rigid_substrate(mu, T):
    """held = (lambda0, lambda0): n (l - 1/l) + lambda0^2 g(J) = 0 with J = lambda0^2 l (independent code)."""
    st = constrained_swelling(PARAMS, mu, T, (LAM0, LAM0))
    l = st.stretch
    assert st.J == pytest.approx(LAM0**2 * l, rel=1e-12)
    assert abs(N * (l - 1 / l) + LAM0**2 * g_mix(LAM0**2 * l, mu, T)) < 1e-9
    # and the global minimum over l of w(lambda0, lambda0, l) on a dense grid
    ls = np.linspace(1 / LAM0**2, 12.0, 400_001)[1:]
    J = LAM0**2 * ls
    w = N / 2 * (2 * LAM0**2 + ls**2 - 3 - 2 * np.log(J)) + (J - 1) * np.log(1 - 1 / J) + chi(T, J) * (1 - 1 / J) - mu * (J - 1)
    assert abs(l - ls[np.argmin(w)]) <= 1.5 * (ls[1] - ls[0])


@pytest.mark.parametrize("l1", [1.0, 1.5, 2.5])
@pytest.mark.parametrize("mu, T", [(0.0, 285.0), (-0.05, 300.0), (0.0, 310.0)])
def test_uniaxial_constraint_free_directions_are_stress_free(l1, mu, T):
    """held = (l1,): the two free directions carry zero nominal stress (independent s_i), J = l1 t^2."""
    st = constrained_swelling(PARAMS, mu, T, (l1,))
    t = st.stretch
    assert st.J == pytest.approx(l1 * t**2, rel=1e-12)
    s = principal_stresses([l1, t, t], mu, T)
    assert abs(s[1]) < 1e-9 and abs(s[2]) < 1e-9
    # the held direction generally carries a stress (the check above is not trivially zero)
    np.testing.assert_allclose(nominal_stresses(PARAMS, [l1, t, t], mu, T), s, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("T", [275.0, 290.0, 300.0])
def test_constraint_reduces_swelling(T):
    """Held stretches below the free stretch give a smaller J than free swelling at the same (mu, T)."""
    free = free_swelling(PARAMS, 0.0, T)
    assert free.stretch > LAM0
    for held in [(LAM0, LAM0), (LAM0,), (1.2, 1.8)]:
        assert max(held) < free.stretch
        c = constrained_swelling(PARAMS, 0.0, T, held)
        assert c.J < free.J, (held, c.J, free.J)
    # holding at exactly the free stretch reproduces free swelling
    c = constrained_swelling(PARAMS, 0.0, T, (free.stretch, free.stretch))
    assert c.J == pytest.approx(free.J, rel=1e-8)


def test_nominal_stresses_against_independent_formula():
    """nominal_stresses equals the docs/model.md s_i for arbitrary principal stretches."""
    for lams, mu, T in [((1.2, 2.0, 3.1), 0.0, 280.0), ((1.5, 1.5, 1.5), -0.0343, 300.0), ((0.9, 1.4, 2.2), -0.1, 310.0)]:
        # sums of terms ~1 with chi0 = A0 + B0 T cancelling 13 to 0.5 (a stress can be ~0): round-off ~1e-15
        np.testing.assert_allclose(nominal_stresses(PARAMS, lams, mu, T), principal_stresses(lams, mu, T), rtol=1e-12, atol=1e-12)


# ------------------------------------------------------------------------------------------------
# 6. No equilibrium for mu > 0


@pytest.mark.parametrize(
    "call",
    [
        lambda: free_swelling(PARAMS, 0.01, 300.0),
        lambda: free_swelling(PARAMS, 0.01, 300.0, T_c=305.0),
        lambda: swelling_curve(PARAMS, 0.05, [290.0]),
        lambda: transition_temperature(PARAMS, 0.02),
    ],
)
def test_positive_mu_has_no_equilibrium(call):
    """mu > 0: the gel swells without bound, ValueError mentioning mu."""
    with pytest.raises(ValueError, match="mu"):
        call()


@pytest.mark.parametrize("mu", [5e-5, 1e-6])
def test_small_positive_mu_has_no_equilibrium(mu):
    """0 < mu << n: w(lambda) ~ 3n/2 lambda^2 - mu lambda^3 is unbounded below (independent check),
    so no stable state exists however small mu is, and free_swelling must raise ValueError too."""
    lam = np.array([10.0, 1e3, 1e5])
    assert w_free(lam[-1], mu, 290.0) < w_free(lam[0], mu, 290.0) - 1e3  # unbounded below
    with pytest.raises(ValueError, match="mu"):
        free_swelling(PARAMS, mu, 290.0)
