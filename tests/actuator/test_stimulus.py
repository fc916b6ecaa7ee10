"""The stimulus path (hydrojam.actuator.stimulus): endpoints, monotonicity, and the swelling path checked
against the swelling module's global-minimum equilibria. Both use the one root finder
(``equilibrium_stretches``, verified against independent formulas in tests/materials); what is
checked here is the path built on it: continuation along the branch, the log-stretch coordinate
and the interpolation between knots."""

import numpy as np
import pytest

from hydrojam import HydrogelParams, constrained_swelling, free_swelling
from hydrojam.actuator.stimulus import stimulus_path

P = HydrogelParams()


@pytest.mark.parametrize("kind", ["linear", "swelling"])
def test_endpoints_are_the_as_prepared_state_and_the_target(kind):
    path = stimulus_path(P, 0.0, 275.0, kind)
    assert path(0.0) == pytest.approx((P.mu0, P.T0), abs=1e-15)
    assert path(1.0) == pytest.approx((0.0, 275.0), abs=1e-15)
    t = [path.position(s) for s in np.linspace(0, 1, 101)]
    assert np.all(np.diff(t) >= 0)


def test_linear_path_is_linear():
    path = stimulus_path(P, -0.01, 290.0, "linear")
    mu, T = path(0.25)
    assert mu == pytest.approx(P.mu0 + 0.25 * (-0.01 - P.mu0))
    assert T == pytest.approx(P.T0 + 0.25 * (290.0 - P.T0))


def _unconfined_stretch(mu, T, dimension):
    """The particles' unconfined equilibrium stretch from the swelling module's global minimisation:
    plane strain in 2D (out-of-plane stretch held at lambda0), free in 3D."""
    if dimension == 2:
        return constrained_swelling(P, mu, T, (P.lambda0,)).stretch
    return free_swelling(P, mu, T).stretch


def _check_even_spread(path, T_target, dimension, samples):
    """s = 0.9 f + 0.1 t at each of ``samples``, f = ln(lambda/lambda0) / ln(lambda_1/lambda0)."""
    lam1 = _unconfined_stretch(0.0, T_target, dimension)
    for s in samples:
        mu, T = path(s)
        f = np.log(_unconfined_stretch(mu, T, dimension) / P.lambda0) / np.log(lam1 / P.lambda0)
        assert 0.9 * f + 0.1 * path.position(s) == pytest.approx(s, abs=2e-3)
    return lam1


@pytest.mark.parametrize("dimension", [2, 3])
def test_swelling_path_spreads_the_log_swelling_evenly(dimension):
    """Along the swelling path, s = 0.9 f + 0.1 t, f = ln(lambda/lambda0) / ln(lambda_1/lambda0)
    of the unconfined equilibrium stretch (plane strain in 2D: out-of-plane stretch held at
    lambda0; free in 3D), computed here by the swelling module's global minimisation."""
    path = stimulus_path(P, 0.0, 275.0, "swelling", dimension=dimension)
    _check_even_spread(path, 275.0, dimension, (0.2, 0.5, 0.8))


@pytest.mark.parametrize("dimension", [2, 3])
def test_swelling_path_follows_a_gel_that_collapses(dimension):
    """Heating to 310 K, past the volume phase transition: the particles collapse, in plane strain
    to an in-plane stretch below the dry network's (0.943: J > 1 only through the held thickness).
    Away from the collapse, which falls between two knots, s = 0.9 f + 0.1 t holds as above, with f
    from the swelling module's equilibria (the only stable state at each of these stimuli)."""
    path = stimulus_path(P, 0.0, 310.0, "swelling", dimension=dimension)
    lam1 = _check_even_spread(path, 310.0, dimension, (0.1, 0.85, 0.95))
    if dimension == 2:
        assert lam1 == pytest.approx(0.9434, abs=1e-4)


def test_swelling_path_reaches_the_plane_strain_stretch():
    """The 2D path's end state: in-plane stretch 2.586 from the as-prepared state (docs/actuator.md, "Stimulus path")."""
    s1 = constrained_swelling(P, 0.0, 275.0, (P.lambda0,))
    assert s1.stretch / P.lambda0 == pytest.approx(2.586, abs=1e-3)


def test_a_target_equal_to_the_start_gives_a_constant_stimulus():
    path = stimulus_path(P, P.mu0, P.T0, "swelling")
    for s in (0.0, 0.3, 1.0):
        assert path(s) == pytest.approx((P.mu0, P.T0))


def test_unknown_path_kind_is_refused():
    with pytest.raises(ValueError, match="swelling"):
        stimulus_path(P, 0.0, 275.0, "cubic")
