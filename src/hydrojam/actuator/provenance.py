"""What defines a run's result besides its design: the code's and its libraries' versions, the
source commit, the CPU and the instruction set MKL dispatches to, the thread settings and the
seeds (metrics.json's ``provenance``). A frictionless particle column has
many equilibria and round-off picks one, so two runs of one design agree bit for bit only where
these agree too (docs/actuator.md, "Path dependence")."""

from __future__ import annotations

import ctypes
import glob
import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path

from hydrojam.fem._env import SWITCH_VARIABLES, THREAD_VARIABLES

#: distributions whose version can change a result's last bits (solver, contact, mesh, kernels)
_PACKAGES = ("hydrojam", "numpy", "scipy", "ipctk", "gmsh", "pypardiso", "mkl", "numba", "meshio")

#: environment variables that set threads or switch code paths of the computation
_VARIABLES = (*THREAD_VARIABLES, *SWITCH_VARIABLES, "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS",
              "OPENBLAS_CORETYPE", "MKL_CBWR", "MKL_ENABLE_INSTRUCTIONS")


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


#: what a lookup that failed records (never an error: provenance must not fail a run)
UNKNOWN = "unknown"

#: MKL's code branches (mkl_service.h, MKL_CBWR_*): what MKL_CBWR_Get_Auto_Branch returns
_MKL_BRANCHES = {1: "OFF", 2: "AUTO", 3: "COMPATIBLE", 4: "SSE2", 5: "SSE3", 6: "SSSE3", 7: "SSE4_1",
                 8: "SSE4_2", 9: "AVX", 10: "AVX2", 11: "AVX512_MIC", 12: "AVX512", 13: "AVX512_MIC_E1",
                 14: "AVX512_E1"}


def source_provenance() -> dict:
    """The source the running hydrojam was imported from: ``commit`` (the git commit's 40 hex
    digits) and ``dirty`` (True where tracked files differ from it) when the package is a tracked
    file of a git checkout (an editable install), else "unknown" for both (an installed wheel, no
    git). Each git call is bounded by 10 s; any failure gives "unknown"."""
    try:
        here = Path(__file__).resolve()
        root = here.parent

        def git(*args):
            return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=10,
                                  check=True).stdout.strip()

        git("ls-files", "--error-unmatch", here.name)  # a tracked file, not a copy in a venv inside a checkout
        commit = git("rev-parse", "HEAD")
        dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
        return {"commit": commit, "dirty": dirty}
    except Exception:  # noqa: BLE001 - no git, not a checkout, a timeout: unknown, never a failed run
        return {"commit": UNKNOWN, "dirty": UNKNOWN}


def cpu_model() -> str:
    """The CPU's model name (Linux: /proc/cpuinfo's "model name"; elsewhere platform.processor()),
    "unknown" where neither tells."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith(("model name", "Model", "cpu model")):
                    return line.split(":", 1)[1].strip() or UNKNOWN
    except OSError:
        pass
    try:
        return platform.processor() or UNKNOWN
    except Exception:  # noqa: BLE001
        return UNKNOWN


def _mkl_library():
    """The loaded MKL runtime (pypardiso's own, else libmkl_rt found on the path or in the
    environment), or None."""
    try:
        from pypardiso.scipy_aliases import pypardiso_solver

        lib = getattr(pypardiso_solver, "libmkl", None)
        if lib is not None:
            return lib
    except Exception:  # noqa: BLE001
        pass
    from ctypes.util import find_library

    for path in [find_library("mkl_rt"), *sorted(glob.glob(f"{sys.prefix}/lib*/**/libmkl_rt*", recursive=True), key=len)]:
        if path:
            try:
                return ctypes.CDLL(path)
            except OSError:
                continue
    return None


def mkl_provenance() -> dict:
    """MKL's code path: ``instruction_set``, the branch it dispatches to on this CPU (e.g.
    "AVX2", "AVX512_E1": the CBWR branch set with MKL_CBWR, else the one MKL picks itself),
    ``cbwr`` (the conditional numerical reproducibility branch set, "OFF" when none) and
    ``version`` (MKL's version string). "unknown" for each where MKL is not loaded or does not
    tell; never an error."""
    result = {"instruction_set": UNKNOWN, "cbwr": UNKNOWN, "version": UNKNOWN}
    try:
        lib = _mkl_library()
        if lib is None:
            return result
        buf = ctypes.create_string_buffer(256)
        lib.MKL_Get_Version_String(buf, ctypes.c_int(len(buf)))
        result["version"] = buf.value.decode("ascii", "replace").strip() or UNKNOWN
        get, auto = lib.MKL_CBWR_Get, lib.MKL_CBWR_Get_Auto_Branch
        get.restype, get.argtypes, auto.restype = ctypes.c_int, [ctypes.c_int], ctypes.c_int
        branch = get(1)  # MKL_CBWR_BRANCH
        result["cbwr"] = _MKL_BRANCHES.get(branch, f"{branch}")
        chosen = auto() if branch in (1, 2) else branch  # off or AUTO: MKL picks the branch itself
        # on some CPUs (seen on AMD EPYC) MKL's auto branch is AUTO itself: it does not tell
        result["instruction_set"] = UNKNOWN if chosen in (1, 2) else _MKL_BRANCHES.get(chosen, f"{chosen}")
    except Exception:  # noqa: BLE001 - an old MKL without these functions: unknown
        pass
    return result


def machine_provenance() -> dict:
    """The machine: ``cpu`` (model name), ``cpu_count`` (logical CPUs) and ``mkl``
    (:func:`mkl_provenance`)."""
    return {"cpu": cpu_model(), "cpu_count": os.cpu_count(), "mkl": mkl_provenance()}


def run_provenance(replica: int = 0, seed: int | None = None) -> dict:
    """Versions (``versions``: package -> version, None where not installed), the Python and the
    machine (``python``, ``platform``), the source (``source``: :func:`source_provenance`, commit
    and dirty flag), the CPU and MKL's dispatch (``machine``: :func:`machine_provenance`), the
    thread and code-path variables as set (``environment``:
    name -> value, None where unset) and the seeds (``mesh_seed``: gmsh's random seed; ``seed``: the
    particles' perturbation seed of replica ``replica`` > 0, None for the design as drawn;
    ``replica``: the replica's index, design.replicas.index)."""
    from hydrojam.fem.meshing import RANDOM_SEED

    return {
        "versions": {name: _version(name) for name in _PACKAGES},
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "source": source_provenance(),
        "machine": machine_provenance(),
        "environment": {name: os.environ.get(name) for name in _VARIABLES},
        "mesh_seed": RANDOM_SEED,
        "seed": seed if replica > 0 else None,
        "replica": replica,
    }
