"""Cell fields of an actuator state (swelling ratio, Cauchy and von Mises stress), as written to
the VTU files and drawn in the figures."""

from __future__ import annotations

import numpy as np

from hydrojam.actuator.model import MEMBRANE, STRAIN_LIMIT_LAYER, ActuatorModel, particle_block


def _plane_strain_3d(F: np.ndarray) -> np.ndarray:
    """2D deformation gradients in (x, z) as 3D ones in (x, y, z) with the out-of-plane stretch 1."""
    F3 = np.zeros(F.shape[:-2] + (3, 3))
    F3[..., 0, 0], F3[..., 0, 2] = F[..., 0, 0], F[..., 0, 1]
    F3[..., 2, 0], F3[..., 2, 2] = F[..., 1, 0], F[..., 1, 1]
    F3[..., 1, 1] = 1.0
    return F3


def cell_fields(model: ActuatorModel, x: np.ndarray, s: float) -> dict[str, np.ndarray]:
    """Cell data of a state at load parameter s: ``body_id``, ``swelling_ratio`` (gel J_dry =
    lambda0^3 det F; 1 in the elastomers), ``cauchy_stress`` (n, 3, 3) in (x, y, z) [MPa] and
    ``von_mises_stress`` [MPa], averaged over each cell's quadrature points; a multi-chamber
    design's also ``chamber``: the chamber of each particle cell (0, 1, ...), -1 in the walls."""
    n = model.mesh.n_cells
    sigma = np.zeros((n, 3, 3))
    swell = np.ones(n)
    cells_of = model.block_cells()
    materials = model.materials_at(s)
    for name, F in model.solid.deformation_gradients(x).items():
        cells, mat = cells_of[name], materials[name]
        F3 = F if F.shape[-1] == 3 else _plane_strain_3d(F)
        J = np.linalg.det(F3)
        P = mat.evaluate(F3, tangent=False).stress
        sigma[cells] = (np.einsum("eqij,eqkj->eqik", P, F3) / J[..., None, None]).mean(axis=1)
        if name not in (MEMBRANE, STRAIN_LIMIT_LAYER):  # a gel
            swell[cells] = np.mean(mat.params.lambda0**3 * J, axis=1)
    dev = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3
    vm = np.sqrt(1.5 * np.einsum("eij,eij->e", dev, dev))
    out = {"body_id": model.body_id.astype(np.int32), "swelling_ratio": swell,
           "cauchy_stress": sigma, "von_mises_stress": vm}
    if model.chamber_gels:  # each chamber's gel told apart in the figures
        chamber = np.full(n, -1, dtype=np.int32)
        for k in range(len(model.chamber_gels)):
            chamber[cells_of[particle_block(k)]] = k
        out["chamber"] = chamber
    return out
