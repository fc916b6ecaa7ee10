"""Verification of the volume term (issue 16): E = sum_b k_b/2 (V_b - Vbar_b)^2 over bodies.

Against finite differences of its own energy (gradient) and gradient (Hessian), the mesh's own
cell areas and volumes (V_b), and the definition of positive semi-definiteness (``project``).
"""

import numpy as np
import pytest

from hydrojam.fem.meshing import ball, disks
from hydrojam.fem.volume import VolumeTerm


def _bodies(dim):
    if dim == 2:
        mesh = disks([(0.0, 0.0), (3.0, 0.5)], [1.0, 1.2], 0.4, order=2)
    else:
        mesh = ball(1.0, 0.8, order=2)
    groups = sorted(k for k in mesh.cell_groups if k != "body") or ["body"]
    bodies = []
    for g in groups:
        cells = mesh.cells[mesh.cell_groups[g]]
        bodies.append((cells, mesh.boundary_facets(mesh.cell_groups[g])))
    return mesh, bodies


def _distorted(points, seed=3):
    rng = np.random.default_rng(seed)
    return 1.1 * points + 0.05 * rng.standard_normal(points.shape) + 0.3


@pytest.mark.parametrize("dim", [2, 3])
def test_volumes_are_the_bodies_own(dim):
    """V_b under an affine map is det A times the sum of the body's isoparametric (curved) cell
    areas/volumes, integrated exactly by the mesh."""
    mesh, bodies = _bodies(dim)
    term = VolumeTerm(mesh.points, bodies)
    A = np.diag([1.1, 0.9, 1.2][:dim]) + 0.1
    x = mesh.points @ A.T + 0.3
    expected = [np.linalg.det(A) * mesh.cell_volumes(curved=True)[mesh.cell_groups[g]].sum()
                for g in sorted(k for k in mesh.cell_groups if k != "body") or ["body"]]
    assert term.volumes(x) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_gradient_and_hessian_match_central_differences(dim):
    """At a distorted state with targets on either side of the volumes (so that k (V - Vbar)
    has both signs): the gradient is the central difference of the energy and the Hessian that of
    the gradient. E is a polynomial of degree 4 (2D) or 6 (3D) in x: truncation h^2/6 |E'''|
    plus round-off eps |E| / h, both from the energy's scale k V^2."""
    mesh, bodies = _bodies(dim)
    x = _distorted(mesh.points)
    term = VolumeTerm(mesh.points, bodies, controller=lambda v: (v * np.linspace(0.8, 1.2, len(v)),
                                                                  np.linspace(2.0, 3.0, len(v))))
    term.begin_step(x)
    V = term.volumes(x)
    if len(V) > 1:
        assert np.any(V > term.targets) and np.any(V < term.targets)
    g, H = term.gradient(x), term.hessian(x).toarray()
    scale = float(np.sum(term.stiffness * V**2))
    h = 1e-5
    eps = np.finfo(float).eps
    tol = 100 * (eps * scale / h + h**2 * scale)
    rng = np.random.default_rng(0)
    dofs = rng.choice(np.unique(np.concatenate([b[1].ravel() for b in bodies])) * dim, size=30, replace=False)
    dofs = np.concatenate([dofs, dofs + 1])
    xf = x.ravel()
    for i in dofs:
        e = np.zeros_like(xf)
        e[i] = h
        xp, xm = (xf + e).reshape(x.shape), (xf - e).reshape(x.shape)
        assert g[i] == pytest.approx((term.energy(xp) - term.energy(xm)) / (2 * h), abs=tol)
        col = (term.gradient(xp) - term.gradient(xm)) / (2 * h)
        assert np.max(np.abs(H[:, i] - col)) <= tol
    assert np.max(np.abs(H - H.T)) <= 1e-12 * np.max(np.abs(H))


@pytest.mark.parametrize("dim", [2, 3])
def test_projected_hessian_is_positive_semidefinite_and_zero_without_stiffness(dim):
    mesh, bodies = _bodies(dim)
    x = _distorted(mesh.points)
    term = VolumeTerm(mesh.points, bodies, controller=lambda v: (1.3 * v, np.full(len(v), 2.0)))
    assert term.energy(x) == 0.0 and not np.any(term.gradient(x))  # before the first step
    term.begin_step(x)
    H = term.hessian(x, project=True).toarray()
    lam = np.linalg.eigvalsh(0.5 * (H + H.T))
    assert lam.min() >= -1e-10 * lam.max()
    assert np.linalg.eigvalsh(term.hessian(x).toarray()).min() < -1e-6 * lam.max()  # the exact one is not
    with pytest.raises(ValueError, match="one target and one stiffness >= 0 per body"):
        VolumeTerm(mesh.points, bodies, controller=lambda v: (v, -np.ones(len(v)))).begin_step(x)


# ----------------------------------------------------------------------------------------------
# point by point


@pytest.mark.parametrize("dim", [2, 3])
def test_local_term_matches_central_differences_and_its_definition(dim):
    """LocalVolumeTerm at a distorted state, targets on either side of det F: its energy is
    sum k/2 (det F - Jbar)^2 w dV computed here from the element's own quadrature; the gradient
    and Hessian are central differences (truncation h^2 |E'''|, round-off eps |E| / h); the
    projected Hessian is positive semi-definite."""
    from hydrojam.fem.elements import element_for_meshio_type, physical_gradients
    from hydrojam.fem.volume import LocalVolumeTerm

    mesh, _ = _bodies(dim)
    el = element_for_meshio_type(mesh.cell_type)
    x = _distorted(mesh.points)
    rng = np.random.default_rng(1)

    def controller(J):
        return J * rng.uniform(0.8, 1.2, J.shape), rng.uniform(1.0, 2.0, J.shape)

    term = LocalVolumeTerm(mesh.points, mesh.cells, el, controller)
    assert term.energy(x) == 0.0
    term.begin_step(x)
    k, Jbar = term._solid.blocks[0].material.stiffness, term._solid.blocks[0].material.targets
    dNdX, dV = physical_gradients(el, mesh.points[mesh.cells])
    F = np.einsum("eai,eqaj->eqij", x[mesh.cells], dNdX)
    J = np.linalg.det(F)
    E = float(np.sum(0.5 * k * (J - Jbar) ** 2 * dV))
    assert term.energy(x) == pytest.approx(E, rel=1e-12)
    g, H = term.gradient(x), term.hessian(x).toarray()
    h, eps = 1e-5, np.finfo(float).eps
    tol = 100 * (eps * E / h + h**2 * E)
    xf = x.ravel()
    for i in rng.choice(xf.size, size=12, replace=False):
        e = np.zeros_like(xf)
        e[i] = h
        xp, xm = (xf + e).reshape(x.shape), (xf - e).reshape(x.shape)
        assert g[i] == pytest.approx((term.energy(xp) - term.energy(xm)) / (2 * h), abs=tol)
        assert np.max(np.abs(H[:, i] - (term.gradient(xp) - term.gradient(xm)) / (2 * h))) <= tol
    lam = np.linalg.eigvalsh(term.hessian(x, project=True).toarray())
    assert lam.min() >= -1e-10 * lam.max()
