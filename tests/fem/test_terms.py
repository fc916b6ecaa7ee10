"""The energy terms of hydrojam.fem.terms on their own: loads against their resultants, the
stabilisation and the centroid spring against finite differences and their definitions, and the
wrappers (TimedTerm, ScaledTerm) passing every protocol member through."""

import numpy as np
import pytest
import scipy.sparse as sp

from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem.meshing import box, rectangle
from hydrojam.fem.terms import (CentroidSpring, EnergyTerm, LinearTerm, ScaledTerm, TimedTerm,
                                ViscousStabilisation, body_load, by_name, face_weights, lumped_volumes,
                                nodal_areas, resultant_load, surface_load)


@pytest.fixture(scope="module")
def plate():
    return rectangle(3.0, 2.0, 0.7, order=2)


def _fd_check(term, x, h=1e-4):
    """Central differences of the energy and of the gradient against gradient and Hessian. These
    energies are quadratic in x, so a central difference is exact but for round-off: 10 eps times
    the size of the terms summed (|x|^T |H| |x| for the energy, |H| |x| for the gradient: x
    enters through differences such as x - x^n, each rounded at eps |x|), over h."""
    eps = np.finfo(float).eps
    g, H = term.gradient(x), sp.csr_matrix(term.hessian(x)).toarray()
    size = np.abs(H) @ (np.abs(x.ravel()) + h)
    rng = np.random.default_rng(1)
    for _ in range(3):
        v = rng.standard_normal(x.shape)
        slope = (term.energy(x + h * v) - term.energy(x - h * v)) / (2 * h)
        exact = float(g @ v.ravel())
        assert abs(slope - exact) <= 10 * eps * (abs(term.energy(x)) + float(size @ np.abs(x.ravel()))) / h
        dg = (term.gradient(x + h * v) - term.gradient(x - h * v)) / (2 * h)
        assert np.abs(dg - H @ v.ravel()).max() <= 10 * eps * size.max() / h


def test_nodal_areas_and_lumped_volumes_sum_to_the_measures(plate):
    """The consistent nodal lengths of the top edge sum to its length (3 mm), the face weights to
    1, and the lumped nodal areas of the plate to its area (6 mm^2); in 3D the box's z-max face
    to its area (2 mm^2) and the lumped volumes to its volume (1.5 mm^3)."""
    top = plate.facet_groups["top"]
    assert nodal_areas(plate.points, top).sum() == pytest.approx(3.0, rel=1e-12)
    assert face_weights(plate.points, top).sum() == pytest.approx(1.0, rel=1e-12)
    assert lumped_volumes(plate.points, plate.cells, plate.cell_volumes()).sum() == pytest.approx(6.0, rel=1e-12)
    cube = box(1.0, 2.0, 0.75, 0.5, order=2)
    assert nodal_areas(cube.points, cube.facet_groups["zmax"]).sum() == pytest.approx(2.0, rel=1e-12)
    assert lumped_volumes(cube.points, cube.cells, cube.cell_volumes()).sum() == pytest.approx(1.5, rel=1e-12)


def test_loads_carry_their_resultants(plate):
    """A traction t on the top edge: nodal forces summing to t x 3 mm; a body force b: to b x
    6 mm^2; a resultant F over the top edge: to F, with the work F . u for a uniform
    displacement u."""
    top = plate.facet_groups["top"]
    t, b, F = np.array([0.2, -1.0]), np.array([0.0, -0.5]), np.array([1.5, 0.25])
    assert surface_load(plate.points, top, t).forces.sum(axis=0) == pytest.approx(3.0 * t, rel=1e-12)
    element = element_for_meshio_type(plate.cell_type)
    assert body_load(plate.points, plate.cells, element, b).forces.sum(axis=0) == pytest.approx(6.0 * b, rel=1e-12)
    load = resultant_load(plate.points, top, F)
    assert load.forces.sum(axis=0) == pytest.approx(F, rel=1e-12)
    u = np.array([0.3, -0.1])
    assert load.energy(plate.points + u) == pytest.approx(-F @ u, rel=1e-12)


