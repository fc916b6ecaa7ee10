"""The assessment's actuation time against the classical series of diffusion (Crank, The
Mathematics of Diffusion, eqs. 6.20 and 5.23), computed here independently."""

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import jn_zeros

from hydrojam._format import duration
from hydrojam.assess.speed import swelling_time


def _series_t90(dimension: int, radius: float, D: float) -> float:
    if dimension == 3:
        tau = radius**2 / (np.pi**2 * D)
        n = np.arange(1, 200)
        share = lambda t: 1 - 6 / np.pi**2 * np.sum(np.exp(-n**2 * t / tau) / n**2)
    else:
        a = jn_zeros(0, 200)
        share = lambda t: 1 - np.sum(4 / a**2 * np.exp(-a**2 * D * t / radius**2))
    return brentq(lambda t: share(t) - 0.9, 1e-6 * radius**2 / D, 10 * radius**2 / D, xtol=1e-12 * radius**2 / D)


@pytest.mark.parametrize("dimension", [2, 3])
def test_swelling_time_matches_the_series(dimension):
    radius, D = 17.3, 1e-4
    tau, t90 = swelling_time(radius, D, dimension)
    assert tau == pytest.approx(radius**2 / (np.pi**2 * D), rel=1e-12)
    # the numerics' error is about 1e-5 of the step past 0.1 tau, the share's slope at t90 about
    # 0.1/tau: 1e-4 tau in time; 2e-3 of t90 leaves a margin of 20 and still catches a wrong shape
    assert t90 == pytest.approx(_series_t90(dimension, radius, D), rel=2e-3)


def test_sphere_t90_is_the_known_multiple_of_tau():
    tau, t90 = swelling_time(1.0, 1.0, 3)
    assert t90 / tau == pytest.approx(1.80, abs=0.01)


def test_durations_read_in_a_sensible_unit():
    assert duration(30.0) == "30 s"
    assert duration(600.0) == "10 min"
    assert duration(3 * 86400.0) == "3 days"
    assert duration(None) == "n/a"
