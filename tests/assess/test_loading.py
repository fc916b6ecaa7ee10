"""Verification of the tip loads and the stiffness measurement (issue 15, item 2): the face's
weights and loads, the centroid spring's derivatives (central finite differences), and the
bending stiffness of a slender plane-strain bilayer cantilever against Euler-Bernoulli for the
composite section (plane-strain moduli E' = E/(1 - nu^2) = 2G/(1 - nu))."""

import numpy as np
import pytest

from hydrojam.assess.loading import Structure, tangent_stiffness, tip_curve
from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem.meshing import bonded_rectangles, rectangle
from hydrojam.fem.problem import fixed
from hydrojam.fem.terms import CentroidSpring, face_weights, resultant_load
from hydrojam.materials.energies import NeoHookean

# a stiff strain-limit-like layer (Dragon Skin 30-class) bonded to an Ecoflex 00-30 layer
STIFF = NeoHookean(shear_modulus=0.2, poisson_ratio=0.45)
SOFT = NeoHookean(shear_modulus=0.023, poisson_ratio=0.45)
H_STIFF, H_SOFT, LENGTH = 2.0, 3.0, 100.0  # mm: L/H = 20, shear deflection ~0.5% of bending


def _plane_strain_modulus(m):
    return 2 * m.shear_modulus * (1 + m.poisson_ratio) / (1 - m.poisson_ratio**2)


def _euler_bernoulli_stiffness():
    """3 (EI)' / L^3 of the two-layer section (per unit depth): the neutral axis where the
    first moment of E' vanishes, parallel-axis theorem for each layer."""
    E = [_plane_strain_modulus(STIFF), _plane_strain_modulus(SOFT)]
    h = [H_STIFF, H_SOFT]
    centre = [H_STIFF / 2, H_STIFF + H_SOFT / 2]
    neutral = sum(e * t * c for e, t, c in zip(E, h, centre)) / sum(e * t for e, t in zip(E, h))
    EI = sum(e * (t**3 / 12 + t * (c - neutral) ** 2) for e, t, c in zip(E, h, centre))
    return 3 * EI / LENGTH**3


@pytest.fixture(scope="module")
def bilayer():
    mesh = bonded_rectangles(H_STIFF, H_SOFT, LENGTH, 1.0)
    el = element_for_meshio_type(mesh.cell_type)
    solid = Solid(mesh.points, [Block(mesh.cells[mesh.cell_groups["left_body"]], el, STIFF, "stiff"),
                                Block(mesh.cells[mesh.cell_groups["right_body"]], el, SOFT, "soft")])
    # clamped at y = L, free end at y = 0; bending in x
    return Structure(mesh.points, (solid,), (fixed(mesh.group_nodes("top"), 2),), mesh.facet_groups["bottom"],
                     SOFT.shear_modulus * H_SOFT)


def test_face_weights_and_resultant_load():
    """The weights sum to 1 and weight the face's nodes by their consistent share of its length
    (quadratic edges: 1/6, 2/3, 1/6 of an edge); the load's nodal forces add up to the force."""
    mesh = rectangle(3.0, 1.0, 0.5, structured=True)
    facets = mesh.facet_groups["top"]
    w = face_weights(mesh.points, facets)
    assert w.sum() == pytest.approx(1.0, abs=1e-14)
    assert np.all(w[np.setdiff1d(np.arange(mesh.n_nodes), facets)] == 0)
    mids = facets[:, 2]
    assert w[mids] == pytest.approx(np.full(len(mids), (2 / 3) * 0.5 / 3.0), rel=1e-12)
    load = resultant_load(mesh.points, facets, [0.3, -0.2])
    assert load.forces.sum(axis=0) == pytest.approx([0.3, -0.2], rel=1e-12)


def test_centroid_spring_matches_central_differences():
    """E = k/2 |c(x) - target|^2 in x only: gradient and Hessian against central differences
    (E is quadratic, so the difference quotients are exact up to round-off eps |E| / h)."""
    mesh = rectangle(2.0, 1.0, 0.5)
    rng = np.random.default_rng(1)
    x = mesh.points + 0.1 * rng.standard_normal(mesh.points.shape)
    spring = CentroidSpring(mesh.points, mesh.facet_groups["right"], [0.5, 0.2], 3.0, components=(0,))
    g, H = spring.gradient(x), spring.hessian(x).toarray()
    h = 1e-4
    scale = max(spring.energy(x), 1e-3)
    for i in rng.choice(x.size, 20, replace=False):
        e = np.zeros(x.size)
        e[i] = h
        xp, xm = (x.ravel() + e).reshape(x.shape), (x.ravel() - e).reshape(x.shape)
        assert (spring.energy(xp) - spring.energy(xm)) / (2 * h) == pytest.approx(g[i], abs=1e-9 * scale / h + 1e-12)
        assert (spring.gradient(xp) - spring.gradient(xm)) / (2 * h) == pytest.approx(H[:, i], abs=1e-9)
    assert spring.reaction(x)[1] == 0.0
    assert spring.reaction(x)[0] == pytest.approx(-3.0 * (spring.centroid(x)[0] - 0.5), rel=1e-12)


def test_bilayer_cantilever_stiffness_matches_euler_bernoulli(bilayer):
    """Tangent stiffness (exact Hessian) and the secant of a tip load of L/100 deflection in +x
    and -x: within 2% of Euler-Bernoulli 3 (EI)'/L^3 for the composite section. The corrections
    left out are below that: Timoshenko shear ~ (E'/kappa G)(H/2L)^2 ~ 0.5%, the clamp's
    plane-strain restraint and the geometric stiffening of a deflection of L/100 (< 0.1%)."""
    k_eb = _euler_bernoulli_stiffness()
    k = tangent_stiffness(bilayer, bilayer.X)
    assert k / k_eb == pytest.approx(1.0, abs=0.02)
    curve = tip_curve(bilayer, bilayer.X, 0.01 * LENGTH * k_eb, fractions=(1.0,))
    assert curve.converged
    for sign in (1, -1):
        assert curve.secant(sign) / k_eb == pytest.approx(1.0, abs=0.02)


def test_spring_holds_the_tip_with_the_euler_bernoulli_force(bilayer):
    """A prescribed tip displacement (the spring's target moved by L/200 in x): the spring's
    reaction over the tip's actual displacement is the stiffness, within 2% of Euler-Bernoulli,
    and the spring's give is F/k_spring (a stiff penalty: well below the displacement)."""
    k_eb = _euler_bernoulli_stiffness()
    spring = CentroidSpring(bilayer.X, bilayer.free_end, [0.0, 0.0], 1e3 * k_eb, components=(0,))
    start = spring.centroid(bilayer.X)
    delta = LENGTH / 200

    def ramped(s):
        spring.target = start + np.array([s * delta, 0.0])
        return [spring]

    res = bilayer.load(bilayer.X, ramped)
    assert res.converged
    moved = spring.centroid(res.x)[0] - start[0]
    force = spring.reaction(res.x)[0]  # the force the spring puts on the tip, +x
    assert force / moved / k_eb == pytest.approx(1.0, abs=0.02)
    assert abs(delta - moved) < 2e-3 * delta
