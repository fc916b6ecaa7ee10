"""Where an actuator simulation's Newton iterations go, and what a change of the path (step
control, stabilisation, its release at s = 1) does to them and to the answer (issue 12, lever b).

Run:  .venv/bin/python benchmarks/path.py [--variant NAME ...] [--design one_layer|default|default_3d ...]
                                          [--seeds 0 1 2 | --replicas N [--workers 2]]
                                          [--set friction=0.01 ...] [--steps] [--trace PREFIX]
                                          [--model-check N] [--pieces]

For every variant and design it prints Newton iterations on the load path and in the release of
the stabilisation (with its rounds: damping scale and iterations), all Newton iterations (the
failed attempts' and the settle's too: the cost), wall time, whether the final
state is an equilibrium without stabilisation ("released"), bending angle and tip. ``--seeds``
runs round-off replicas instead of a design: the stimulus path's interior knots jittered by 1e-7 x a
standard normal (a test harness, not a library feature), since one run's angle of the default
design is one sample of its round-off spread (docs/actuator.md, "Path dependence").
``--replicas N`` runs the design's replicas 0 .. N-1 instead (particle centres jittered from
seed 0, docs/replicas.md), ``--workers`` of them at once in separate processes, and prints per
variant the mean, standard deviation and range of the angle and tip and the mean iterations: the
test of whether a faster path samples the same distribution of equilibria as the default one.
``--set`` overrides design fields for every run. ``--steps`` prints the iterations of every load
step as it is accepted and, at the end, with its damping scale and failed attempts, and of every
release round. ``--trace`` writes every Newton iteration (benchmarks/_trace.py); ``--model-check N``
measures at every N-th how far the quadratic model holds along the step, term by term
(benchmarks/_model_check.py); ``--pieces`` times the pieces of the iterations
(benchmarks/_pieces.py). ``default_3d`` is
the default design in 3D at the quick mesh (half model, 4 mm): about 6 CPU minutes a run.

Iteration counts are deterministic; wall times are disturbed by whatever else runs (the load is
printed).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import functools
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_load, table  # noqa: E402
from _model_check import ModelCheck  # noqa: E402
from _pieces import PieceTimer  # noqa: E402
from _trace import IterationTrace  # noqa: E402

from hydrojam.actuator.design import apply_overrides, default_design, with_replicas  # noqa: E402
from hydrojam.actuator.model import build_model  # noqa: E402
from hydrojam.actuator.simulate import ACTUATOR_PATH, simulate  # noqa: E402
from hydrojam.fem import LinearSolver, ReleaseOptions  # noqa: E402

DESIGNS = {"one_layer": ["particle_layers=1"], "default": [],
           "near_prepared": ["particle_layers=1", "mesh.size=4", "stimulus.mu=-0.0343", "stimulus.temperature=300"],
           "default_3d": ["dimension=3", "mesh.size=4"],
           "one_layer_3d": ["dimension=3", "particle_layers=1", "mesh.size=4"],
           "proxy_3d": ["dimension=3", "particle_layers=2", "mesh.size=4"]}

#: variant name -> keyword arguments of simulate (``options`` replaces fields of ACTUATOR_PATH)
VARIANTS = {
    "main": {},
    # a step whose energy change is within the energy's round-off of Armijo's demand is taken on the energy alone
    "no_residual_search": {"options": {"newton": {"residual_search": False}}},
    "no_curvature_step": {"options": {"newton": {"curvature_step": 0.0}}},
    "curvature_step_8x": {"options": {"newton": {"curvature_doublings": 3}}},
    # the path before every state was an equilibrium: damped from the start, released once at s = 1
    "stabilised_path": {"options": {"damping_start": 1.0, "extrapolate": False,
                                    "release": ReleaseOptions(each_step=False)}},
    "no_extrapolation": {"options": {"extrapolate": False}},
    "damped_from_start": {"options": {"damping_start": 1.0}},
    "no_stabilisation": {"stabilisation": 0.0},
    "settle_never": {"options": {"settle": "never"}},
    "path_ds_0.1_0.2": {"options": {"ds0": 0.1, "ds_max": 0.2}},
    "path_ds_0.025": {"options": {"ds0": 0.025, "ds_max": 0.025}},
    "path_ds_0.2": {"options": {"ds0": 0.2, "ds_max": 0.2}},
    # the full Hessian's step wherever it descends, a negative eigenvalue or not (no inertia correction)
    "indefinite": {"options": {"newton": {"definite": False}}},
    # the full Hessian's K factorised first in every iteration
    "full_start": {"options": {"newton": {"fallback_start": "full"}}},
    "rtol_1e-5": {"options": {"newton": {"rtol": 1e-5}}},
    # an undamped step that runs out of its 200 iterations is retried damped at once
    "undamped_1": {"options": {"undamped_blocks": 1}},
    # where the undamped blocks all ran out, the damped attempts start from the step's start
    "damped_from_step_start": {"options": {"damped_from_blocks": False}},
    # the linear solver without the contact term's reach pattern: the union of recent patterns
    "no_reach": {"solver": {"use_reach": False}},
    # every factorisation an LDL^T, the definite ones too (main factorises those by Cholesky in 3D)
    "ldlt": {"solver": {"use_cholesky": False}},
    # the Cholesky factorisations in double (main factorises them in single and refines in double)
    "double": {"solver": {"mixed_precision": False}},
}


def _simulate_kwargs(variant: str) -> dict:
    kw = dict(VARIANTS[variant])
    kw.pop("solver", None)
    if "options" in kw:
        fields = dict(kw["options"])
        base = ACTUATOR_PATH
        if isinstance(fields.get("newton"), dict):  # fields of the path's NewtonOptions
            fields["newton"] = dataclasses.replace(base.newton, **fields["newton"])
        kw["options"] = dataclasses.replace(base, **fields)
    return kw


def jittered(model, seed: int, size: float = 1e-7):
    """The model with its stimulus path's interior knots t moved by ``size`` x N(0, 1) (seeded):
    a round-off-sized change of the path, to sample the spread of the answer."""
    path = model.path
    t = np.array(path.t_knots, dtype=float)
    t[1:-1] += size * np.random.default_rng(seed).standard_normal(len(t) - 2)
    t = np.maximum.accumulate(np.clip(t, 0.0, 1.0))
    return dataclasses.replace(model, path=dataclasses.replace(path, t_knots=t))


def label_of(seed: int | None, replica: int | None) -> str:
    """A run's label in the tables: "-", the seed, or "r<replica>"."""
    return "-" if seed is None and replica is None else (f"r{replica}" if replica is not None else str(seed))


