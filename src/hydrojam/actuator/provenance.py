"""What defines a run's result besides its design: the code's and its libraries' versions, the
thread settings and the seeds (metrics.json's ``provenance``). A frictionless particle column has
many equilibria and round-off picks one, so two runs of one design agree bit for bit only where
these agree too (docs/actuator.md, "Path dependence")."""

from __future__ import annotations

import os
import platform
import sys
from importlib import metadata

#: distributions whose version can change a result's last bits (solver, contact, mesh, kernels)
_PACKAGES = ("hydrojam", "numpy", "scipy", "ipctk", "gmsh", "pypardiso", "mkl", "numba", "meshio")

#: environment variables that set threads or switch code paths of the computation
_VARIABLES = ("HYDROJAM_SOLVER_THREADS", "HYDROJAM_IPC_THREADS", "HYDROJAM_REUSE_ANALYSIS", "HYDROJAM_COMPILED",
              "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OPENBLAS_CORETYPE")


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def run_provenance(replica: int = 0, seed: int | None = None) -> dict:
    """Versions (``versions``: package -> version, None where not installed), the Python and the
    machine (``python``, ``platform``), the thread and code-path variables as set (``environment``:
    name -> value, None where unset) and the seeds (``mesh_seed``: gmsh's random seed; ``seed``: the
    particles' perturbation seed of replica ``replica`` > 0, None for the design as drawn;
    ``replica``: the replica's index, design.replicas.index)."""
    from hydrojam.fem.meshing import RANDOM_SEED

    return {
        "versions": {name: _version(name) for name in _PACKAGES},
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "environment": {name: os.environ.get(name) for name in _VARIABLES},
        "mesh_seed": RANDOM_SEED,
        "seed": seed if replica > 0 else None,
        "replica": replica,
    }
