"""Shared helpers for the benchmark scripts: timing, growth-exponent fits and plain-text tables."""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from importlib import metadata
from pathlib import Path

import numpy as np


def median_time(
    fn: Callable[[], object], repeats: int = 3, warmup: int = 1, slow_s: float = 2.0
) -> tuple[float, object]:
    """Median wall time [s] of ``repeats`` calls of ``fn`` after ``warmup`` untimed calls, and the
    result of the last call. A call whose warm-up took longer than ``slow_s`` is timed once (its
    first-call overheads are negligible, and repeating it would blow the time budget)."""
    result = None
    t_warm = 0.0
    for _ in range(warmup):
        t0 = time.perf_counter()
        result = fn()
        t_warm = time.perf_counter() - t0
    times = []
    for _ in range(1 if t_warm > slow_s else repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), result


def growth_exponent(sizes: Sequence[float], times: Sequence[float | None]) -> float | None:
    """Least-squares slope of log(time) against log(size) over the entries that have a time;
    None with fewer than two."""
    pts = [(s, t) for s, t in zip(sizes, times) if t is not None and t > 0]
    if len(pts) < 2:
        return None
    s, t = np.log(np.array(pts)).T
    return float(np.polyfit(s, t, 1)[0])


def fmt(value: float | None, scale: float = 1.0, digits: int = 3) -> str:
    """``value * scale`` with ``digits`` significant digits (no exponent below 1e6); "-" for None."""
    if value is None:
        return "-"
    v = float(f"{value * scale:.{digits}g}")  # round first so 99.96 prints as 100, not 100.0
    if v == 0 or 1e-3 <= abs(v) < 1e6:
        decimals = max(0, digits - 1 - int(np.floor(np.log10(abs(v)))) if v else 0)
        return f"{v:.{decimals}f}"
    return f"{v:.{digits - 1}e}"


def fmt_slope(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def table(header: Sequence[str], rows: Sequence[Sequence[str]], left: int = 1) -> str:
    """Plain-text table: the first ``left`` columns left-aligned, the rest right-aligned."""
    cols = list(zip(header, *rows))
    widths = [max(len(c) for c in col) for col in cols]

    def line(cells):
        return "  ".join(c.ljust(w) if k < left else c.rjust(w) for k, (c, w) in enumerate(zip(cells, widths)))

    rule = "-" * len(line(header))
    return "\n".join([line(header), rule] + [line(r) for r in rows])


def section(title: str) -> None:
    print()
    print(title)
    print("=" * len(title))


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for row in f:
                if row.startswith("model name"):
                    return row.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "not installed"


def print_environment(packages: Sequence[str]) -> None:
    """Machine (platform, CPU model and count) and the versions of ``packages``."""
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"machine : {platform.platform()}, Python {platform.python_version()}")
    print(f"CPU     : {_cpu_model()}, {os.cpu_count()} logical CPUs ({usable} usable)")
    print("versions: " + ", ".join(f"{p} {_version(p)}" for p in packages))
    threads = {k: os.environ[k] for k in THREAD_VARIABLES if k in os.environ}
    shown = ", ".join(f"{k}={v}" for k, v in threads.items())
    print("threads : " + (shown or "library defaults (none of these variables set)"))
    print_load("load    ")


THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "HYDROJAM_SOLVER_THREADS")


def print_load(label: str = "load") -> None:
    """The 1-minute load average against the CPU count: timings taken on a busy machine are noisy."""
    if hasattr(os, "getloadavg"):
        print(f"{label}: load average {os.getloadavg()[0]:.2f} (1 min) on {os.cpu_count()} CPUs")


def page_parser(doc: str, tag: str) -> argparse.ArgumentParser:
    """The options of a benchmark that runs a hydrojam command on DESIGN.toml into OUT and writes
    its table into the section '<!-- TAG: NAME -->' of a docs page (docs/assess.md unless --page);
    the caller adds its own and passes the rest on to the command."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("design")
    parser.add_argument("-o", "--out", required=True)
    parser.add_argument("--section", required=True, help=f"the page's section: <!-- {tag}: NAME -->")
    parser.add_argument("--page", default=str(Path(__file__).resolve().parents[1] / "docs" / "assess.md"))
    return parser


def measured_by(script: str, argv: Sequence[str] | None) -> str:
    """The head of a table's line of conditions: "Measured by `benchmarks/SCRIPT ARGS`: code of
    `abc1234` [(with local changes)], N cores, T solver thread(s) a run" (``argv`` None: this
    process's arguments)."""
    from hydrojam.actuator.provenance import source_provenance

    src = source_provenance()
    commit = src["commit"][:7] if src["commit"] != "unknown" else "unknown"
    threads = os.environ.get("HYDROJAM_SOLVER_THREADS", "1")
    command = f"benchmarks/{script} " + " ".join(sys.argv[1:] if argv is None else argv)
    return (f"Measured by `{command}`: code of `{commit}`{' (with local changes)' if src['dirty'] is True else ''}, "
            f"{os.cpu_count()} cores, {threads} solver thread(s) a run")


def write_section(page: str | os.PathLike, tag: str, name: str, text: str) -> None:
    """Replace the section '<!-- TAG: NAME -->' of the Markdown ``page`` by ``text`` (path.replace_section),
    writing the page atomically."""
    from path import replace_section

    from hydrojam._io import write_text_atomic

    page = Path(page)
    write_text_atomic(page, replace_section(page.read_text(encoding="utf-8"), name, text, tag=tag))
