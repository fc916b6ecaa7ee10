"""A slender structure whose bending is softer than the Newton regularisation: a clamped
gel-elastomer bilayer strip (plane strain, 100 x 2 mm) cooled by 0.1 K bends to the curvature of
Timoshenko's bimetal strip, and the default Newton converges quadratically in its bending mode
(the regularised factorisation only preconditions the step: docs/solver.md, "Newton")."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from hydrojam.fem import NewtonOptions
from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem.meshing import bonded_rectangles
from hydrojam.fem.problem import fixed
from hydrojam.fem.solver.newton import minimize
from hydrojam.materials.energies import Hydrogel, HydrogelParams, NeoHookean
from hydrojam.materials.swelling import constrained_swelling

PARAMS = HydrogelParams()
COOLING = 0.1  # K: the gel swells by eps* = 0.6 % in plane strain
GEL = Hydrogel(PARAMS).at(PARAMS.mu0, PARAMS.T0 - COOLING)
ELASTOMER = NeoHookean(shear_modulus=0.023, poisson_ratio=0.45)  # Ecoflex 00-30
T_GEL, T_EL, LENGTH = 1.0, 1.0, 100.0  # mm: L/h = 50


def _axial_modulus(material, stretch):
    """dP_yy/dF_yy about F = stretch I (plane strain) with P_xx = 0 (the strip's faces free):
    the layer's axial modulus in beam theory [MPa], from the material's tangent alone."""
    A = material.evaluate(stretch * np.eye(2)[None]).tangent[0]
    return A[1, 1, 1, 1] - A[1, 1, 0, 0] * A[0, 0, 1, 1] / A[0, 0, 0, 0]


def _timoshenko_curvature():
    """Timoshenko's (1925) bimetal-strip curvature [1/mm] of the two layers, the gel's mismatch
    eps* its free plane-strain stretch at the cooled state less 1 (the mesh is the gel's stress-free
    state before cooling), the moduli the layers' axial ones (:func:`_axial_modulus`).
    Exact for linear plane elasticity away from the ends (pure bending of a layered section)."""
    stretch = constrained_swelling(PARAMS, PARAMS.mu0, PARAMS.T0 - COOLING, (PARAMS.lambda0,)).stretch / PARAMS.lambda0
    mismatch = stretch - 1.0
    m, n = T_GEL / T_EL, _axial_modulus(GEL, stretch) / _axial_modulus(ELASTOMER, 1.0)
    h = T_GEL + T_EL
    return 6 * mismatch * (1 + m) ** 2 / (h * (3 * (1 + m) ** 2 + (1 + m * n) * (m**2 + 1 / (m * n)))), mismatch


@pytest.fixture(scope="module")
def strip():
    """The strip (gel on x in [0, 1], elastomer on [1, 2], clamped at y = L) minimised from its
    flat state by the default Newton (iterations: 100, to see a linear tail end)."""
    mesh = bonded_rectangles(T_GEL, T_EL, LENGTH, 1.0)
    el = element_for_meshio_type(mesh.cell_type)
    solid = Solid(mesh.points, [Block(mesh.cells[mesh.cell_groups["left_body"]], el, GEL, "gel"),
                                Block(mesh.cells[mesh.cell_groups["right_body"]], el, ELASTOMER, "elastomer")])
    free = np.ones(mesh.points.size, dtype=bool)
    free[fixed(mesh.group_nodes("top"), 2).dofs] = False
    res = minimize([solid], mesh.points, free, GEL.shear_modulus_ref, NewtonOptions(max_iter=100))
    interface = np.flatnonzero(np.isclose(mesh.points[:, 0], T_GEL))
    interface = interface[np.argsort(mesh.points[interface, 1])]
    return mesh, solid, free, res, interface


def _curvature(X, x, interface):
    """The interface's rotation per reference length [1/mm], fitted over its middle 60 % (clear
    of the clamp's and the free end's boundary layers, a few thicknesses long)."""
    d = np.diff(x[interface], axis=0)
    angle = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    y = 0.5 * (X[interface][1:, 1] + X[interface][:-1, 1])
    middle = (y > 0.2 * LENGTH) & (y < 0.8 * LENGTH)
    return abs(np.polyfit(y[middle], angle[middle], 1)[0])


def test_a_cooled_bilayer_strip_bends_to_timoshenkos_curvature(strip):
    """Within 2 eps* of Timoshenko: beam theory is linear, and the terms it leaves out (the
    strains, ~eps*, against 1; the tip's rotation of 0.28 rad changes nothing in pure bending)
    are of relative order eps* = 0.6 % (measured -0.7 %; the 1 mm and 0.5 mm meshes agree to
    1e-7: quadratic elements hold pure bending's linear strains exactly)."""
    mesh, _, _, res, interface = strip
    assert res.converged, res.message
    expected, mismatch = _timoshenko_curvature()
    assert _curvature(mesh.points, res.x, interface) == pytest.approx(expected, rel=2 * mismatch)


def test_the_default_newton_converges_quadratically_in_the_bending_mode(strip):
    """The bending mode's stiffness lies below the regularisation's 1e-9 mean|diag H| here; the
    undamped step still solves H itself, so the last step cuts the residual by far more than a
    linear rate (the regularised step alone: x0.55 an iteration over the last ten). The converged
    state is within the solver tolerance of the discrete equilibrium: one exact Newton correction
    (SciPy's LU of the unregularised H, the clamp making it non-singular) changes the curvature by
    less than 10 rtol relative (the regularised step alone stopped 2.6e-4 short)."""
    mesh, solid, free, res, interface = strip
    assert res.converged, res.message
    r = res.residuals
    assert r[-1] <= 0.1 * r[-2]
    fidx = np.flatnonzero(free)
    g = solid.gradient(res.x).ravel()[fidx]
    H = sp.csc_matrix(solid.hessian(res.x, False)[fidx][:, fidx])
    corrected = res.x.copy().ravel()
    corrected[fidx] -= spla.spsolve(H, g)
    kappa, exact = _curvature(mesh.points, res.x, interface), _curvature(mesh.points, corrected.reshape(res.x.shape),
                                                                          interface)
    assert abs(kappa - exact) <= 10 * NewtonOptions().rtol * exact
