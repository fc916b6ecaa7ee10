"""PARDISO against NVIDIA cuDSS (a GPU sparse direct solver) on the linear systems of a 3D run,
replayed call by call.

Run:  .venv/bin/python benchmarks/cudss.py record FILE [--design NAME] [--calls N] [--pick I,J,...]
      python benchmarks/cudss.py replay FILE      (on a machine with an NVIDIA GPU)

``record`` (CPU) simulates the design (``default_3d``: the default design in 3D at the 4 mm mesh,
22 324 unknowns; ``default_3d_2mm``: at its own 2 mm mesh, 88 078) and stores PARDISO's calls
as hydrojam makes them, until ``--calls`` calls: each factorisation's upper triangle (1-based
CSR, the union pattern with its explicit zeros, the values in the precision PARDISO factorised),
its right-hand side, whether it analysed a new pattern, whether PARDISO's Cholesky refused it
(not positive definite), and PARDISO's own time for it (``_Pardiso.solve``: an analysis,
factorisation and substitution, or a factorisation and substitution). ``--pick`` keeps those
calls only (the analysis in force at each is stored with it), so that the file stays small
enough to carry; the whole file is one lzma-compressed .npz.

``replay`` (GPU; needs the ``gpu-bench`` extra, ``cupy-cuda13x`` and ``nvidia-cudss-cu13`` 0.7 or
0.8, or ``HYDROJAM_CUDSS_LIB`` naming libcudss.so.0) replays the same sequence through cuDSS's C
interface, as PARDISO saw it: an analysis (reordering and symbolic factorisation, on the host)
wherever PARDISO analysed, a factorisation after it, refactorisations of the same pattern after
that, then the solve. It prints a line per system and a summary per variant: Cholesky in double,
Cholesky in single refined in double against the double matrix to 1e-8 (as hydrojam refines
PARDISO's), with 2 host threads for the analysis; and the LDL^T with its inertia on the first
system. Times are wall times around each phase with the device synchronised, the host-to-device
copy of the values apart.

Reading the numbers: the PARDISO column is the recording machine's (a 2-core CPU in
docs/benchmarks.md), the cuDSS columns the GPU machine's; both are exact about which phase ran.
A Cholesky that cuDSS refuses reports the pivot where it stopped (``info``).
"""

from __future__ import annotations

import argparse
import ctypes
import glob
import io
import json
import lzma
import os
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))

DESIGNS = {"default_3d": ["dimension=3", "mesh.size=4"], "default_3d_2mm": ["dimension=3"]}


# --- record (CPU) -------------------------------------------------------------------------------

class _Enough(Exception):
    """Stops the simulation once the calls wanted are recorded."""


