"""Mesh convergence of a design: its replicas at several element sizes, and the coarsest mesh whose
answer lies within the finest's.

Run:  .venv/bin/python benchmarks/mesh.py [--design DESIGN.toml] [--set FIELD=VALUE ...]
          --sizes 4 3 2 --replicas 3 2 2 --root ROOT [--report-only] [--workers N]
          [--markdown FILE --section NAME]

The design is the default one (or DESIGN.toml) with the ``--set`` overrides, e.g. ``--set
dimension=3`` for the 3D default. Each size S runs it as ``hydrojam run DESIGN.toml -o ROOT/mesh-S
--set mesh.size=S --replicas N``
(:func:`hydrojam.study.replicas.run_replicas`: cached and resumable, so an interrupted size goes on
where it stopped; ``--report-only`` runs nothing and reads what the folders hold). Per size it
prints, and with ``--markdown`` writes into the page's marked section, the runs' states, the angle,
the tip, the curling index as mean ± std over the runs that finished, the Newton iterations and the
wall time a run.

The rule (docs/actuator.md, "Mesh convergence"): a size qualifies when, for each of θ, δx, δz and
the curling index, its mean lies within the finest size's mean ± 2 s, s the larger of the two
sizes' standard deviations over their replicas (the answer's own spread; two runs estimate it
poorly, so the wider of the two is taken). Only runs in the finest size's most common state are
compared. The coarsest size that qualifies is the one chosen.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import statistics
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_section  # noqa: E402

#: the compared metrics: (column of replicas.csv, label, format)
METRICS = (("bending_angle_deg", "θ [deg]", "{:.2f}"), ("tip_dx_mm", "δx [mm]", "{:.1f}"),
           ("tip_dz_mm", "δz [mm]", "{:.1f}"), ("curling_index", "curling index", "{:.3f}"))

#: a size's mean qualifies within this many standard deviations of the finest's
SPREADS = 2.0


@dataclass
class SizeRuns:
    """The finished runs of one mesh size: per run its state and metrics."""

    size: float
    runs: list[dict]
    total: int
    commits: tuple[str, ...] = ()

    def state(self) -> str | None:
        """The most common state of the runs (None without runs)."""
        counts = Counter(r["states"] or "—" for r in self.runs)
        return counts.most_common(1)[0][0] if counts else None

    def values(self, column: str, state: str | None = None) -> list[float]:
        return [float(r[column]) for r in self.runs
                if r.get(column) not in (None, "") and (state is None or (r["states"] or "—") == state)]


def _cached_rows(out: Path, design, count: int) -> list[dict]:
    """One row per replica 0 .. count-1 of ``design``, as replicas.csv has them, from the records
    in ``out/points`` (a run that finished before its replica study was stopped counts too)."""
    from hydrojam.study.replicas import replica_records, replica_study
    from hydrojam.study.table import replica_table

    study = replica_study(design, count)
    records = replica_records(out, study)
    return replica_table(study, records).rows


def read_runs(out: Path, size: float, base=None, count: int | None = None) -> SizeRuns:
    """The runs that finished (status ok) of replicas 0 .. ``count``-1 of the design ``base`` at
    mesh ``size`` in ``out/points``, or, without a base, of ``out/replicas.csv``; ``total``
    counts all rows."""
    path = out / "replicas.csv"
    if base is not None and count and (out / "points").is_dir():
        from hydrojam.actuator.design import apply_overrides

        rows = _cached_rows(out, apply_overrides(base, [f"mesh.size={size!r}"]), count)
    elif not path.is_file():
        return SizeRuns(size, [], 0)
    else:
        with path.open(newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    runs = [r for r in rows if r.get("status") == "ok"]
    commits = []
    for r in runs:
        try:
            record = json.loads((out / r["point_dir"] / "metrics.json").read_text(encoding="utf-8"))
            commits.append(str(record["provenance"]["source"]["commit"])[:7])
        except (KeyError, OSError, TypeError, ValueError):
            continue
    return SizeRuns(size, runs, len(rows), tuple(dict.fromkeys(commits)))


def _ms(values: list[float]) -> tuple[float, float]:
    return statistics.mean(values), (statistics.stdev(values) if len(values) > 1 else 0.0)


def qualifies(coarse: SizeRuns, finest: SizeRuns) -> tuple[bool, list[str]]:
    """Whether ``coarse`` lies within ``finest``'s spread (the module's rule), and per metric why."""
    state = finest.state()
    notes, ok = [], True
    for column, label, f in METRICS:
        a, b = coarse.values(column, state), finest.values(column, state)
        if not a or not b:
            return False, [f"no run in the state {state}"]
        (ma, sa), (mb, sb) = _ms(a), _ms(b)
        bound = SPREADS * max(sa, sb)
        inside = abs(ma - mb) <= bound
        ok &= inside
        notes.append(f"{label} {'+' if ma >= mb else '−'}{f.format(abs(ma - mb))} "
                     f"({'within' if inside else 'beyond'} {f.format(bound)})")
    return ok, notes


def convergence_table(sizes: list[SizeRuns]) -> tuple[str, float | None]:
    """The Markdown table of ``sizes`` (coarsest first) and the coarsest size within the finest's spread."""
    finest = min([s for s in sizes if s.runs] or sizes, key=lambda s: s.size)
    header = ["mesh [mm]", "runs", "states", *(lab for _, lab, _ in METRICS), "Newton iterations",
              "wall time a run [min], as recorded", "against the finest"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---:|" * (len(header) - 1) + "---|"]
    chosen = None
    for s in sorted(sizes, key=lambda s: -s.size):
        states = Counter(r["states"] or "—" for r in s.runs)
        cells = [f"{s.size:g}", f"{len(s.runs)} of {s.total}", ", ".join(f"{k} {v}" for k, v in states.items()) or "—"]
        for column, _, f in METRICS:
            v = s.values(column)
            cells.append(" ± ".join(f.format(x) for x in _ms(v)) if v else "—")
        it, wall = s.values("newton_iterations"), s.values("wall_time_s")
        cells.append(" ± ".join(f"{x:.0f}" for x in _ms(it)) if it else "—")
        cells.append(f"{statistics.mean(wall) / 60:.1f}" if wall else "—")
        if s is finest:
            cells.append("the finest")
        elif s.runs and finest.runs:
            ok, notes = qualifies(s, finest)
            cells.append(("**within**: " if ok else "**beyond**: ") + "; ".join(notes))
            if ok and chosen is None:
                chosen = s.size
        else:
            cells.append("not finished")
        lines.append("| " + " | ".join(cells) + " |")
    if chosen is None and finest.runs:
        chosen = finest.size
    if len(finest.runs) < 2 and finest.runs:
        lines.append("")
        lines.append(f"The finest size, {finest.size:g} mm, has one finished run: its own spread is not measured, "
                     f"so the rule's bound is the coarser size's alone; the choice below is provisional.")
    unfinished = [s.size for s in sizes if not s.runs and s.size < finest.size]
    if unfinished:
        lines.append("")
        lines.append(f"Not finished yet: {', '.join(f'{x:g} mm' for x in unfinished)}; the finest finished "
                     f"size, {finest.size:g} mm, stands in for it.")
    return "\n".join(lines), chosen


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", type=Path, default=None, help="the design file (default: the default design)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="FIELD=VALUE",
                    help="a design override (repeatable)")
    ap.add_argument("--sizes", type=float, nargs="+", required=True, help="element sizes [mm]")
    ap.add_argument("--replicas", type=int, nargs="+", required=True, help="runs per size (one value, or one per size)")
    ap.add_argument("--root", type=Path, required=True, help="ROOT/mesh-S holds size S's runs")
    ap.add_argument("--report-only", action="store_true", help="run nothing: read what ROOT holds")
    ap.add_argument("--workers", type=int, default=1, help="runs at once")
    ap.add_argument("--markdown", metavar="FILE", help="write the table into FILE's section")
    ap.add_argument("--section", metavar="NAME", help="with --markdown: the marked section NAME")
    args = ap.parse_args(argv)
    counts = args.replicas * len(args.sizes) if len(args.replicas) == 1 else args.replicas
    if len(counts) != len(args.sizes):
        ap.error("--replicas: one value, or one per size")

    from hydrojam.actuator.design import apply_overrides, default_design, load_design

    base = apply_overrides(load_design(args.design) if args.design else default_design(), args.overrides)
    if not args.report_only:
        from hydrojam.study.replicas import run_replicas

        for size, n in zip(args.sizes, counts):
            design = apply_overrides(base, [f"mesh.size={size!r}"])
            print(f"mesh {size:g} mm: {n} run(s) into {args.root / f'mesh-{size:g}'}", flush=True)
            run_replicas(design, args.root / f"mesh-{size:g}", count=n, workers=args.workers)
    sizes = [read_runs(args.root / f"mesh-{s:g}", s, base, n) for s, n in zip(args.sizes, counts)]
    text, chosen = convergence_table(sizes)
    commits = list(dict.fromkeys(c for s in sizes for c in s.commits))
    code = ("runs computed by the code of " + ", ".join(f"`{c}`" for c in commits)) if commits else "no run yet"
    threads = os.environ.get("HYDROJAM_SOLVER_THREADS", "1")
    dim = f"{base.dimension}D" + (" half model" if base.dimension == 3 and base.mesh.symmetry else "")
    what = " ".join([*([f"--design {args.design.name}"] if args.design else []), *(f"--set {o}" for o in args.overrides)])
    conditions = (f"Measured by `benchmarks/mesh.py {what + ' ' if what else ''}--sizes {' '.join(f'{s:g}' for s in args.sizes)} "
                  f"--replicas {' '.join(str(c) for c in counts)}`: {dim}, friction {base.friction:g}, "
                  f"{base.stimulus.temperature:g} K, {code}, {os.cpu_count()} cores, {threads} solver "
                  f"thread(s) a run; mean ± std over each size's runs that finished.")
    verdict = (f"The coarsest mesh within the finest's spread: **{chosen:g} mm**." if chosen is not None
               else "No size finished yet.")
    out = "\n\n".join([conditions, text, verdict])
    print(out)
    if args.markdown:
        write_section(args.markdown, "mesh.py", args.section or "mesh", out)
    return 0 if all(math.isfinite(s.size) for s in sizes) else 1


if __name__ == "__main__":
    sys.exit(main())
