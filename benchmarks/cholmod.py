"""PARDISO against CHOLMOD (SuiteSparse's supernodal Cholesky) on the definite linear systems of a
3D run, replayed call by call on the CPU.

Run:  .venv/bin/python benchmarks/cudss.py record FILE --design default_3d --calls 200
      .venv/bin/python benchmarks/cholmod.py FILE [--systems N] [--ordering metis|amd|default]

``FILE`` is a record of PARDISO's calls (``cudss.py record``: the upper triangle on hydrojam's
union pattern, the values PARDISO factorised, the right-hand side, whether the call analysed a
new pattern and whether the Cholesky refused the matrix). Every Cholesky call (the definite
solves of the inertia correction) is replayed, interleaved, through

- "PARDISO single": PARDISO's Cholesky in single precision, refined in double to 1e-8 in at
  most 6 substitutions, ``LinearSolver``'s target and limit (hydrojam's solver for these systems),
- "PARDISO double": PARDISO's Cholesky in double,
- "CHOLMOD metis" (or the ``--ordering`` given): CHOLMOD's supernodal Cholesky in double
  (scikit-sparse), where it is installed,

each with an analysis (a fresh fill-reducing ordering) wherever the recording analysed and a
refactorisation on that analysis otherwise. It prints a line a system and, per solver, the ms of
a system on a new pattern (analysis, factorisation and substitutions), of one on the pattern
analysed (factorisation and substitutions, the refused ones left out), the mean per system, the
refusals, the largest relative residual ||K x - b|| / ||b|| and the mean factor entries. One
thread for MKL and for the BLAS.

CHOLMOD is not a dependency of hydrojam. On Debian 12: ``apt-get install libsuitesparse-dev
libopenblas0-pthread`` (SuiteSparse 5.12 on OpenBLAS, instead of the unoptimised reference BLAS),
then ``.venv/bin/pip install "scikit-sparse<0.5"`` (0.5 builds against SuiteSparse 7 only). The
values recorded for PARDISO's single-precision calls are single precision: every solver gets
them, in its own precision.

Reading the numbers: compare the columns of one run (one machine, one load); the refusals and
the factor sizes are exact.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cudss import _full, _load, refine  # noqa: E402

from hydrojam.fem.solver import linsolve  # noqa: E402


class _PardisoCholesky:
    """PARDISO's Cholesky on one handle, in single (refined in double) or in double precision."""

    def __init__(self, single: bool):
        self.single, self.handle, self.pattern = single, None, None

    def run(self, key, ia, ja, values, b, K) -> tuple[float, float, np.ndarray | None, int]:
        """(analysis s, factorisation and solve s, x or None where refused, factor entries)."""
        dtype = np.float32 if self.single else np.float64
        t = time.perf_counter()
        new = key != self.pattern
        if new:
            if self.handle is not None:
                self.handle.release()
            self.handle, self.pattern = linsolve._Pardiso(1, 2, single=self.single), key
        try:
            x = self.handle.solve(values.astype(dtype), ia, ja, b.astype(dtype), reuse_analysis=not new)
        except self.handle.error:
            x = None
        if x is not None and self.single:
            x, _ = refine(lambda r: self.handle.resolve(r.astype(dtype)).astype(np.float64), K, b, x)
        elapsed = time.perf_counter() - t
        # PARDISO's phase 13 analyses and factorises in one call: its split is not known here
        return (elapsed, 0.0) if new else (0.0, elapsed), x, self.handle.factor_entries()