class Recorder:
    """Wraps ``_Pardiso.solve`` while installed: every call's row (``meta``) and, for the calls
    kept (``pick``, None: all), its values, right-hand side and the pattern in force (``arrays``).
    Raises ``_Enough`` at call number ``calls``."""

    def __init__(self, calls: int | None = None, pick: set[int] | None = None):
        self.calls, self.pick = calls, pick
        self.meta: list[dict] = []
        self.arrays: dict[str, np.ndarray] = {}
        self._handles: dict[int, int] = {}
        self._patterns: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}  # handle -> (call, ia, ja)
        self._original = None

    def install(self) -> None:
        from hydrojam.fem.solver import linsolve

        self._original = original = linsolve._Pardiso.solve
        recorder = self

        def solve(pardiso, data, ia, ja, b, reuse_analysis, ordering=None, keep_ordering=False):
            i = len(recorder.meta)
            if recorder.calls is not None and i >= recorder.calls:
                raise _Enough
            h = recorder._handles.setdefault(id(pardiso), len(recorder._handles))
            if not reuse_analysis:
                recorder._patterns[h] = (i, np.array(ia, dtype=np.int32), np.array(ja, dtype=np.int32))
            row = dict(i=i, handle=h, mtype=pardiso.mtype, single=bool(pardiso.single), new=not reuse_analysis,
                       n=len(ia) - 1, nnz=len(ja), pattern=recorder._patterns[h][0])
            t = time.perf_counter()
            try:
                x = original(pardiso, data, ia, ja, b, reuse_analysis, ordering, keep_ordering)
                row["ok"] = True
                return x
            except pardiso.error:  # PARDISO's own error (a refused Cholesky), before LinearSolver wraps it
                row["ok"] = False
                raise
            finally:
                row["pardiso_ms"] = 1e3 * (time.perf_counter() - t)
                row["factor_entries"] = pardiso.factor_entries()
                recorder.meta.append(row)
                if recorder.kept(i):
                    p, pia, pja = recorder._patterns[h]
                    recorder.arrays.setdefault(f"ia{p}", pia)
                    recorder.arrays.setdefault(f"ja{p}", pja)
                    recorder.arrays[f"val{i}"] = np.array(data, dtype=np.float32 if pardiso.single else np.float64)
                    recorder.arrays[f"rhs{i}"] = np.array(b, dtype=np.float64)

        linsolve._Pardiso.solve = solve

    def kept(self, i: int) -> bool:
        """Whether call ``i``'s arrays are kept (``pick``)."""
        return self.pick is None or i in self.pick

    def uninstall(self) -> None:
        from hydrojam.fem.solver import linsolve

        linsolve._Pardiso.solve = self._original

    def save(self, path: str) -> list[dict]:
        """Write the calls kept to ``path`` (one lzma-compressed .npz); their rows."""
        kept = [m for m in self.meta if self.kept(m["i"])]
        buffer = io.BytesIO()
        np.savez(buffer, meta=np.array(json.dumps(kept)), **self.arrays)
        Path(path).write_bytes(lzma.compress(buffer.getvalue(), preset=6))
        return kept


def record(path: str, design_name: str, calls: int, pick: set[int] | None) -> None:
    """Simulate ``design_name`` and store PARDISO's first ``calls`` calls (those in ``pick``) in ``path``."""
    from _common import print_environment
    from hydrojam import build_model, default_design, simulate
    from hydrojam.actuator.design import apply_overrides

    print_environment(["numpy", "scipy", "pypardiso", "mkl"])
    recorder = Recorder(calls, pick)
    recorder.install()
    try:
        simulate(build_model(apply_overrides(default_design(), DESIGNS[design_name])))
    except _Enough:
        pass
    finally:
        recorder.uninstall()
    kept = recorder.save(path)
    print(f"{design_name}: {len(recorder.meta)} PARDISO calls, {len(kept)} kept in {path} "
          f"({Path(path).stat().st_size / 1e6:.1f} MB); PARDISO {np.mean([m['pardiso_ms'] for m in kept]):.1f} ms a call")


# --- replay (GPU) -------------------------------------------------------------------------------

# cuDSS 0.7/0.8 (cudss.h): data types, matrix types and views, phases, configuration and data keys
R32F, R64F, R32I = 0, 1, 10
MTYPE_SYMMETRIC, MTYPE_SPD, MVIEW_UPPER, BASE_ONE, COL_MAJOR = 1, 3, 2, 1, 0
ANALYSIS, FACTORIZATION, REFACTORIZATION, SOLVE = 0x3, 0x4, 0x8, 0x3F0
CONFIG_HOST_NTHREADS = 15
DATA_INFO, DATA_LU_NNZ, DATA_INERTIA = 0, 1, 3


