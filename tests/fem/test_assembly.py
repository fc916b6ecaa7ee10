"""The Solid's compiled path (numba element loops, materials' evaluate_compiled) against its numpy
path (batched einsum, bincount), an independent implementation of the same mathematics: equal up
to round-off, and the same admissibility (+inf energy) exactly."""

import numpy as np
import pytest

from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem.meshing import box, rectangle
from hydrojam.materials.energies import Hydrogel, HydrogelParams, NeoHookean, Yeoh

GEL_COLD = Hydrogel(HydrogelParams()).at(0.0, 275.0)  # swells: J_dry well above 1 at x = 1.1 X
YEOH = Yeoh(c10=0.0115, c20=0.002, c30=0.0004)
# Round-off of a sum of ~1e2 terms is ~1e-14 of its largest term; a factor of > 100 above it.
RTOL = 1e-11


def _mesh(dim):
    return rectangle(2.0, 1.0, 0.4, order=2) if dim == 2 else box(1.0, 1.0, 1.0, 0.6, order=2)


def _distorted(mesh, amplitude, seed):
    """Reference positions moved by a smooth field and some noise, so that element shapes and
    dNdX vary from cell to cell (curved edges: the tri6/tet10 Jacobian varies inside a cell)."""
    rng = np.random.default_rng(seed)
    X = mesh.points
    return X + 0.1 * np.sin(X[:, ::-1]) + amplitude * rng.standard_normal(X.shape)


def _solids(dim, materials, seed=0):
    mesh = _mesh(dim)
    el = element_for_meshio_type(mesh.cell_type)
    X = _distorted(mesh, 0.01, seed)
    half = len(mesh.cells) // 2
    blocks = [Block(mesh.cells[:half], el, materials[0], "a"), Block(mesh.cells[half:], el, materials[1], "b")]
    return mesh, X, Solid(X, blocks, kernels="numpy"), Solid(X, blocks, kernels="compiled")


def _gap(a, b):
    return abs(a - b).max() / abs(a).max()


PAIRS = {
    "neohookean+yeoh": (NeoHookean(), YEOH),
    "gel+neohookean": (GEL_COLD, NeoHookean()),
    "gel+gel": (GEL_COLD, GEL_COLD.at(-0.5, 290.0)),
}


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("pair", list(PAIRS))
def test_compiled_path_equals_numpy_path_up_to_round_off(dim, pair):
    """Energy, block energies, gradient, force flux, plain and PSD-projected Hessians (assembled
    and per element) agree to RTOL of their largest entry, at a swollen, distorted state."""
    mesh, X, Sn, Sc = _solids(dim, PAIRS[pair])
    rng = np.random.default_rng(1)
    x = 1.1 * X + 0.01 * rng.standard_normal(X.shape)
    assert Sn.compiled is False and Sc.compiled is True
    en = Sn.energy(x)
    assert np.isfinite(en)
    assert Sc.energy(x) == pytest.approx(en, rel=RTOL)
    for k, v in Sn.block_energies(x).items():
        assert Sc.block_energies(x)[k] == pytest.approx(v, rel=RTOL)
    assert _gap(Sn.gradient(x), Sc.gradient(x)) <= RTOL
    assert _gap(Sn.force_flux(x), Sc.force_flux(x)) <= RTOL
    for project in (False, True):
        Hn, Hc = Sn.hessian(x, project), Sc.hessian(x, project)
        assert Hc.shape == Hn.shape and Hc.nnz == Hn.nnz
        assert _gap(Hn, Hc) <= RTOL
        for Kn, Kc in zip(Sn.element_hessians(x, project), Sc.element_hessians(x, project)):
            assert Kc.shape == Kn.shape and _gap(Kn, Kc) <= RTOL
    np.testing.assert_allclose(Sc.deformation_gradients(x)["a"], Sn.deformation_gradients(x)["a"], rtol=0, atol=RTOL)


@pytest.mark.parametrize("dim", [2, 3])
def test_projected_element_matrices_are_psd_on_both_paths(dim):
    """At a state with compressed, indefinite elements, the projection clamps the same spectrum."""
    mesh, X, Sn, Sc = _solids(dim, (NeoHookean(), YEOH))
    x = X * np.r_[0.6, 1.3, 1.0][:dim] + 0.02 * np.random.default_rng(3).standard_normal(X.shape)
    Kp = Sc.element_hessians(x, project=True)[0]
    w = np.linalg.eigvalsh(Kp)
    assert w.min() >= -1e-12 * np.abs(w).max()
    assert np.linalg.eigvalsh(Sc.element_hessians(x)[0]).min() < -1e-6 * np.abs(w).max()  # there was something to clamp
    assert _gap(Sn.element_hessians(x, project=True)[0], Kp) <= RTOL


@pytest.mark.parametrize("dim", [2, 3])
def test_inadmissible_states_are_infinite_on_both_paths(dim):
    """Inverted elements (det F < 0), and a compressed gel (J_dry <= 1), give +inf on both paths;
    the elastomer block alone stays finite and equal."""
    mesh, X, Sn, Sc = _solids(dim, (GEL_COLD, NeoHookean()))
    inverted = X.copy()
    inverted[:, 0] *= -1.0  # a mirror image
    squeezed = 0.5 * X  # J_dry = 1.5^3 0.5^d <= 0.85 in the gel block
    for x in (inverted, squeezed):
        assert Sn.energy(x) == np.inf and Sc.energy(x) == np.inf
    bn, bc = Sn.block_energies(squeezed), Sc.block_energies(squeezed)
    assert bn["a"] == np.inf and bc["a"] == np.inf
    assert bc["b"] == pytest.approx(bn["b"], rel=RTOL)


class _Opaque:
    """A material without evaluate_compiled (the numpy protocol only)."""

    def __init__(self, inner):
        self.inner = inner
        self.shear_modulus_ref = inner.shear_modulus_ref

    def energy(self, F):
        return self.inner.energy(F)

    def evaluate(self, F, tangent=True):
        return self.inner.evaluate(F, tangent)


def test_a_material_without_compiled_kernel_runs_with_the_compiled_element_loops():
    mesh, X, Sn, Sc = _solids(2, (_Opaque(GEL_COLD), NeoHookean()))
    x = 1.1 * X
    assert Sc.energy(x) == pytest.approx(Sn.energy(x), rel=RTOL)
    assert _gap(Sn.gradient(x), Sc.gradient(x)) <= RTOL
    assert _gap(Sn.hessian(x, True), Sc.hessian(x, True)) <= RTOL


def test_kernels_choice(monkeypatch):
    mesh = _mesh(2)
    blocks = [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), NeoHookean(), "a")]
    assert Solid(mesh.points, blocks).kernels == "compiled"
    assert Solid(mesh.points, blocks).with_materials({"a": YEOH}).kernels == "compiled"
    monkeypatch.setenv("HYDROJAM_COMPILED", "0")
    assert Solid(mesh.points, blocks).kernels == "numpy"
    assert Solid(mesh.points, blocks, kernels="compiled").kernels == "compiled"
    with pytest.raises(ValueError, match="kernels"):
        Solid(mesh.points, blocks, kernels="fortran")