class _Steps:
    """An observer of the load path that keeps every accepted step's record (its iterations,
    release rounds, damping and failed attempts)."""

    def __init__(self):
        self.history = []

    def on_step_accepted(self, event) -> None:
        if event.record is not None:
            self.history.append(event.record)


def run(design: str, variant: str, seed: int | None, steps: bool, overrides: tuple[str, ...] = (),
        replica: int | None = None, count: int = 1, trace: str | None = None, model_check: int = 0,
        pieces: bool = False) -> list[str]:
    sim_kw = _simulate_kwargs(variant)
    d = apply_overrides(default_design(), [*DESIGNS[design], *overrides])
    if replica is not None:
        d = with_replicas(d, count).replica(replica)
    model = build_model(d)
    if seed is not None:
        model = jittered(model, seed)
    solver_attrs = VARIANTS[variant].get("solver", {})  # LinearSolver class attributes, for this run
    saved_attrs = {k: getattr(LinearSolver, k) for k in solver_attrs}
    for k, v in solver_attrs.items():
        setattr(LinearSolver, k, v)
    tracer = IterationTrace() if trace else None
    checker = ModelCheck(model_check) if model_check else None
    timer = PieceTimer() if pieces else None
    steps_seen = _Steps()
    observers = [o for o in (steps_seen, tracer, checker, timer) if o is not None]
    try:
        t0 = time.perf_counter()
        calls = []

        def on_step(state):
            calls.append(state)
            if steps:  # live, for the long runs
                print(f"    {design} {variant}: s = {state.s:.4f}, {state.iterations} iterations, "
                      f"{time.perf_counter() - t0:.0f} s, {state.metrics['bending_angle_deg']:.2f} deg, "
                      f"negative eigenvalues {state.negative_eigenvalues}", flush=True)

        res = simulate(model, on_step=on_step, observers=observers, **sim_kw)
        wall = time.perf_counter() - t0
    finally:
        for k, v in saved_attrs.items():
            setattr(LinearSolver, k, v)
    if timer is not None:
        timer.add_terms(res.term_timings)
        print(timer.summary(f"{design} {variant} {label_of(seed, replica)}", wall), flush=True)
    if checker is not None:
        print(checker.summary(f"{design} {variant} {label_of(seed, replica)}"), flush=True)
    if tracer is not None:
        name = f"{trace}-{design}-{variant}-{label_of(seed, replica)}.csv"
        tracer.write(name)
        print(tracer.summary(f"{design} {variant} {label_of(seed, replica)}") + f"\n  trace written to {name}", flush=True)
    m = res.metrics
    rounds = res.stabilisation.get("release_rounds", [])
    history = steps_seen.history
    release_its = sum(r["iterations"] for r in rounds) + sum(h.release_iterations for h in history)
    n_rounds = len(rounds) + sum(h.release_rounds for h in history)
    if len(calls) > 1 and calls[-1].index == calls[-2].index:
        calls.pop()  # the released final state replaces the path's last, stabilised one
    if steps:
        print(f"  {design} {variant} seed {seed}: step iterations (@ damping scale, ! a failed attempt) "
              + " ".join(f"{h.iterations}@{h.damping if h.damping is not None else 0:g}{'!' * h.rejected}"
                         for h in history)
              + "; release rounds " + " ".join(f"{r['scale']:g}:{r['iterations']}{'' if r['converged'] else '!'}"
                                               for r in rounds), flush=True)
    t = res.timings
    its = max(int(t["newton_iterations"]), 1)
    print(f"  {design} {variant} {label_of(seed, replica)}: {1e3 * wall / its:.0f} ms a Newton iteration; of the "
          f"wall, linear solves {t['linear_solve'] / wall:.0%}, contact {t['contact'] / wall:.0%}, elastic "
          f"{t['elastic'] / wall:.0%}", flush=True)
    label = label_of(seed, replica)
    return [design, variant, label, str(res.newton_iterations - release_its),
            str(release_its), str(n_rounds), str(res.timings["newton_iterations"]), f"{wall:.1f}", str(m["stabilisation_released"]),
            f"{m['bending_angle_deg']:.2f}", f"({m['tip_dx_mm']:.1f}, {m['tip_dz_mm']:.1f})"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", nargs="+", default=["main"], choices=sorted(VARIANTS))
    ap.add_argument("--design", nargs="+", default=["one_layer", "default"], choices=sorted(DESIGNS))
    ap.add_argument("--seeds", nargs="*", type=int, default=[], help="round-off replicas (knot jitter seeds)")
    ap.add_argument("--replicas", type=int, default=0, help="run replicas 0 .. N-1 (particle jitter)")
    ap.add_argument("--workers", type=int, default=1, help="replica runs at once (processes)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="FIELD=VALUE",
                    help="design override for every run (repeatable)")
    ap.add_argument("--steps", action="store_true", help="print every load step's iterations")
    ap.add_argument("--markdown", metavar="FILE", help="write each (design, variant)'s replica table, with a line of "
                    "conditions, to FILE (with --section: into FILE's marked section)")
    ap.add_argument("--section", metavar="NAME", help="with --markdown: replace the text between the lines "
                    "'<!-- path.py: NAME -->' and '<!-- /path.py: NAME -->' of FILE (a docs page) instead")
    ap.add_argument("--trace", metavar="PREFIX", help="write every Newton iteration to PREFIX-<design>-<variant>-<run>.csv "
                    "and print where the iterations went")
    ap.add_argument("--model-check", type=int, default=0, metavar="N", help="at every N-th Newton iteration, "
                    "measure each energy term's deviation from the quadratic model along the step and print "
                    "where the model fails (benchmarks/_model_check.py)")
    ap.add_argument("--pieces", action="store_true", help="time the pieces of the Newton iterations (the Hessians, "
                    "the linear solver's calls, the CCD, ...) and print their shares of the wall (benchmarks/_pieces.py)")
    args = ap.parse_args(argv)
    print_load()
    if args.overrides:
        print("overrides: " + " ".join(args.overrides))
    if args.model_check < 0:
        ap.error(f"--model-check must be 0 (off) or a positive integer, got {args.model_check}")
    jobs = [(design, variant, seed, args.steps, tuple(args.overrides), rep, max(args.replicas, 1), args.trace,
             args.model_check, args.pieces)
            for variant in args.variant for design in args.design
            for seed in (args.seeds if not args.replicas else [None]) or [None]
            for rep in (range(args.replicas) if args.replicas else [None])]
    rows = []
    with concurrent.futures.ProcessPoolExecutor(max(args.workers, 1)) as pool:
        for row in pool.map(run, *zip(*jobs)):
            rows.append(row)
            print("  " + " | ".join(row), flush=True)
    print_load()
    print()
    print(table(["design", "variant", "seed", "path its", "release its", "rounds", "all its", "wall [s]", "released",
                 "angle [deg]", "tip (dx, dz) [mm]"], rows, left=3))
    if len(rows) > len({(r[0], r[1]) for r in rows}):
        print()
        print(table(["design", "variant", "runs", "angle mean ± std [deg]", "angle range", "dx mean ± std [mm]",
                     "dz mean ± std [mm]", "iterations mean ± std", "all iterations mean ± std"],
                    _spreads(rows), left=2))
    if args.markdown:
        _write_markdown(args.markdown, rows, args.workers, args.overrides, args.section)
        print(f"\nreplica tables written to {args.markdown}" + (f", section {args.section}" if args.section else ""))
    return 0


def _write_markdown(path: str, rows: list[list[str]], workers: int, overrides: list[str],
                    section: str | None = None) -> None:
    """The replica tables as Markdown: a line of conditions (the command, the commit, cores,
    solver threads, runs at once), then per (design, variant) the angle, tip and all iterations
    as mean ± std, min and max with their run, and every run's value; written to ``path``, or
    into its ``section`` (:func:`replace_section`)."""
    from hydrojam.actuator.provenance import source_provenance

    src = source_provenance()
    commit = src["commit"][:7] if src["commit"] != "unknown" else "unknown"
    threads = os.environ.get("HYDROJAM_SOLVER_THREADS", "1")
    command = "benchmarks/path.py " + " ".join(sys.argv[1:])
    lines = [f"Measured by `{command}`: code of `{commit}`{' (with local changes)' if src['dirty'] is True else ''}, "
             f"{os.cpu_count()} cores, {threads} solver thread(s) a run, {max(workers, 1)} run(s) at once.", ""]
    for key in dict.fromkeys((r[0], r[1]) for r in rows):
        sel = [r for r in rows if (r[0], r[1]) == key]
        q = _quantities(sel)
        lines += [f"**{key[0]}** ({' '.join([*DESIGNS[key[0]], *overrides]) or 'the default design'}), "
                  f"{len(sel)} run(s), variant {key[1]}:", "",
                  "| | mean ± std | min (run) | max (run) | runs in order |", "|---|---:|---:|---:|---|"]
        names = [r[2] for r in sel]
        for label, values, f in [("θ [deg]", q["angle"], "{:.2f}"), ("δx [mm]", q["dx"], "{:.1f}"),
                                 ("δz [mm]", q["dz"], "{:.1f}"), ("Newton iterations (all)", q["all"], "{:.0f}")]:
            spread = statistics.stdev(values) if len(values) > 1 else 0.0
            lo, hi = int(np.argmin(values)), int(np.argmax(values))
            lines.append(f"| {label} | {f.format(statistics.mean(values))} ± {f.format(spread)} | "
                         f"{f.format(values[lo])} ({names[lo]}) | {f.format(values[hi])} ({names[hi]}) | "
                         + ", ".join(f.format(v) for v in values) + " |")
        lines.append("")
    text = "\n".join(lines)
    if section:
        text = replace_section(Path(path).read_text(encoding="utf-8"), section, text)
    Path(path).write_text(text, encoding="utf-8")


def replace_section(page: str, name: str, text: str, tag: str = "path.py") -> str:
    """``page`` with the lines between '<!-- TAG: NAME -->' and '<!-- /TAG: NAME -->' (TAG the
    benchmark's file name) replaced by ``text`` (the markers kept); ValueError naming the markers
    where either is missing."""
    begin, end = f"<!-- {tag}: {name} -->", f"<!-- /{tag}: {name} -->"
    i, j = page.find(begin), page.find(end)
    if i < 0 or j < i:
        raise ValueError(f"no section {begin} ... {end} in the page")
    return page[: i + len(begin)] + "\n" + text.rstrip("\n") + "\n" + page[j:]


def _quantities(sel: list[list[str]]) -> dict[str, list[float]]:
    """The runs' angle [deg], tip dx and dz [mm], iterations on the path and in the releases
    ("path"), and all iterations ("all"), read back from their table rows."""
    tips = [r[10].strip("()").split(",") for r in sel]
    return {"angle": [float(r[9]) for r in sel], "dx": [float(t[0]) for t in tips], "dz": [float(t[1]) for t in tips],
            "path": [float(int(r[3]) + int(r[4])) for r in sel], "all": [float(r[6]) for r in sel]}


def _spreads(rows: list[list[str]]) -> list[list[str]]:
    """Per (design, variant): mean ± sample standard deviation of angle, tip and iterations."""
    def ms(v):
        return f"{statistics.mean(v):.1f} ± {statistics.stdev(v):.1f}" if len(v) > 1 else f"{v[0]:.1f}"
    out = []
    for key in dict.fromkeys((r[0], r[1]) for r in rows):
        sel = [r for r in rows if (r[0], r[1]) == key]
        q = _quantities(sel)
        out.append([*key, str(len(sel)), ms(q["angle"]), f"{min(q['angle']):.1f}-{max(q['angle']):.1f}", ms(q["dx"]),
                    ms(q["dz"]), ms(q["path"]), ms(q["all"])])
    return out


if __name__ == "__main__":
    raise SystemExit(main())