def _cudss():
    """libcudss (ctypes) and cupy, or SystemExit with what is missing."""
    try:
        import cupy
    except ImportError:
        raise SystemExit("replay needs cupy (pip install -e '.[gpu-bench]') and an NVIDIA GPU") from None
    for name in ("libcublasLt.so.13", "libcublas.so.13"):
        try:
            ctypes.CDLL(name, mode=ctypes.RTLD_GLOBAL)
            continue
        except OSError:
            pass
        roots = [os.environ.get("CUDA_PATH", "/usr/local/cuda"), "/usr/local", sys.prefix]
        found = [f for r in roots for f in sorted(glob.glob(f"{r}/**/{name}", recursive=True))]
        if found:
            ctypes.CDLL(found[0], mode=ctypes.RTLD_GLOBAL)
    lib = os.environ.get("HYDROJAM_CUDSS_LIB")
    if not lib:
        try:
            import nvidia.cu13  # a namespace package: the CUDA 13 wheels' folders
            found = [Path(p) / "lib" / "libcudss.so.0" for p in nvidia.cu13.__path__]
            lib = str(next(f for f in found if f.exists()))
        except (ImportError, StopIteration):
            raise SystemExit("replay needs cuDSS: pip install -e '.[gpu-bench]', "
                             "or HYDROJAM_CUDSS_LIB=/path/to/libcudss.so.0") from None
    return ctypes.CDLL(lib), cupy


class _CuDSS:
    """One cuDSS solver (handle, configuration, data) on the device for one pattern at a time."""

    def __init__(self, lib, cupy, mtype: int, dtype, host_threads: int = 0):
        self.L, self.cp, self.mtype, self.dtype = lib, cupy, mtype, dtype
        self.value_type = R32F if dtype == np.float32 else R64F
        self.h, self.cfg, self.data, self.A = ctypes.c_void_p(), ctypes.c_void_p(), None, None
        self._check(lib.cudssCreate(ctypes.byref(self.h)), "create")
        self._check(lib.cudssConfigCreate(ctypes.byref(self.cfg)), "configuration")
        if host_threads:
            mt = Path(lib._name).with_name("libcudss_mtlayer_gomp.so.0")
            self._check(lib.cudssSetThreadingLayer(self.h, str(mt).encode()), "threading layer")
            v = ctypes.c_int(host_threads)
            self._check(lib.cudssConfigSet(self.cfg, CONFIG_HOST_NTHREADS, ctypes.byref(v), 4), "host threads")
        self.factorised = False

    @staticmethod
    def _check(status: int, what: str) -> None:
        if status != 0:
            raise RuntimeError(f"cuDSS {what}: status {status}")

    def _sync(self) -> None:
        self.cp.cuda.Device().synchronize()

    def analyse(self, ia, ja, values) -> float:
        """A new pattern: its analysis on the host [s]."""
        L, cp, vp = self.L, self.cp, ctypes.c_void_p
        if self.data is not None:
            L.cudssMatrixDestroy(self.A)
            L.cudssDataDestroy(self.h, self.data)
        self.data = vp()
        self._check(L.cudssDataCreate(self.h, ctypes.byref(self.data)), "data")
        n = len(ia) - 1
        self.ia, self.ja = cp.asarray(ia, dtype=cp.int32), cp.asarray(ja, dtype=cp.int32)
        self.v = cp.asarray(values, dtype=self.dtype)
        self.b, self.x = cp.zeros(n, dtype=self.dtype), cp.zeros(n, dtype=self.dtype)
        self.A, self.B, self.X = vp(), vp(), vp()
        self._check(L.cudssMatrixCreateCsr(ctypes.byref(self.A), ctypes.c_int64(n), ctypes.c_int64(n), ctypes.c_int64(len(ja)),
                                           vp(self.ia.data.ptr), None, vp(self.ja.data.ptr), vp(self.v.data.ptr),
                                           R32I, self.value_type, self.mtype, MVIEW_UPPER, BASE_ONE), "matrix")
        for m, a in ((self.B, self.b), (self.X, self.x)):
            self._check(L.cudssMatrixCreateDn(ctypes.byref(m), ctypes.c_int64(n), ctypes.c_int64(1), ctypes.c_int64(n),
                                              vp(a.data.ptr), self.value_type, COL_MAJOR), "vector")
        self.factorised = False
        t = time.perf_counter()
        self._check(self._execute(ANALYSIS), "analysis")
        self._sync()
        return time.perf_counter() - t

    def _execute(self, phase: int) -> int:
        return self.L.cudssExecute(self.h, phase, self.cfg, self.data, self.A, self.X, self.B)

    def factorise(self, values) -> tuple[float, float, int]:
        """(host-to-device copy [s], factorisation [s], cuDSS's info: 0, or the pivot where a
        Cholesky stopped): a refactorisation after a successful one."""
        t0 = time.perf_counter()
        self.v.set(np.asarray(values, dtype=self.dtype))
        self._sync()
        t1 = time.perf_counter()
        self._check(self._execute(REFACTORIZATION if self.factorised else FACTORIZATION), "factorisation")
        self._sync()
        t2 = time.perf_counter()
        info = self.info()
        self.factorised = info == 0
        return t1 - t0, t2 - t1, info

    def solve(self, b) -> tuple[np.ndarray, float]:
        """The solution for b, in double, and the time of copy, substitution and copy back [s]."""
        t = time.perf_counter()
        self.b.set(np.asarray(b, dtype=self.dtype))
        self._check(self._execute(SOLVE), "solve")
        x = self.cp.asnumpy(self.x)
        return x.astype(np.float64), time.perf_counter() - t

    def _get(self, key: int, value) -> None:
        written = ctypes.c_size_t()
        self._check(self.L.cudssDataGet(self.h, self.data, key, ctypes.byref(value), ctypes.sizeof(value),
                                        ctypes.byref(written)), "data get")

    def info(self) -> int:
        v = ctypes.c_int()
        self._get(DATA_INFO, v)
        return v.value

    def factor_entries(self) -> int:
        v = ctypes.c_int64()
        self._get(DATA_LU_NNZ, v)
        return v.value

    def inertia(self) -> tuple[int, int]:
        v = (ctypes.c_int * 2)()
        self._get(DATA_INERTIA, v)
        return v[0], v[1]


