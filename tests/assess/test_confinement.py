"""Verification of the confinement measures (issue 15, item 5): the gel's confined swelling
pressure against central finite differences of its free energy, and the nodal-force-to-pressure
conversion against the nodal forces of a known uniform pressure (PressureTerm's energy
derivative)."""

import numpy as np
import pytest

from hydrojam.assess.confinement import confined_swelling_pressure, segment_pressure
from hydrojam.fem.terms import PressureTerm
from hydrojam.materials.energies import HydrogelParams, gel_psi


@pytest.mark.parametrize("T", [275.0, 285.0, 295.0, 310.0])
def test_swelling_pressure_is_minus_the_free_energy_derivative(T):
    """A gel held at J = lambda0^3 (dry reference) under uniform dilation: the Cauchy pressure is
    -k_B T/nu d w(I1 = 3 J^(2/3), J)/dJ (energy per dry volume, so its J-derivative is the
    stress), here by central differences of gel_psi (order 0) with step 1e-5 J: truncation
    ~ h^2 w''' and round-off eps |w| / h, both below 1e-6 of the stress scale k_B T/nu."""
    p = HydrogelParams()
    J0, h = p.lambda0**3, 1e-5 * p.lambda0**3

    def w(J):
        return float(gel_psi(p, 0.0, T, 3.0 * J ** (2 / 3), J, order=0)[0])

    sigma = p.kT_over_nu * (w(J0 + h) - w(J0 - h)) / (2 * h)
    assert confined_swelling_pressure(p, 0.0, T) == pytest.approx(-sigma, abs=1e-6 * p.kT_over_nu)


def test_swelling_pressure_is_zero_as_prepared_and_megapascals_when_cold():
    """Zero at the as-prepared stimulus (mu0, T0) (stress-free by the definition of mu0); at
    275 K in water about 7 MPa (the radial solution of docs/model.md), falling with T."""
    p = HydrogelParams()
    assert confined_swelling_pressure(p, p.mu0, p.T0) == pytest.approx(0.0, abs=1e-9 * p.kT_over_nu)
    cold = confined_swelling_pressure(p, 0.0, 275.0)
    assert 6.0 < cold < 8.5
    assert confined_swelling_pressure(p, 0.0, 295.0) < confined_swelling_pressure(p, 0.0, 285.0) < cold


def test_segment_pressure_recovers_a_uniform_pressure():
    """A uniform pressure p on a polyline of straight, uneven segments (an arc, part of it
    loaded): its consistent nodal forces (PressureTerm's dead load: half of each segment's
    force p l n to each end) turned back into a pressure give p at every loaded node and as the
    mean, over the loaded length, up to the bend: a node's force is the vector sum of its two
    half-forces, shorter than their sum by cos(half the turning angle) at most."""
    t = np.sort(np.random.default_rng(0).uniform(0, np.pi, 30))
    x = np.column_stack([np.cos(t), np.sin(t)]) * 5.0
    segments = np.column_stack([np.arange(29), np.arange(1, 30)])
    loaded = segments[5:20]
    p = 0.013
    forces = -PressureTerm(x, loaded, p, follower=False).gradient(x).reshape(-1, 2)
    tangents = np.diff(x, axis=0)
    turn = np.abs(np.diff(np.arctan2(tangents[:, 1], tangents[:, 0]))).max()
    rel = 1 - np.cos(turn / 2) + 1e-12
    out = segment_pressure(loaded, x, forces)
    length = np.linalg.norm(x[loaded[:, 1]] - x[loaded[:, 0]], axis=1).sum()
    assert out.contact_length == pytest.approx(length, rel=1e-12)
    assert out.mean == pytest.approx(p, rel=rel)
    assert out.maximum == pytest.approx(p, rel=rel)
    assert out.total_force == pytest.approx(p * length, rel=rel)