class _Cholmod:
    """CHOLMOD's supernodal Cholesky in double, analysed once a pattern."""

    def __init__(self, ordering: str):
        from sksparse import cholmod

        self.cholmod, self.ordering, self.factor, self.pattern = cholmod, ordering, None, None

    def run(self, key, ia, ja, values, b, K):
        n = len(ia) - 1
        lower = sp.csr_matrix((values.astype(np.float64), ja - 1, ia - 1), shape=(n, n)).T.tocsc()
        t = time.perf_counter()
        if key != self.pattern:
            self.factor = self.cholmod.analyze(lower, mode="supernodal", ordering_method=self.ordering)
            self.pattern = key
        analysis = time.perf_counter() - t
        t = time.perf_counter()
        try:
            self.factor.cholesky_inplace(lower)
            x = self.factor(b)
        except self.cholmod.CholmodNotPositiveDefiniteError:
            x = None
        entries = self.factor.L().nnz if x is not None else 0
        return (analysis, time.perf_counter() - t), x, entries


def replay(path: str, systems: int | None = None, ordering: str = "metis") -> dict[str, list[dict]]:
    """Replay the Cholesky calls of the record ``path`` (the first ``systems``) through every
    solver; print a line a system and a summary per solver; return the rows per solver."""
    meta, z = _load(path)
    calls = [m for m in meta if m["mtype"] == 2][:systems]
    solvers = {"PARDISO single": _PardisoCholesky(True), "PARDISO double": _PardisoCholesky(False)}
    try:
        solvers[f"CHOLMOD {ordering}"] = _Cholmod(ordering)
    except ImportError:
        print("scikit-sparse is not installed: PARDISO only (see this script's docstring)")
    rows: dict[str, list[dict]] = {name: [] for name in solvers}
    print(f"{path}: {len(calls)} Cholesky calls, {sum(m['new'] for m in calls)} on a new pattern, "
          f"{sum(not m.get('ok', False) for m in calls)} refused by PARDISO when recorded")
    with threadpool_limits(1):
        for m in calls:
            ia, ja = z[f"ia{m['pattern']}"], z[f"ja{m['pattern']}"]
            values, b = np.asarray(z[f"val{m['i']}"]), np.asarray(z[f"rhs{m['i']}"], dtype=np.float64)
            K = _full(ia, ja, values)
            line = [f"{m['i']:4d}{' new' if m['new'] else '    '}"]
            for name, solver in solvers.items():
                (analysis, factor), x, entries = solver.run(m["pattern"], ia, ja, values, b, K)
                residual = None if x is None else float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))
                rows[name].append(dict(new=m["new"], analysis=1e3 * analysis, factor=1e3 * factor,
                                       refused=x is None, residual=residual, entries=entries))
                line.append(f"{name}: {1e3 * (analysis + factor):6.1f} ms{' refused' if x is None else ''}")
            print(" | ".join(line), flush=True)
    print(f"\n{'solver':16s} {'new pattern':>14s} {'same pattern':>14s} {'per system':>11s} "
          f"{'refused':>8s} {'max residual':>13s} {'factor entries':>15s}")
    for name, r in rows.items():
        new = [x["analysis"] + x["factor"] for x in r if x["new"]]
        again = [x["factor"] for x in r if not x["new"] and not x["refused"]]
        residuals = [x["residual"] for x in r if x["residual"] is not None]
        entries = [x["entries"] for x in r if x["entries"]]
        print(f"{name:16s} {np.mean(new) if new else np.nan:11.1f} ms {np.mean(again) if again else np.nan:11.1f} ms "
              f"{np.mean([x['analysis'] + x['factor'] for x in r]):8.1f} ms {sum(x['refused'] for x in r):8d} "
              f"{max(residuals) if residuals else np.nan:13.1e} {np.mean(entries) / 1e6 if entries else np.nan:13.2f} M")
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("file", help="a record of cudss.py record")
    parser.add_argument("--systems", type=int, default=None, help="replay the first N Cholesky calls only")
    parser.add_argument("--ordering", default="metis", choices=["metis", "amd", "default"],
                        help="CHOLMOD's fill-reducing ordering")
    args = parser.parse_args(argv)
    replay(args.file, args.systems, args.ordering)


if __name__ == "__main__":
    main()