def _load(path: str):
    z = np.load(io.BytesIO(lzma.decompress(Path(path).read_bytes())))
    return json.loads(str(z["meta"])), z


# LinearSolver.refinement_tolerance and refinement_steps, as literals: the GPU replay runs
# without importing hydrojam
REFINE_TO, REFINE_STEPS = 1e-8, 6


def refine(solve, K, b: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, int]:
    """x refined in double against K to LinearSolver's target and step limit: x += solve(b - K x)
    while ||K x - b|| > REFINE_TO ||b||, at most REFINE_STEPS times (LinearSolver also stops
    where a step does not halve the residual); (x, the substitutions made)."""
    steps, target = 0, REFINE_TO * np.linalg.norm(b)
    while np.linalg.norm(K @ x - b) > target and steps < REFINE_STEPS:
        x, steps = x + solve(b - K @ x), steps + 1
    return x, steps


def _full(ia, ja, values) -> sp.csr_matrix:
    upper = sp.csr_matrix((np.asarray(values, dtype=np.float64), ja - 1, ia - 1), shape=(len(ia) - 1,) * 2)
    return upper + sp.triu(upper, 1).T


def replay_sequence(lib, cupy, meta, z, label: str, dtype, host_threads: int = 0) -> None:
    """Replay the recorded calls through one cuDSS Cholesky; print a line a system and a summary."""
    solver = _CuDSS(lib, cupy, MTYPE_SPD, dtype, host_threads)
    rows, current = [], None
    for m in meta:
        values, b = z[f"val{m['i']}"], z[f"rhs{m['i']}"]
        ia, ja = z[f"ia{m['pattern']}"], z[f"ja{m['pattern']}"]
        t_analysis = 0.0
        if m["pattern"] != current:
            t_analysis, current = solver.analyse(ia, ja, values), m["pattern"]
        t_copy, t_factor, info = solver.factorise(values)
        x, t_solve = solver.solve(b)
        K = _full(ia, ja, values)
        steps = 0
        if info == 0:
            t = time.perf_counter()
            x, steps = refine(lambda r: solver.solve(r)[0], K, b, x)
            t_solve += time.perf_counter() - t
        residual = np.linalg.norm(K @ x - b) / np.linalg.norm(b)
        rows.append(dict(i=m["i"], analysis=1e3 * t_analysis, copy=1e3 * t_copy, factor=1e3 * t_factor,
                         solve=1e3 * t_solve, info=info, pardiso_ok=m.get("ok", False), residual=residual if info == 0 else None,
                         refinement=steps, factor_entries=solver.factor_entries(), pardiso=m["pardiso_ms"]))
    print(f"\n== {label}")
    for r in rows:
        print("  " + " ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items()), flush=True)
    analysed = [r["analysis"] for r in rows if r["analysis"] > 0]
    total = np.mean([r["analysis"] + r["copy"] + r["factor"] + r["solve"] for r in rows])
    print(f"  {label}: {len(rows)} systems, {len(analysed)} analyses of {np.mean(analysed):.1f} ms, factorisation "
          f"{np.mean([r['factor'] for r in rows]):.1f} ms, solve {np.mean([r['solve'] for r in rows]):.1f} ms, copy "
          f"{np.mean([r['copy'] for r in rows]):.1f} ms: {total:.1f} ms a system against PARDISO's "
          f"{np.mean([r['pardiso'] for r in rows]):.1f} ms; refused: cuDSS {sum(r['info'] != 0 for r in rows)}, "
          f"PARDISO {sum(not r['pardiso_ok'] for r in rows)}", flush=True)


def replay(path: str) -> None:
    """Replay a recorded sequence through cuDSS's variants."""
    lib, cupy = _cudss()
    version = [ctypes.c_int() for _ in range(3)]
    for k, v in enumerate(version):
        lib.cudssGetProperty(k, ctypes.byref(v))
    props = cupy.cuda.runtime.getDeviceProperties(0)
    print(f"cuDSS {'.'.join(str(v.value) for v in version)}, GPU {props['name'].decode()}, host CPUs {os.cpu_count()}")
    meta, z = _load(path)
    definite = [m for m in meta if m["mtype"] == 2]  # the Newton solver's Cholesky calls
    print(f"{path}: {len(meta)} systems of {meta[0]['n']} unknowns, {len(definite)} of them PARDISO's Cholesky")
    meta = definite
    m = meta[0]
    ldlt = _CuDSS(lib, cupy, MTYPE_SYMMETRIC, np.float64)
    t_a = ldlt.analyse(z[f"ia{m['pattern']}"], z[f"ja{m['pattern']}"], z[f"val{m['i']}"])
    _, t_f, _ = ldlt.factorise(z[f"val{m['i']}"])
    print(f"LDL^T of system {m['i']}: analysis {1e3 * t_a:.0f} ms, factorisation {1e3 * t_f:.1f} ms, "
          f"inertia (positive, negative) {ldlt.inertia()}")
    replay_sequence(lib, cupy, meta, z, "warm-up, Cholesky in double", np.float64)
    replay_sequence(lib, cupy, meta, z, "Cholesky in double", np.float64)
    replay_sequence(lib, cupy, meta, z, "Cholesky in single, refined in double", np.float32)
    replay_sequence(lib, cupy, meta, z, "Cholesky in double, 2 host threads", np.float64, host_threads=2)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("record", help="simulate and store PARDISO's calls (CPU)")
    r.add_argument("file")
    r.add_argument("--design", choices=list(DESIGNS), default="default_3d")
    r.add_argument("--calls", type=int, default=200, help="PARDISO calls to run (default 200)")
    r.add_argument("--pick", help="comma-separated call numbers to keep (default: all)")
    g = sub.add_parser("replay", help="replay a stored sequence through cuDSS (GPU)")
    g.add_argument("file")
    args = p.parse_args(argv)
    if args.command == "record":
        pick = None if not args.pick else {int(i) for i in args.pick.split(",")}
        record(args.file, args.design, args.calls, pick)
    else:
        replay(args.file)


if __name__ == "__main__":
    main()