def test_the_stabilisation_is_the_weighted_distance_from_the_step_start(plate):
    """c/2 sum w |x - x^n|^2 with x^n set by begin_step: zero before it and at x^n, its gradient
    and Hessian its derivatives (finite differences), linear in the scale."""
    w = lumped_volumes(plate.points, plate.cells, plate.cell_volumes())
    stab = ViscousStabilisation(w, 2.0, 2)
    x = plate.points + 0.01 * np.random.default_rng(0).standard_normal(plate.points.shape)
    assert stab.energy(x) == 0.0 and not np.any(stab.gradient(x)) and not np.any(stab.hessian(x).data)
    stab.begin_step(plate.points)
    assert stab.energy(plate.points) == 0.0
    ref = 0.5 * 2.0 * float(np.sum(w[:, None] * (x - plate.points) ** 2))
    assert stab.energy(x) == pytest.approx(ref, rel=1e-12)
    _fd_check(stab, x)
    stab.scale = 0.25
    assert stab.energy(x) == pytest.approx(0.25 * ref, rel=1e-12)


def test_the_centroid_spring_holds_the_face_mean(plate):
    """k/2 |c(x) - target|^2 over the components held: its reaction -k (c - target) balances
    the gradient's resultant, and its derivatives match finite differences."""
    top = plate.facet_groups["top"]
    spring = CentroidSpring(plate.points, top, target=[1.5, 2.5], stiffness=10.0, components=(1,))
    x = plate.points.copy()
    c = spring.centroid(x)
    assert c == pytest.approx([1.5, 2.0], rel=1e-12)
    assert spring.reaction(x) == pytest.approx([0.0, 5.0], rel=1e-12)
    assert spring.gradient(x).reshape(-1, 2).sum(axis=0) == pytest.approx(-spring.reaction(x), rel=1e-12)
    _fd_check(spring, x + 0.01)


class _Probe(EnergyTerm):
    """Every protocol member answers with something recognisable."""

    name = "probe"
    fallback_projection = True

    def __init__(self):
        self.begun = None

    def energy(self, x):
        return 2.0

    def gradient(self, x):
        return np.full(np.size(x), 3.0)

    def hessian(self, x, project=False):
        return sp.identity(np.size(x), format="csr") * (5.0 if project else 4.0)

    def max_step(self, x, dx):
        return 0.5

    def begin_step(self, x):
        self.begun = x

    def hessian_pattern(self, x):
        return sp.identity(np.size(x), format="csr")

    def force_flux(self, x, gradient=None):
        return np.full(np.size(x), 7.0)


def test_the_wrappers_pass_every_protocol_member_through():
    """TimedTerm: the same answers, and one record per call naming the method; ScaledTerm: energy,
    gradient, Hessian and forces in play scaled, the step cap, pattern and step start not."""
    x = np.zeros((2, 2))
    calls = []
    timed = TimedTerm(_Probe(), lambda method, seconds: calls.append((method, seconds)))
    assert (timed.name, timed.fallback_projection) == ("probe", True)
    assert timed.energy(x) == 2.0 and timed.gradient(x)[0] == 3.0 and timed.max_step(x, x) == 0.5
    assert timed.hessian(x, True).diagonal()[0] == 5.0 and timed.hessian_pattern(x).nnz == 4
    assert timed.force_flux(x)[0] == 7.0
    timed.begin_step(x)
    assert timed._term.begun is x
    assert [m for m, _ in calls] == ["energy", "gradient", "max_step", "hessian", "hessian_pattern", "force_flux",
                                     "begin_step"]
    assert all(s >= 0 for _, s in calls)
    probe = _Probe()
    scaled = ScaledTerm(probe, 0.5)
    assert scaled.energy(x) == 1.0 and scaled.gradient(x)[0] == 1.5 and scaled.hessian(x).diagonal()[0] == 2.0
    assert scaled.force_flux(x)[0] == 3.5 and scaled.max_step(x, x) == 0.5 and scaled.hessian_pattern(x).nnz == 4
    scaled.begin_step(x)
    assert probe.begun is x


def test_terms_are_addressed_by_unique_names():
    a, b = LinearTerm(np.zeros((1, 2)), np.zeros((1, 2)), "a"), LinearTerm(np.zeros((1, 2)), np.zeros((1, 2)), "b")
    assert list(by_name([a, b])) == ["a", "b"]
    with pytest.raises(ValueError, match="two energy terms are named 'a'"):
        by_name([a, a])
