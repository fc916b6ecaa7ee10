"""Environment variables that tune the FE core, read and validated in one place."""

from __future__ import annotations

import functools
import os


def positive_int(name: str, default: int) -> int:
    """The positive integer in environment variable ``name`` (``default`` when unset); a
    ValueError naming the variable and the allowed values for anything else (abc, 0, -1)."""
    raw = os.environ.get(name)
    if raw is None:
        return default
    try:
        value = int(raw.strip())
    except ValueError:
        value = 0
    if value < 1:
        raise ValueError(f"{name} must be a positive integer (1, 2, ...); got {raw!r}")
    return value


def flag(name: str, default: bool) -> bool:
    """The switch in environment variable ``name``: "1" on, "0" off (``default`` when unset); a
    ValueError naming the variable and the allowed values for anything else."""
    raw = os.environ.get(name)
    if raw is None:
        return default
    if raw.strip() not in ("0", "1"):
        raise ValueError(f"{name} must be 0 or 1; got {raw!r}")
    return raw.strip() == "1"


#: every thread count hydrojam reads from the environment (positive integers, default 1)
THREAD_VARIABLES = ("HYDROJAM_SOLVER_THREADS", "HYDROJAM_IPC_THREADS", "HYDROJAM_BLAS_THREADS")
#: every switch it reads (0 or 1)
SWITCH_VARIABLES = ("HYDROJAM_REUSE_ANALYSIS", "HYDROJAM_COMPILED")


def check_environment() -> None:
    """Validate every variable hydrojam reads from the environment at once, before any work
    (the solver reads each only when it is built): a ValueError naming the first invalid one
    and its allowed values."""
    for name in THREAD_VARIABLES:
        positive_int(name, 1)
    for name in SWITCH_VARIABLES:
        flag(name, True)


#: the BLAS libraries that numpy and SciPy may load (threadpoolctl's names); MKL is not among
#: them: its threads are PARDISO's, set per handle by ``HYDROJAM_SOLVER_THREADS`` (linsolve.py)
_BLAS = ["openblas", "blis", "flexiblas"]
_controller = None


def limited_blas():
    """A context in which numpy's and SciPy's BLAS run on ``HYDROJAM_BLAS_THREADS`` threads (a
    positive integer, default 1), their setting restored on exit.

    Why: OpenBLAS threads the dot products of vectors above about 10k entries (the norms of a 3D
    residual), and beside another busy process (a sweep's second worker) each such call then
    waits for a thread the scheduler has not run yet: two 3D runs at once took 1.8x longer a
    Newton iteration with OpenBLAS's default threads (docs/solver.md, "3D: ordering, threads").
    The libraries are found once, at the first call (numpy's and SciPy's are loaded by then)."""
    global _controller
    threads = positive_int("HYDROJAM_BLAS_THREADS", 1)
    if _controller is None:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController().select(internal_api=_BLAS)
    return _controller.limit(limits=threads)


def blas_limited(function):
    """``function`` run inside :func:`limited_blas` (a decorator)."""

    @functools.wraps(function)
    def limited(*args, **kwargs):
        with limited_blas():
            return function(*args, **kwargs)

    return limited
