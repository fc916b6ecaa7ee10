"""A small-strain linear-elastic solve of the actuator's walls under a uniform eigenstrain, written
here apart from the simulator's solid (its own B matrices and sparse assembly): the cheap elastic
check of the helical strip's twist (docs/chambers.md, "A helical strip")."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from hydrojam.fem.elements import element_for_meshio_type, physical_gradients


def isotropic_stiffness(shear_modulus: float, poisson_ratio: float) -> np.ndarray:
    """The 6 x 6 isotropic elasticity matrix in Voigt order (xx, yy, zz, yz, xz, xy), engineering
    shear strains [MPa]."""
    G, nu = shear_modulus, poisson_ratio
    lam = 2.0 * G * nu / (1.0 - 2.0 * nu)
    C = np.zeros((6, 6))
    C[:3, :3] = lam
    C[np.arange(3), np.arange(3)] += 2.0 * G
    C[np.arange(3, 6), np.arange(3, 6)] = G
    return C


def _b_matrices(dNdX: np.ndarray) -> np.ndarray:
    """(ne, nq, 6, 3 nen) strain-displacement matrices from shape gradients (ne, nq, nen, 3)."""
    ne, nq, nen, _ = dNdX.shape
    B = np.zeros((ne, nq, 6, 3 * nen))
    gx, gy, gz = dNdX[..., 0], dNdX[..., 1], dNdX[..., 2]
    B[..., 0, 0::3], B[..., 1, 1::3], B[..., 2, 2::3] = gx, gy, gz
    B[..., 3, 1::3], B[..., 3, 2::3] = gz, gy
    B[..., 4, 0::3], B[..., 4, 2::3] = gz, gx
    B[..., 5, 0::3], B[..., 5, 1::3] = gy, gx
    return B


def solve_eigenstrain(mesh, groups: dict[str, tuple[np.ndarray, float]], clamp: np.ndarray) -> np.ndarray:
    """Displacements (n, 3) [mm] of the cells of ``groups`` (name: (6 x 6 stiffness [MPa], Voigt
    eigenstrain (6,) [-])) with the nodes ``clamp`` held; the nodes of no group are left at 0."""
    el = element_for_meshio_type(mesh.cell_type)
    n = mesh.n_nodes
    rows, cols, vals, f = [], [], [], np.zeros(3 * n)
    used = []
    for name, (C, eps0) in groups.items():
        cells = mesh.cells[mesh.cell_groups[name]]
        used.append(cells.ravel())
        dNdX, dV = physical_gradients(el, mesh.points[cells])
        B = _b_matrices(dNdX)
        K = np.einsum("eqai,ab,eqbj,eq->eij", B, C, B, dV)
        fe = np.einsum("eqai,a,eq->ei", B, C @ eps0, dV)
        dofs = (3 * cells[:, :, None] + np.arange(3)).reshape(len(cells), -1)
        rows.append(np.repeat(dofs, dofs.shape[1], axis=1).ravel())
        cols.append(np.tile(dofs, (1, dofs.shape[1])).ravel())
        vals.append(K.ravel())
        np.add.at(f, dofs.ravel(), fe.ravel())
    K = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * n, 3 * n))
    active = np.zeros(n, dtype=bool)
    active[np.unique(np.concatenate(used))] = True
    active[clamp] = False
    free = np.repeat(active, 3)
    u = np.zeros(3 * n)
    u[free] = spla.spsolve(K[free][:, free].tocsc(), f[free])
    return u.reshape(n, 3)


def cell_volume(mesh, group: str) -> float:
    """The volume [mm^3] of the cells of ``group``, by the elements' own quadrature."""
    cells = mesh.cells[mesh.cell_groups[group]]
    return float(physical_gradients(element_for_meshio_type(mesh.cell_type), mesh.points[cells])[1].sum())


def rigid_rotation(points: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The small rotation vector (3,) [rad] of the least-squares rigid motion u = a + w x (X - c)
    of the nodes at ``points`` (n, 3) [mm] displaced by ``u`` (n, 3) [mm]."""
    r = points - points.mean(axis=0)
    A = np.zeros((len(r), 3, 6))
    A[:, :, :3] = np.eye(3)
    zero = np.zeros(len(r))
    A[:, :, 3:] = np.stack([np.stack([zero, r[:, 2], -r[:, 1]], axis=1),
                            np.stack([-r[:, 2], zero, r[:, 0]], axis=1),
                            np.stack([r[:, 1], -r[:, 0], zero], axis=1)], axis=1)
    return np.linalg.lstsq(A.reshape(-1, 6), u.ravel(), rcond=None)[0][3:]
