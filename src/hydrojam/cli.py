"""Command-line interface: a thin layer over the Python API. Bad input exits with status 2 and
one line naming the option and its allowed range."""

from __future__ import annotations

import contextlib
import csv
import errno
import io
import json
import math
import os
import sys
from pathlib import Path
from typing import Optional

import numpy as np
import typer
from pydantic import ValidationError
from rich.console import Console
from rich.table import Table

from hydrojam._io import FolderKind, make_folder
from hydrojam._validation import describe_error, is_non_finite, non_finite_message
from hydrojam.materials.energies import WATER_RANGE_K, HydrogelParams
from hydrojam.materials.swelling import swelling_curve

try:  # typer >= 0.2x vendors its own click; Abort and Exit are typer's own in both cases
    from typer._click import exceptions as _click_exc
except ImportError:  # pragma: no cover - older typer on top of click
    from click import exceptions as _click_exc

T_MIN_WATER, T_MAX_WATER = WATER_RANGE_K

#: most temperatures `hydrojam swell` computes in one call (a range with a tiny --t-step would
#: otherwise run for minutes and fill the memory before printing anything)
MAX_TEMPERATURES = 10_000

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
    help="hydrojam: simulate active particle jamming actuators (PNIPAM hydrogel particles in an elastomer chamber).",
)


class InputError(Exception):
    """Invalid user input: reported as one line, exit status 2."""


class _Stopped(Exception):
    """A command stopped by a signal (:class:`hydrojam._interrupt.Interrupted`), its clean-up
    done: reported as one line, what stopped it and ``where`` it stands, exit status 128 + the
    signal's number."""

    def __init__(self, stop, where: str):
        super().__init__(f"stopped by {stop.words}{where}")
        self.stop = stop


def _stopped(err: BaseException, where) -> None:
    """Raise :class:`_Stopped` with ``where()`` (where the command stands, e.g. " at s = 0.41;
    ...") when a signal is behind ``err`` (:func:`hydrojam._interrupt.interruption`); return
    otherwise (the caller re-raises ``err``)."""
    from hydrojam._interrupt import interruption

    stop = interruption(err)
    if stop is not None:
        raise _Stopped(stop, where()) from None


def _print_version(value: bool) -> None:
    if value:
        from hydrojam._version import __version__

        print(f"hydrojam {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                 help="Print hydrojam's version and exit."),
) -> None:
    """Units: mm, MPa, K; chemical potential mu in k_B T."""


def _check_environment(args: list[str]) -> None:
    """Every thread count and switch hydrojam reads from the environment, checked before any work
    (an InputError naming the first invalid one); not for help or the version, which run nothing."""
    from hydrojam.fem._env import check_environment

    if not args or {"-h", "--help", "--version"} & set(args):
        return
    try:
        check_environment()
    except ValueError as err:
        raise InputError(str(err)) from None


def _temperatures(temperatures: str | None, t_min, t_max, t_step) -> list[float]:
    if temperatures is not None and any(v is not None for v in (t_min, t_max, t_step)):
        raise InputError("--temperatures: give either a list or --t-min/--t-max/--t-step, not both")
    if temperatures is not None:
        Ts = []
        for tok in temperatures.split(","):
            try:
                Ts.append(float(tok))
            except ValueError:
                raise InputError(
                    f"--temperatures: {tok.strip()!r} is not a number; give comma-separated temperatures in K "
                    f"within [{T_MIN_WATER}, {T_MAX_WATER}]"
                ) from None
        if len(Ts) > MAX_TEMPERATURES:
            raise InputError(f"--temperatures: {len(Ts)} temperatures; at most {MAX_TEMPERATURES} in one call")
    else:
        water = f"[{T_MIN_WATER}, {T_MAX_WATER}]"
        for option, value, allowed in (("--t-min", t_min, water), ("--t-max", t_max, water),
                                       ("--t-step", t_step, "(0, inf)")):
            if is_non_finite(value):
                raise InputError(non_finite_message(option, value, allowed, "K"))
        lo = 275.0 if t_min is None else t_min
        hi = 315.0 if t_max is None else t_max
        step = 5.0 if t_step is None else t_step
        if not step > 0:
            raise InputError(f"--t-step: must be > 0 K (got {step})")
        if hi < lo:
            raise InputError(f"--t-max: must be >= --t-min ({lo} K) (got {hi})")
        steps = (hi - lo) / step + 1e-9  # a float: a tiny step must not overflow an int
        if steps + 1 > MAX_TEMPERATURES:
            count = f"{math.floor(steps) + 1}" if steps < 1e15 else "over 1e15"
            raise InputError(
                f"--t-step: {step:g} K from --t-min {lo:g} K to --t-max {hi:g} K gives {count} temperatures; "
                f"at most {MAX_TEMPERATURES} in one call (use a larger --t-step or a narrower range)"
            )
        Ts = list(lo + step * np.arange(math.floor(steps) + 1))
    for T in Ts:
        if is_non_finite(T):
            raise InputError(non_finite_message("--temperatures", T, f"[{T_MIN_WATER}, {T_MAX_WATER}]", "K"))
        if not (T_MIN_WATER <= T <= T_MAX_WATER):
            raise InputError(
                f"temperature {T} K is outside liquid water's range [{T_MIN_WATER}, {T_MAX_WATER}] K "
                "(--temperatures / --t-min / --t-max)"
            )
    return Ts


@app.command()
def swell(
    temperatures: Optional[str] = typer.Option(None, "--temperatures", help="Comma-separated temperatures [K], e.g. 275,285,295."),
    t_min: Optional[float] = typer.Option(None, "--t-min", help="Lowest temperature of a range [K] (default 275)."),
    t_max: Optional[float] = typer.Option(None, "--t-max", help="Highest temperature of a range [K] (default 315)."),
    t_step: Optional[float] = typer.Option(None, "--t-step", help="Temperature step of a range [K] (default 5)."),
    mu: float = typer.Option(0.0, "--mu", help="Solvent chemical potential \\[k_B T]; 0 = pure water; must be <= 0."),
    nnu: float = typer.Option(0.01, "--nnu", help="N nu: crosslink density times solvent molecule volume [-], in (0, 1]."),
    lambda0: float = typer.Option(1.5, "--lambda0", help="As-prepared swelling stretch lambda0 [-], > 1."),
    t0: float = typer.Option(300.0, "--t0", help="Temperature of the as-prepared state T0 [K]."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object instead of a table."),
    as_csv: bool = typer.Option(False, "--csv", help="Print a CSV table instead of the rich table."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Write the swelling curve to this PNG file."),
) -> None:
    """Free swelling of the PNIPAM gel: equilibrium stretch against temperature, and the transition."""
    if as_json and as_csv:
        raise InputError("--json and --csv: choose one output format")
    try:
        params = HydrogelParams(n=nnu, lambda0=lambda0, T0=t0)
    except ValidationError as err:
        raise InputError(describe_error(err, HydrogelParams, {"n": "--nnu", "lambda0": "--lambda0", "T0": "--t0"})) from None
    if is_non_finite(mu):
        raise InputError(non_finite_message("--mu", mu, "(-inf, 0]", "k_B T"))
    if not mu <= 0:
        raise InputError(f"--mu: must be <= 0 k_B T (pure water is 0; above it a gel swells without bound) (got {mu})")
    if plot is not None and plot.suffix.lower() != ".png":
        raise InputError(f"--plot: the figure file must end in .png (got {str(plot)!r})")
    if plot is not None:
        _check_file_target("--plot", plot)
    Ts = _temperatures(temperatures, t_min, t_max, t_step)

    transition, states = swelling_curve(params, mu, Ts)
    points = [
        {"T": s.T, "stretch": s.stretch, "stretch_rel": s.stretch_rel, "J": s.J, "branch": s.branch} for s in states
    ]
    if plot is not None:
        from hydrojam.materials.plots import plot_swelling_curve

        plot_swelling_curve(params, mu, states, transition, plot)

    if as_json:
        out = {
            "mu": mu,
            "mu0": params.mu0,
            "transition_temperature": transition.T,
            "transition_discontinuous": transition.discontinuous,
            "params": params.model_dump(),
            "points": points,
        }
        print(json.dumps(out, indent=2))
    elif as_csv:
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=list(points[0]))
        w.writeheader()
        w.writerows(points)
        sys.stdout.write(buf.getvalue())
    else:
        console = Console()
        table = Table(title=f"PNIPAM free swelling at mu = {mu:g} kT (N nu = {nnu:g}, lambda0 = {lambda0:g}, T0 = {t0:g} K)")
        for col in ("T [K]", "stretch (dry)", "stretch / lambda0", "J = V/V_dry", "branch"):
            table.add_column(col, justify="right")
        for p in points:
            table.add_row(f"{p['T']:.2f}", f"{p['stretch']:.4f}", f"{p['stretch_rel']:.4f}", f"{p['J']:.3f}", p["branch"])
        console.print(table)
        kind = "discontinuous" if transition.discontinuous else "continuous"
        console.print(f"mu0 (stress-free as-prepared state) = {params.mu0:.5f} kT; "
                      f"volume phase transition at {transition.T:.2f} K ({kind})")
    if plot is not None and not as_json and not as_csv:
        Console().print(f"figure written: {plot}")


def _check_file_target(option: str | None, path: Path) -> None:
    """InputError naming ``option`` (if any) and the path when a file cannot be written at ``path`` (a folder, a parent
    that is a file, a folder without write permission), before any work or temporary file."""
    from hydrojam._io import check_file_target

    try:
        check_file_target(path)
    except OSError as err:
        raise InputError(f"{option + ': ' if option else ''}{err.filename}: {err.strerror}") from None


def _design_or_exit(design_file: Path | None, overrides: list[str]):
    from hydrojam.actuator.design import DesignError, apply_overrides, default_design, load_design
    from hydrojam.actuator.model import check_supported

    try:
        design = default_design() if design_file is None else load_design(design_file)
        design = apply_overrides(design, overrides)
        check_supported(design)
    except DesignError as err:
        raise InputError(str(err)) from None
    return design


@app.command()
def init(
    path: Path = typer.Argument(Path("design.toml"), help="Where to write the design (TOML)."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing file."),
    overrides: list[str] = typer.Option([], "--set", help="Change a field, e.g. --set particle_layers=7 (repeatable)."),
) -> None:
    """Write the default actuator design as a commented TOML file (every field, units, ranges)."""
    from hydrojam.actuator.design import write_design

    _check_file_target(None, path)
    if path.exists() and not force:
        raise InputError(f"{path}: exists; use --force to overwrite it")
    if path.suffix.lower() != ".toml":
        raise InputError(f"{path}: the design file must end in .toml")
    design = _design_or_exit(None, overrides)
    write_design(path, design)
    Console(stderr=True).print(f"design written: {path}  (run it with: hydrojam run {path} -o out)")


@app.command("run")
def run_design(
    design_file: Path = typer.Argument(..., help="Design file (TOML), e.g. from `hydrojam init`."),
    out: Path = typer.Option(..., "-o", "--out", help="Output folder (created; earlier results in it are replaced, but a run of the same design stopped midway goes on from its checkpoint)."),
    overrides: list[str] = typer.Option([], "--set", help="Change a field, e.g. --set stimulus.temperature=295 (repeatable)."),
    dimension: Optional[int] = typer.Option(None, "--dimension", help="2 (plane strain) or 3 (spheres; the half model unless --set mesh.symmetry=false); same as --set dimension=N."),
    vtu: bool = typer.Option(True, "--vtu/--no-vtu", help="Write a VTU file per load step and the .pvd index."),
    fresh: bool = typer.Option(False, "--fresh", help="Start from s = 0 even where OUT holds a checkpoint of this design."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    replicas: Optional[int] = typer.Option(None, "--replicas", help="Run N replicas in parallel (jittered particle centres, see docs/replicas.md); default: the design's replicas.count."),
    workers: Optional[int] = typer.Option(None, "--workers", help="With replicas: local worker processes, one thread each (default: one per CPU)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="With replicas: address of a running dask scheduler, e.g. tcp://10.0.0.5:8786."),
) -> None:
    """Simulate one actuator along its stimulus path and write its results to OUT.

    OUT gets design.toml (resolved), metrics.json, history.csv, centreline.csv, steps/*.vtu with
    results.pvd (ParaView), final.png (3D: with a render of the whole actuator) and report.html (one
    page that opens offline: metrics, figures, 3D: an interactive view); with stimulus.schedule (a time-resolved temperature) also
    angle_time.png, the bending angle against time. Exit status 0 when the target stimulus was reached, 1
    when the solver stopped early (the results then hold the last converged state), 2 on bad input.

    With N > 1 replicas (--replicas or replicas.count) they run in parallel like a sweep's points,
    resumable: OUT gets points/<key>/ per replica (final.vtu), replicas.csv, and summary.csv and
    summary.json (mean, standard deviation, min, max of every metric, and which replica gave which);
    exit status 1 when a replica failed or stopped early.

    A run keeps OUT/checkpoint.npz, rewritten after every accepted load step and every round of
    the release, and removed when it ends. Run the same design into the same OUT again and it goes
    on from there (--fresh: from s = 0).
    """
    replicas = _check_replicas(replicas)
    if not design_file.is_file():
        raise InputError(f"{design_file}: no such design file")
    if dimension is not None and dimension not in (2, 3):
        raise InputError(f"--dimension: allowed 2 or 3 (got {dimension})")
    design = _design_or_exit(design_file, ([f"dimension={dimension}"] if dimension is not None else []) + overrides)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out: {out} exists and is not a folder")
    design = _with_replicas_or_exit(design, replicas)
    if design.replicas.count > 1:
        _check_workers(workers, scheduler, out)
        _run_replicas(design, design_file, out, workers, scheduler, quiet)
        return
    if workers is not None or scheduler is not None:
        raise InputError(f"{'--workers' if workers is not None else '--scheduler'}: only with --replicas N > 1 "
                         "(a single run is one process)")
    with _output_folder(out, FolderKind.RUN):  # before meshing: a folder that cannot be taken is refused at once
        _run_one(design, design_file, out, vtu, fresh, quiet)


@app.command()
def animate(
    out: Path = typer.Argument(..., help="A run's output folder (hydrojam run -o OUT), with its steps/*.vtu."),
    movie: Optional[Path] = typer.Option(None, "--movie", help="The .gif or .mp4 to write (default: OUT/movie.gif); "
                                         "an MP4 needs ffmpeg (the extra 'render' brings one)."),
    fps: float = typer.Option(6.0, "--fps", help="Frames per second, in (0, 50]."),
    max_frames: int = typer.Option(120, "--max-frames", help="Most frames, in [2, 1000]; more states are thinned evenly."),
) -> None:
    """Write the actuation movie of a run: a GIF (or MP4) from the as-prepared state to the end, one frame
    per written state, with the load parameter s, the temperature and the bending angle on each.

    3D: renders of the whole actuator (membrane translucent, particles coloured by swelling ratio;
    with the extra 'render', else the section y = 0); 2D: the section as in final.png. One camera,
    scale and colour range for all frames. Where OUT holds a finished run, its report.html is
    rewritten to show the movie. Exit status 0, 2 for a folder without written states.
    """
    from hydrojam.actuator import NO_MP4, NoStates, mp4_encoder, write_movie
    from hydrojam.actuator.page import write_run_page

    if not out.is_dir():
        raise InputError(f"{out}: {'not a folder' if out.exists() else 'no such folder'}")
    if not (0.0 < fps <= 50.0):
        raise InputError(f"--fps: allowed (0, 50] (got {fps:g})")
    if not (2 <= max_frames <= 1000):
        raise InputError(f"--max-frames: allowed [2, 1000] (got {max_frames})")
    if movie is not None and movie.suffix.lower() not in (".gif", ".mp4"):
        raise InputError(f"--movie: a .gif or .mp4 file (got {movie})")
    if movie is not None and movie.suffix.lower() == ".mp4" and mp4_encoder() is None:
        raise InputError(f"--movie: {NO_MP4}")
    import time

    t0 = time.perf_counter()
    try:
        path = write_movie(out, movie, fps=fps, max_frames=max_frames)
    except NoStates as err:
        raise InputError(str(err)) from None
    console = Console(stderr=True)
    console.print(f"movie: {path} ({time.perf_counter() - t0:.1f} s)", highlight=False, soft_wrap=True)
    if (out / "metrics.json").is_file() and movie is None:
        console.print(f"page: {write_run_page(out)}", highlight=False, soft_wrap=True)


@contextlib.contextmanager
def _output_folder(out: Path, kind: FolderKind):
    """:func:`hydrojam._io.output_folder` with its refusals (another kind of output, a live
    run's lock) as one line, exit status 2."""
    from hydrojam._io import FolderKindError, LockHeld, output_folder

    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(output_folder(out, kind))
        except (FolderKindError, LockHeld) as err:
            raise InputError(str(err)) from None
        yield out


def _run_one(design, design_file: Path, out: Path, vtu: bool, fresh: bool, quiet: bool) -> None:
    """Run ``design`` into ``out`` (a folder this process holds) with a progress bar, going on
    from its checkpoint unless ``fresh``; the summary; exit 1 when the solver stopped early.
    Stopped by a signal: :class:`_Stopped`, saying the s reached and that the checkpoint is kept."""
    try:
        _run_model(design, design_file, out, vtu, fresh, quiet)
    except BaseException as err:
        _stopped(err, lambda: _run_stand(out))
        raise


def _run_stand(out: Path) -> str:
    """Where a run into ``out`` stopped midway stands, and how to go on, as the end of a line."""
    from hydrojam.actuator.checkpoint import CHECKPOINT
    from hydrojam.study.cache import point_progress

    checkpoint = out / CHECKPOINT
    if not checkpoint.is_file():
        return " before its first load step was kept (no checkpoint yet); run the same command again to start it"
    progress = point_progress(out)
    where = ("" if progress is None else " in the release of the stabilisation at s = 1" if progress[0] >= 1.0
             else f" at s = {progress[0]:.3f}")
    return f"{where}; its checkpoint {checkpoint} is kept: run the same command again to go on from there"


def _run_model(design, design_file: Path, out: Path, vtu: bool, fresh: bool, quiet: bool) -> None:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from hydrojam.actuator.model import build_model
    from hydrojam.actuator.results import ResultWriter
    from hydrojam.actuator.simulate import simulate

    console = Console(stderr=True)
    model = build_model(design)
    writer = ResultWriter(out, model, vtu=vtu)
    ck = writer.start(resume=not fresh)
    if writer.discarded and not quiet:
        console.print(f"[yellow]hydrojam: starting from s = 0: the checkpoint cannot be resumed: {writer.discarded}[/yellow]")
    if ck is not None and not quiet:
        last = ck.states[-1]
        where = "in the release at s = 1" if ck.release is not None else f"at s = {last['s']:.4g} (state {last['index']})"
        console.print(f"hydrojam: going on from the checkpoint in {out} {where}")
    columns = [TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("s = {task.completed:.3f}"),
               TextColumn("{task.fields[info]}"), TimeElapsedColumn()]
    with Progress(*columns, console=console, disable=quiet, transient=False) as progress:
        schedule = design.stimulus.schedule
        label = (f"T -> {design.stimulus.temperature:g} K" if schedule is None
                 else f"schedule to t = {schedule[-1][0]:g} s")
        task = progress.add_task(label, total=1.0, info="", completed=0.0 if ck is None else ck.states[-1]["s"])

        seen, last = set(), [""]

        def on_step(state):
            writer.step(state)
            m = state.metrics
            info = f"angle {m['bending_angle_deg']:.1f} deg, iterations {state.iterations}"
            if state.time_s is not None:
                info = f"t = {state.time_s:.4g} s, T = {state.T:.1f} K, " + info
            last[0] = info
            if state.s >= 1.0:  # the stabilised end state first, then the released one (same index)
                info += "; releasing the stabilisation..." if state.index not in seen else "; final state"
                seen.add(state.index)
            progress.update(task, completed=state.s, info=info)

        def on_release(release):
            progress.update(task, info="; ".join(t for t in (last[0], _release_text(release)) if t))

        result = simulate(model, on_step=on_step, checkpoint=writer.checkpoint_path, resume=ck,
                          on_release=on_release)
    metrics = writer.finish(result, page=True)
    if not quiet:
        console.print(_run_summary(f"hydrojam run: {design_file.name} -> {out}", metrics))
        if metrics.get("buckled_at_s") is not None:  # docs/solver.md, "Where the path branched"
            console.print(f"buckled at s = {metrics['buckled_at_s']:.3g}: the path passed an instability there "
                          f"({metrics['unstable_states']} unstable states); the answer is path dependent from there")
    if not result.converged:
        console.print(f"[red]hydrojam: the solver stopped early: {result.message}[/red]")
        raise typer.Exit(code=1)
    if not metrics.get("stabilisation_released", True):
        console.print(f"[yellow]hydrojam: warning: {result.message}[/yellow]")


def _check_replicas(replicas: Optional[int]) -> Optional[int]:
    """``--replicas`` refused outside [1, MAX_REPLICAS] (one line, exit 2)."""
    from hydrojam.actuator.design import MAX_REPLICAS

    if replicas is not None and not 1 <= replicas <= MAX_REPLICAS:
        raise InputError(f"--replicas: must be in [1, {MAX_REPLICAS}] (got {replicas})")
    return replicas


def _with_replicas_or_exit(design, replicas: Optional[int]):
    """The design with ``--replicas`` applied (None: as it is)."""
    from hydrojam.actuator.design import DesignError, with_replicas

    if replicas is None:
        return design
    try:
        return with_replicas(design, replicas)
    except DesignError as err:
        raise InputError(f"--replicas: {err}") from None


def _run_replicas(design, design_file: Path, out: Path, workers, scheduler, quiet: bool) -> None:
    """`hydrojam run` of N > 1 replicas: run them, print the summary table, exit 1 on a failure."""
    from hydrojam.study.replicas import run_replicas

    summary = []

    def run_points(on_point, on_running):
        table, s = run_replicas(design, out, workers=workers, scheduler=scheduler, on_point=on_point,
                                on_running=on_running)
        summary.append(s)
        return table

    def after():
        if quiet or not summary:
            return
        console = Console(stderr=True)
        console.print(_replica_summary(f"hydrojam run: {design_file.name}, {design.replicas.count} replicas -> {out}",
                                       summary[0]))
        console.print(f"summary: {out / 'summary.csv'} and {out / 'summary.json'}; per replica: "
                      f"{out / 'replicas.csv'}", soft_wrap=True)

    _run_with_progress(run_points, out, quiet, after=after)


def _replica_summary(title: str, summary) -> Table:
    """The summary table of replicas: per metric mean ± std, min and max with their replicas."""
    from hydrojam.actuator.metrics import metric

    table = Table(title=title)
    table.add_column("metric", no_wrap=True, min_width=len("contacts_per_particle"))
    for col in ("mean", "std", "min (replica)", "max (replica)", "n"):
        table.add_column(col, justify="right")
    table.add_column("unit")

    def num(v):
        return "—" if v is None else f"{v:.4g}"

    for name in ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm", "curling_index", "packing_fraction",
                 "contacts_per_particle", "newton_iterations", "wall_time_s"):
        sp = summary.stats[name]
        table.add_row(name, num(sp.mean), num(sp.std), f"{num(sp.min)} (#{sp.argmin})" if sp.n else "—",
                      f"{num(sp.max)} (#{sp.argmax})" if sp.n else "—", f"{sp.n}/{summary.count}", metric(name).unit)
    table.caption = (f"seed {summary.design.replicas.seed}, jitter {summary.design.replicas.jitter:g} x clearance; "
                     f"wall time {summary.wall_time_s:.1f} s (replicas in parallel), summed {summary.compute_time_s:.1f} s"
                     + (f"; states: {summary.states_text}" if summary.states_text else ""))
    return table


#: the metrics of `hydrojam run`'s summary table, in its order (units and meanings from the registry)
RUN_SUMMARY = ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm", "curling_index", "packing_fraction",
               "contacts_per_particle", "converged", "stabilisation_released", "newton_iterations", "wall_time_s")
#: added to the summary of a time-resolved run (stimulus.schedule)
TIMED_SUMMARY = ("time_s", "particle_time_constant_s", "time_to_90_percent_angle_s", "swelling_time_to_90_percent_s",
                 "max_bending_angle_deg",
                 "cycle_return_deg", "hysteresis_deg")


def _run_summary(title: str, metrics: dict) -> Table:
    """The summary table of a run: metric, value, unit and meaning (:mod:`hydrojam.actuator.metrics`)."""
    from hydrojam.actuator.metrics import metric

    table = Table(title=title)
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_column("unit")
    table.add_column("meaning")
    keys = RUN_SUMMARY + (TIMED_SUMMARY if metrics.get("time_s") is not None else ())
    for key in keys:
        m, v = metric(key), metrics.get(key)
        table.add_row(key, f"{v:.4g}" if isinstance(v, float) else str(v), m.unit, m.description)
    return table


def _point_label(points) -> str:
    """A study point in a few words from the study points sharing its design: sweep[index],
    replica, values (a replica of `hydrojam run --replicas`: its number)."""
    from hydrojam.study.replicas import REPLICA_STUDY

    p = points[0]
    if p.sweep == REPLICA_STUDY and list(p.values) == ["replicas.count"]:  # `hydrojam run --replicas`
        return f"replica {p.replica}"
    values = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in p.values.items())
    replica = f" replica {p.replica}" if p.replicas > 1 else ""
    return f"{p.sweep}[{p.index}]{replica} {values}"


@app.command()
def sweep(
    study_file: Path = typer.Argument(..., help="Study file (TOML): a base design and named sweeps over it, see docs/sweeps.md."),
    out: Path = typer.Option(..., "-o", "--out", help="Output folder: points/<key>/ per design, results.csv and .parquet; rerun to resume."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes, one thread each (default: one per CPU)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Address of a running dask scheduler, e.g. tcp://10.0.0.5:8786."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar and no summary."),
    replicas: Optional[int] = typer.Option(None, "--replicas", help="Replicas per point (the table holds their mean and spread); default: the base design's replicas.count."),
    table_only: bool = typer.Option(False, "--table-only", help="Run nothing: the table of the points finished in OUT so far, the others as not finished (a study in progress)."),
    plot: Optional[str] = typer.Option(None, "--plot", help="Also draw these metrics (comma-separated, e.g. bending_angle_deg,twist_deg) against each sweep's varied field: OUT/figures/<sweep>.png."),
) -> None:
    """Run every point of a study in parallel (dask), cached in OUT/points/, and write the table.

    Points already finished in OUT (ok or not converged) are loaded, not run again; failed and
    unfinished ones are run. Exit status 0 when every point reached its target stimulus (with
    --table-only: every finished one), 1 when any failed or stopped early (the table is still
    written), 2 on bad input.
    """
    from hydrojam.actuator.design import DesignError
    from hydrojam.study.spec import load_study
    from hydrojam.study.sweep import run_sweep

    replicas = _check_replicas(replicas)
    metrics = _check_plot(plot)
    if table_only:
        _check_nothing_runs("--table-only", workers, scheduler, out)
    else:
        _check_workers(workers, scheduler, out)
    if not study_file.is_file():
        raise InputError(f"{study_file}: no such study file")
    try:
        study = load_study(study_file)
    except DesignError as err:
        raise InputError(str(err)) from None
    if replicas is not None:
        try:
            study = study.with_replicas(replicas)
        except DesignError as err:
            raise InputError(f"--replicas: {err}") from None

    def figures(table):
        if metrics:
            from hydrojam.study.plots import write_sweep_figures

            for path in write_sweep_figures(study, table, out, metrics):
                if not quiet:
                    Console(stderr=True).print(f"figure: {path}", soft_wrap=True)
        return table

    if table_only:
        _interim_report(lambda: figures(run_sweep(study, out, run=False)), out, quiet)
        return
    _run_with_progress(lambda on_point, on_running: run_sweep(study, out, workers=workers, scheduler=scheduler,
                                                              on_point=on_point, on_running=on_running), out, quiet,
                       after=(lambda: figures(run_sweep(study, out, run=False))) if metrics else None)


def _check_plot(plot: Optional[str]) -> list[str]:
    """The metrics of ``sweep --plot`` (none without it); InputError naming --plot for a bad one."""
    if plot is None:
        return []
    from hydrojam.study.plots import check_plot_metrics

    names = [n.strip() for n in plot.split(",") if n.strip()]
    try:
        check_plot_metrics(names)
    except ValueError as err:
        raise InputError(str(err)) from None
    return names


#: seconds between two lines on the running points where stderr is not a terminal (a log file)
RUNNING_LOG_INTERVAL_S = 600.0


def _release_text(progress) -> str:
    """A release's progress (:class:`~hydrojam.actuator.checkpoint.ReleaseProgress`) in a few words."""
    return f"releasing the stabilisation: {progress.summary()}"


def _running_text(running) -> str:
    """The running points in a few words: label, s reached and run time, and at s = 1 the release's
    progress."""
    from hydrojam._format import duration

    return "; ".join(f"{_point_label(r.points)}: s = {r.s:.3f} after {duration(r.wall_time_s)}"
                     + ("" if r.release is None else f", {_release_text(r.release)}") for r in running)


def _run_with_progress(run_points, out: Path, quiet: bool, report: bool = False, after=None) -> None:
    """Run ``run_points(on_point, on_running)`` (a sweep) under a progress bar over points, with
    the running points' progress (the load parameter s reached), print the summary (then call
    ``after()``) and exit 1 when a point failed or stopped early. Where stderr is not a terminal
    (a log file), a line per finished point and the running points every 10 minutes instead."""
    import threading
    import time

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
    from rich.text import Text

    from hydrojam.actuator.design import DesignError
    from hydrojam._format import duration
    from hydrojam.study.cache import PointStatus
    from hydrojam.study.sweep import SchedulerError

    console = Console(stderr=True)
    counts = {PointStatus.OK: 0, PointStatus.NOT_CONVERGED: 0, PointStatus.FAILED: 0}
    cached = [0]
    t0 = time.perf_counter()
    columns = [TextColumn("[bold]points"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[info]}"),
               TimeElapsedColumn()]
    log = not console.is_terminal
    # started at the first point: a refused --scheduler leaves no progress bar behind
    progress = Progress(*columns, console=console, disable=quiet or log, transient=False)
    task = progress.add_task("points", total=None, info="")
    last_info, logged = [""], [time.perf_counter()]
    started_lock = threading.Lock()

    def on_running(running, done, total):
        if quiet:
            return
        text = _running_text(running)
        if log:
            if running and time.perf_counter() - logged[0] >= RUNNING_LOG_INTERVAL_S:
                logged[0] = time.perf_counter()
                console.print(f"{time.strftime('%H:%M:%S')} running: {text}", soft_wrap=True, highlight=False)
        else:
            with started_lock:
                if not progress.live.is_started:
                    progress.start()
            progress.update(task, completed=done, total=total,
                            info=last_info[0] + (f" | running: {text}" if text else ""))

    def on_point(outcome, done, total):
        with started_lock:
            if not progress.live.is_started:
                progress.start()
        counts[outcome.status] = counts.get(outcome.status, 0) + 1
        cached[0] += outcome.cached
        if outcome.status == PointStatus.FAILED:
            info = f"[red]{_point_label(outcome.points)}: {outcome.error}[/red]"
        else:
            angle = (outcome.metrics or {}).get("bending_angle_deg")
            info = _point_label(outcome.points) + (f": {angle:.1f} deg" if isinstance(angle, (int, float)) else "")
            if outcome.status == PointStatus.NOT_CONVERGED:
                info = f"[yellow]{info} (stopped early)[/yellow]"
        info += " (cached)" if outcome.cached else ""
        if outcome.damaged and not quiet:
            console.print(f"hydrojam: {_point_label(outcome.points)}: computed again, its {', '.join(outcome.damaged)} "
                          "no longer matching the checksum kept when it finished", soft_wrap=True, highlight=False,
                          markup=False)
        last_info[0] = info
        progress.update(task, completed=done, total=total, info=info)
        if log and not quiet and not outcome.cached:
            wall = outcome.wall_time_s
            took = f" after {duration(wall)}" if isinstance(wall, (int, float)) else ""
            plain = Text.from_markup(info).plain
            console.print(f"{time.strftime('%H:%M:%S')} point {done}/{total} {outcome.status}{took}: {plain}",
                          soft_wrap=True, highlight=False, markup=False)

    try:
        result = run_points(on_point, on_running)
    except SchedulerError as err:
        raise InputError(f"--scheduler: {err}") from None
    except DesignError as err:
        raise InputError(str(err)) from None
    except BaseException as err:
        if progress.live.is_started:
            progress.stop()
        _stopped(err, lambda: _sweep_stand(out, progress.tasks[0]))
        raise
    finally:
        if progress.live.is_started:
            progress.stop()
    table = result[0] if isinstance(result, tuple) else result
    wall = time.perf_counter() - t0
    n = sum(counts.values())
    if not quiet:
        console.print(
            f"hydrojam: {n} distinct points ({len(table)} rows): {counts[PointStatus.OK]} ok, "
            f"{counts[PointStatus.NOT_CONVERGED]} not converged, {counts[PointStatus.FAILED]} failed; {cached[0]} cached, "
            f"{n - cached[0]} computed; wall time {wall:.1f} s"
        )
        console.print(f"table: {out / 'results.csv'} and {out / 'results.parquet'}", soft_wrap=True)
        if report:
            console.print(f"report: {result[1]} (figures in {out / 'figures'})", soft_wrap=True)
    if after is not None:
        after()
    if counts[PointStatus.FAILED] or counts[PointStatus.NOT_CONVERGED]:
        console.print(f"[red]hydrojam: {counts[PointStatus.FAILED]} point(s) failed and "
                      f"{counts[PointStatus.NOT_CONVERGED]} stopped "
                      f"early; see the status and error columns of {out / 'results.csv'} (a rerun retries the "
                      f"failed ones)[/red]", soft_wrap=True)
        raise typer.Exit(code=1)


def _sweep_stand(out: Path, task) -> str:
    """Where a study's run into ``out`` stopped midway stands (``task``: its progress bar's task,
    points done of total), and how to go on, as the end of a line."""
    from hydrojam.actuator.checkpoint import CHECKPOINT

    done = int(task.completed or 0)
    finished = f"{done} of {int(task.total)} points finished" if task.total else f"{done} points finished"
    kept = sum(1 for f in (out / "points").glob(f"*/{CHECKPOINT}")
               if not (f.parent / "point.json").exists()) if (out / "points").is_dir() else 0
    checkpoints = f", {kept} unfinished keep their checkpoints" if kept else ""
    return f": {finished} (in {out / 'points'}){checkpoints}; run the same command again to go on"


def _check_nothing_runs(flag: str, workers: Optional[int], scheduler: Optional[str], out: Path) -> None:
    """``flag`` (--report-only, --table-only) runs nothing: no --workers or --scheduler, and OUT
    must be a folder (a study already run or started there)."""
    if workers is not None or scheduler is not None:
        raise InputError(f"--{'workers' if workers is not None else 'scheduler'}: nothing runs with {flag}")
    if not out.is_dir():
        raise InputError(f"--out: {out}: {'not a folder' if out.exists() else 'no such folder'} ({flag} "
                         "writes the results of a study already run or started there)")


def _interim_report(write, out: Path, quiet: bool) -> None:
    """Call ``write()`` (a table, or a (table, report path), written without running: ``sweep
    --table-only``, ``reproduce --report-only``), print how many distinct designs (each replica
    one, as a run counts them) are in each state and where the results are, and exit 1 when a
    finished one failed or stopped early."""
    from hydrojam.actuator.design import DesignError
    from hydrojam.study.cache import ROW_STATUSES, PointStatus
    from hydrojam.study.table import run_states

    try:
        result = write()
    except DesignError as err:
        raise InputError(str(err)) from None
    table, path = result if isinstance(result, tuple) else (result, None)
    by_key = run_states(out, table)
    counts = {st: sum(v == st for v in by_key.values()) for st in ROW_STATUSES}
    console = Console(stderr=True)
    if not quiet:
        console.print(f"hydrojam: nothing run; {len(by_key)} distinct points ({len(table)} rows): "
                      f"{counts[PointStatus.OK]} ok, {counts[PointStatus.NOT_CONVERGED]} not converged, "
                      f"{counts[PointStatus.FAILED]} failed, {counts[PointStatus.UNFINISHED]} not finished",
                      soft_wrap=True)
        console.print(f"table: {out / 'results.csv'} and {out / 'results.parquet'}", soft_wrap=True)
        if path is not None:
            console.print(f"report: {path} (figures in {out / 'figures'})", soft_wrap=True)
    if counts[PointStatus.FAILED] or counts[PointStatus.NOT_CONVERGED]:
        raise typer.Exit(code=1)


def _check_workers(workers: Optional[int], scheduler: Optional[str], out: Path) -> None:
    if workers is not None and workers < 1:
        raise InputError(f"--workers: must be >= 1 (got {workers})")
    if workers is not None and scheduler is not None:
        raise InputError("--workers: only without --scheduler (the scheduler's workers run the points)")
    if out.exists() and not out.is_dir():
        raise InputError(f"--out: {out} exists and is not a folder")


@app.command()
def reproduce(
    out: Path = typer.Option(..., "-o", "--out", help="Output folder: report.md, figures/, results.csv/.parquet, points/; rerun to resume."),
    quick: bool = typer.Option(False, "--quick", help="Coarser mesh (4 mm) and fewer points (12 rows, 10 designs): minutes in 2D, tens of CPU hours in 3D (days on 2 cores)."),
    dimension: int = typer.Option(2, "--dimension", help="2 (plane strain, cylinders) or 3 (spheres, the half model): a study of its own, in its own output folder."),
    compare_2d: Optional[Path] = typer.Option(None, "--compare-2d", help="With --dimension 3: the output folder of the 2D study of the same kind (quick or full); the report adds a 2D-against-3D table."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes, one thread each (default: one per CPU)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Address of a running dask scheduler, e.g. tcp://10.0.0.5:8786."),
    sweep: list[str] = typer.Option([], "--sweep", help="Run only this sweep (repeatable): temperature, particle_layers, strain_limit_thickness, and in 3D strain_limit_width (the paper's h read as the strip's width); a later run into the same folder adds the others."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar and no summary."),
    replicas: int = typer.Option(1, "--replicas", help="Replicas per point: the table and figures give their mean and spread, and a statement agrees or disagrees only beyond the spread."),
    report_only: bool = typer.Option(False, "--report-only", help="Run nothing: the table, figures and report.md of the points finished in OUT so far, the others shown as not finished (an interim report of a study in progress)."),
    overrides: list[str] = typer.Option([], "--set", help="Change a model choice for every point, e.g. --set friction=0.1 (repeatable): a study of its own, for its own output folder (docs/reproduce.md, \"Sensitivity\")."),
    write_results: list[Path] = typer.Option([], "--write-results", help="A Markdown page whose marked sections take the results: '<!-- reproduce: STUDY -->' the points table with a line of conditions, 'STUDY verdicts', 'STUDY time' the cost, 'STUDY compare' the 2D-against-3D verdicts (with --compare-2d), 'STUDY figures' the trend figures (copied into _static/STUDY/ beside the page), 'KIND sensitivity' one row per model choice (repeatable; e.g. README.md, docs/reproduce.md)."),
) -> None:
    """Reproduce the paper's Section IV (2D, or 3D with --dimension 3): the temperature,
    particle-layer and strain-limit thickness sweeps (in 3D also the strip width), their figures and
    OUT/report.md (the paper's statements, agree/disagree, per state of the replicas; in 3D also 2D
    against 3D with --compare-2d).

    Cached and resumable like `hydrojam sweep`. Exit status 0 when every point converged (with
    --report-only: every finished one), 1 when any failed or stopped early (the report is still
    written), 2 on bad input.
    """
    from hydrojam.paper.compare import CompareError, read_2d_results
    from hydrojam.paper.reproduce import reproduce as run_reproduce
    from hydrojam.paper.sections import SectionError, check_page
    from hydrojam.paper.study import DIMENSIONS, paper_study, study_name

    if dimension not in DIMENSIONS:
        raise InputError(f"--dimension: allowed {' or '.join(map(str, DIMENSIONS))} (got {dimension})")
    if compare_2d is not None and dimension != 3:
        raise InputError("--compare-2d: only with --dimension 3 (it compares the 3D study with a 2D one)")
    _check_replicas(replicas)
    try:
        paper_study(quick, dimension=dimension, overrides=overrides)
    except ValueError as err:
        raise InputError(str(err)) from None
    try:
        paper_study(quick, sweep or None, dimension=dimension)
    except ValueError as err:
        raise InputError(f"--sweep: {err}") from None
    if report_only:
        _check_nothing_runs("--report-only", workers, scheduler, out)
    else:
        _check_workers(workers, scheduler, out)
    if compare_2d is not None:
        try:
            read_2d_results(compare_2d, quick)
        except CompareError as err:
            raise InputError(f"--compare-2d: {err}") from None
    for page in write_results:
        try:
            check_page(page, study_name(quick, dimension, overrides))
        except SectionError as err:
            raise InputError(f"--write-results: {err}") from None
    if report_only:
        _interim_report(lambda: run_reproduce(out, quick=quick, sweeps=sweep or None, replicas=replicas,
                                              dimension=dimension, compare_2d=compare_2d, report_only=True,
                                              results_pages=write_results, overrides=overrides),
                        out, quiet)
        return
    _run_with_progress(lambda on_point, on_running: run_reproduce(
                           out, quick=quick, workers=workers, scheduler=scheduler, sweeps=sweep or None,
                           on_point=on_point, replicas=replicas, dimension=dimension, compare_2d=compare_2d,
                           on_running=on_running, results_pages=write_results, overrides=overrides),
                       out, quiet, report=True)


@app.command("assess")
def assess_design(
    design_file: Path = typer.Argument(..., help="Design file (TOML), e.g. from `hydrojam init`."),
    out: Path = typer.Option(..., "-o", "--out", help="Output folder: report.md, assessment.json, design.toml, *.png."),
    loads_file: Optional[Path] = typer.Option(None, "--loads", help="Loads file (TOML; keys in docs/assess.md); the options below override it."),
    max_force: Optional[float] = typer.Option(None, "--max-force", help="Largest tip force of the curves, > 0 [N/mm per mm of depth in 2D; N of the whole actuator in 3D]."),
    vacuum_kpa: Optional[float] = typer.Option(None, "--vacuum-kpa", help="Vacuum baseline's pressure difference in kPa, in (0, 101.325]."),
    pneumatic_angle: Optional[float] = typer.Option(None, "--pneumatic-angle", help="Bending angle the pneumatic baseline is pressurised to [deg], in (0, 360]; default: the actuator's own."),
    pneumatic_max_kpa: Optional[float] = typer.Option(None, "--pneumatic-max-kpa", help="Largest inner pressure of the pneumatic baseline in kPa, in (0, 1000]."),
    replicas: Optional[int] = typer.Option(None, "--replicas", help="Assess N replicas in parallel (jittered particle centres) and give every figure with its spread."),
    workers: Optional[int] = typer.Option(None, "--workers", help="With replicas: local worker processes, one thread each (default: one per CPU)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="With replicas: address of a running dask scheduler."),
    temperatures: Optional[str] = typer.Option(None, "--temperatures", help="Blocked-force temperatures [K], comma-separated, e.g. 275,285,295."),
    overrides: list[str] = typer.Option([], "--set", help="Change a design field, e.g. --set particle_layers=1 (repeatable)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress messages."),
) -> None:
    """Assess a design as a jamming actuator: bending, stiffness ratio (actuated / unactuated),
    blocked force against temperature, the vacuum-jamming and pneumatic baselines and the
    confinement, in 2D (per mm of depth) or 3D (N and N/mm of the whole actuator); writes
    OUT/report.md with its figures. With --replicas N > 1 the replicas run in parallel (OUT/points/
    holds each one's report) and every figure comes with its spread. Exit status 0 when every part
    converged, 1 when one stopped early (the report says which), 2 on bad input. See docs/assess.md."""
    from hydrojam.assess.spec import AssessError, load_loads, loads_from_dict

    replicas = _check_replicas(replicas)
    if workers is not None and workers < 1:
        raise InputError(f"--workers: must be >= 1 (got {workers})")
    if (workers is not None or scheduler is not None) and not (replicas or 1) > 1:
        raise InputError(f"{'--workers' if workers is not None else '--scheduler'}: only with --replicas N > 1 "
                         f"(got {'--replicas ' + str(replicas) if replicas is not None else 'no --replicas'})")
    if scheduler is not None:
        from hydrojam.study.sweep import SchedulerError, check_address

        try:
            check_address(scheduler)
        except (SchedulerError, ValueError) as err:
            raise InputError(f"--scheduler: {err}") from None

    if not design_file.is_file():
        raise InputError(f"{design_file}: no such design file")
    design = _design_or_exit(design_file, overrides)
    try:
        data = {} if loads_file is None else load_loads(loads_file).model_dump(exclude_unset=True)
    except AssessError as err:
        raise InputError(str(err)) from None
    options = {"max_force": max_force, "vacuum_pressure": vacuum_kpa, "pneumatic_angle": pneumatic_angle,
               "pneumatic_max_pressure": pneumatic_max_kpa}
    for key, value in options.items():
        if value is not None:
            data[key] = value
    if temperatures is not None:
        try:
            data["temperatures"] = tuple(float(t) for t in temperatures.split(","))
        except ValueError:
            raise InputError(f"--temperatures: expected comma-separated numbers [K], e.g. 275,285,295 (got {temperatures!r})") from None
    names = {"max_force": "--max-force", "vacuum_pressure": "--vacuum-kpa", "temperatures": "--temperatures",
             "pneumatic_angle": "--pneumatic-angle", "pneumatic_max_pressure": "--pneumatic-max-kpa"}
    try:
        loads = loads_from_dict(data, names)
    except AssessError as err:
        raise InputError(str(err)) from None
    from hydrojam.actuator.design import DesignError
    from hydrojam.assess.assessment import assess, check_assessable

    try:
        check_assessable(design)
    except DesignError as err:
        raise InputError(str(err)) from None
    if out.exists() and not out.is_dir():
        raise InputError(f"--out: {out} exists and is not a folder")
    from hydrojam.assess.report import write_report

    console = Console(stderr=True)
    if replicas is not None and replicas > 1:
        _assess_replicas(design, loads, out, replicas, workers, scheduler, quiet, console)
        return
    with _output_folder(out, FolderKind.ASSESSMENT):
        result = assess(design, loads, on_progress=None if quiet else lambda m: console.print(f"hydrojam assess: {m}..."))
        report = write_report(result, out)
    if not quiet:
        console.print(f"report: {report}", soft_wrap=True)
    v = result.values
    stopped = [name for name, ok in (("actuation", v["actuation_converged"]),
                                     *((f"{k} curve", c.converged) for k, c in result.curves.items()),
                                     *((f"blocked force at {b['temperature_K']:g} K", b["converged"]) for b in result.blocked))
               if not ok]
    if stopped:
        console.print(f"[red]hydrojam: stopped early: {', '.join(stopped)} (see {report})[/red]", soft_wrap=True)
        raise typer.Exit(code=1)


def _assess_replicas(design, loads, out: Path, replicas: int, workers, scheduler, quiet: bool, console) -> None:
    """`hydrojam assess --replicas N`: the replicas' assessments in parallel, the report with every
    figure's spread; exit status 1 when a replica failed or a part of one stopped early."""
    from hydrojam.assess.replicas import assess_replicas, check_replica_folder
    from hydrojam.assess.report import write_replica_report
    from hydrojam.assess.spec import AssessError

    try:
        check_replica_folder(out, loads)
    except AssessError as err:
        raise InputError(str(err)) from None

    def on_point(outcome, done, total):
        if not quiet:
            console.print(f"hydrojam assess: replica {done}/{total} {outcome.status}"
                          f"{'' if not outcome.error else ': ' + outcome.error}", soft_wrap=True)

    from hydrojam.actuator.design import DesignError
    from hydrojam.study.sweep import SchedulerError

    if not quiet:
        console.print(f"hydrojam assess: {replicas} replicas in parallel...")
    try:
        result = assess_replicas(design, loads, out, replicas, workers=workers, scheduler=scheduler, on_point=on_point)
    except SchedulerError as err:
        raise InputError(f"--scheduler: {err}") from None
    except DesignError as err:  # a folder of another kind, or held by a live run: before any work
        raise InputError(str(err)) from None
    report = write_replica_report(result, out)
    if not quiet:
        console.print(f"report: {report}", soft_wrap=True)
    bad = [run for run in result.runs if run.get("status") != "ok"]
    if bad:
        console.print(f"[red]hydrojam: {len(bad)} of {len(result.runs)} replicas failed or stopped early "
                      f"(see {report})[/red]", soft_wrap=True)
        raise typer.Exit(code=1)


def _numbers(option: str, text: str, unit: str) -> list[float]:
    """Comma-separated numbers of a CLI option, or InputError naming it (their range is the
    design field's: :func:`_field_values`)."""
    try:
        return [float(t) for t in text.split(",")]
    except ValueError:
        raise InputError(f"{option}: expected comma-separated numbers in {unit}, e.g. 1,2,4 (got {text!r})") from None


def _field_values(design, option: str, field: str, values: list[float]) -> None:
    """Each of ``values`` of a CLI list option that feeds the design field ``field`` (dotted) put
    into ``design`` and validated as that field is everywhere (its range, non-finite numbers, the
    design's checks); InputError naming the option, the value and the field's rule."""
    from hydrojam.actuator.design import DesignError, apply_overrides

    for v in values:
        item = f"{field}={v!r}"
        try:
            apply_overrides(design, [item])
        except DesignError as err:
            raise InputError(f"{option} {v:g}: {str(err).removeprefix(f'--set {item}: ')}") from None


@app.command("design-map")
def design_map_command(
    design_file: Path = typer.Argument(..., help="Base design file (TOML)."),
    out: Path = typer.Option(..., "-o", "--out", help="Output folder: points/ (cached, resumable), design_map.csv, design_map.png."),
    thickness: str = typer.Option("1,2,4", "--thickness", help="Membrane side-wall thicknesses t0 in mm, comma-separated."),
    modulus: str = typer.Option("0.023,0.07,0.2", "--modulus", help="Membrane shear moduli G in MPa, comma-separated (Ecoflex 00-30 0.023 ... Dragon Skin 30-class 0.2)."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes, one thread each (default: one per CPU)."),
    overrides: list[str] = typer.Option([], "--set", help="Change a base design field (repeatable)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress messages."),
) -> None:
    """The membrane design map: bending angle, stiffness ratio and confinement (contact against
    swelling pressure) over wall thickness x shear modulus, one assessment (no blocked force, no
    vacuum) per point, run as a cached sweep. See docs/assess.md."""
    if not design_file.is_file():
        raise InputError(f"{design_file}: no such design file")
    design = _design_or_exit(design_file, overrides)
    from hydrojam.actuator.design import DesignError
    from hydrojam.assess.design_map import MAP_VALUES, MODULUS, THICKNESS, design_map, map_study

    ts, gs = _numbers("--thickness", thickness, "mm"), _numbers("--modulus", modulus, "MPa")
    _field_values(design, "--thickness", THICKNESS, ts)
    _field_values(design, "--modulus", MODULUS, gs)
    try:
        map_study(design, ts, gs)  # every pair, before any work
    except DesignError as err:
        raise InputError(f"--thickness/--modulus: {err}") from None
    _check_workers(workers, None, out)

    console = Console(stderr=True)

    def on_point(outcome, done, total):
        if not quiet:
            console.print(f"hydrojam design-map: point {done}/{total} {outcome.status}{' (cached)' if outcome.cached else ''}")

    try:
        rows = design_map(design, ts, gs, out, workers=workers, on_point=on_point)
    except DesignError as err:
        raise InputError(str(err)) from None
    from hydrojam._io import finite_or_none, write_text_atomic

    buffer = io.StringIO()
    writer = csv.writer(buffer)
    columns = [THICKNESS, MODULUS, *MAP_VALUES]
    writer.writerow(columns)
    for r in rows:
        writer.writerow(["" if finite_or_none(r.get(c)) is None else r.get(c) for c in columns])
    write_text_atomic(out / "design_map.csv", buffer.getvalue())
    if not quiet:
        console.print(f"map: {out / 'design_map.csv'} and {out / 'design_map.png'}", soft_wrap=True)
    if any(r.get("converged") is not True for r in rows):
        console.print("[red]hydrojam: some points failed or stopped early (empty cells in design_map.csv)[/red]")
        raise typer.Exit(code=1)


#: errno values of file-system errors, reported as one line (exit status 2) rather than a traceback
_FILE_SYSTEM_ERRORS = frozenset(
    getattr(errno, name) for name in ("ENOTDIR", "EISDIR", "EEXIST", "ENOENT", "EACCES", "EPERM", "ENOSPC",
                                      "EDQUOT", "EROFS", "ENAMETOOLONG", "ELOOP", "EFBIG", "EMFILE", "ENFILE",
                                      "EXDEV", "EBUSY", "ETXTBSY")
    if hasattr(errno, name)
)


def _measured(metrics: dict | None) -> str:
    """A release's current state in a few words (``hydrojam status --measure``)."""
    if metrics is None:
        return ""
    return (f"; now {metrics['bending_angle_deg']:.2f} deg, tip ({metrics['tip_dx_mm']:.1f}, "
            f"{metrics['tip_dz_mm']:.1f}) mm")


@app.command()
def status(
    out: Path = typer.Argument(..., help="Output folder of `hydrojam sweep`, `reproduce`, `design-map`, `run --replicas` or `run`."),
    measure: bool = typer.Option(False, "--measure", help="Also the angle and tip of every unfinished release's current state (builds its model: up to a minute a 3D point)."),
) -> None:
    """Where an output folder stands, read from its files (nothing runs): each point of its study
    (or the run) finished, failed, unfinished (the s reached; at s = 1 how far the release has
    gone) or not started, and when it was last written. A run going on in another process shows
    as unfinished, its lock as in use; a run whose process is gone (killed) as stopped. Rerun the
    command that made the folder to go on. Exit status 0, 2 for a folder that is not hydrojam's.
    """
    import time

    from hydrojam._format import duration
    from hydrojam.study.cache import PointStatus
    from hydrojam.study.status import StatusError, folder_status

    if not out.is_dir():
        raise InputError(f"{out}: {'not a folder' if out.exists() else 'no such folder'}")
    try:
        st = folder_status(out, measure=measure)
    except StatusError as err:
        raise InputError(str(err)) from None
    now = time.time()
    table = Table(title=f"{st.kind} {st.name} ({out})")
    for name, justify in (("point", "left"), ("state", "left"), ("s", "right"), ("angle [deg]", "right"),
                          ("run time", "right"), ("written", "right"), ("release / error", "left")):
        table.add_column(name, justify=justify)
    colours = {PointStatus.OK: "green", PointStatus.NOT_CONVERGED: "yellow", PointStatus.FAILED: "red",
               PointStatus.UNFINISHED: "cyan"}
    for r in st.runs:
        label = _point_label(r.points) if r.points else (f"points/{r.key} (not in study.toml)" if r.key else st.name)
        state = r.state.replace("_", " ")
        table.add_row(label, f"[{colours[r.state]}]{state}[/]" if r.state in colours else state,
                      "" if r.s is None else f"{r.s:.3f}",
                      "" if r.bending_angle_deg is None else f"{r.bending_angle_deg:.2f}",
                      "" if r.wall_time_s is None else duration(r.wall_time_s),
                      "" if r.updated is None else f"{duration(max(now - r.updated, 0.0))} ago",
                      r.error or ("" if r.release is None else r.release.summary() + _measured(r.release_metrics)))
    console = Console()
    console.print(table)
    console.print(", ".join(f"{n} {state.replace('_', ' ')}" for state, n in st.counts().items()))
    if st.lock is not None:
        console.print(_lock_text(st.lock, st.lock_state), soft_wrap=True, highlight=False, markup=False)
    if st.kind == FolderKind.STUDY and ({PointStatus.UNFINISHED, PointStatus.NOT_STARTED} & set(st.counts())):
        hint = _paper_commands(out, st.name, st.replicas)
        if hint:
            console.print(hint, soft_wrap=True, highlight=False, markup=False)


def _lock_text(lock: dict, state) -> str:
    """The line of ``hydrojam status`` on a folder's lock: the run holding it, or, where its
    process is gone, that the run was stopped."""
    from hydrojam._io import LockState

    holder = (f"process {lock.get('pid')} on {lock.get('host')}" + (f" since {lock['started']}" if lock.get("started") else "")
              if lock else "")
    if state == LockState.DEAD:
        return (f"stopped (its process is gone); rerun to resume ({holder or 'its lock file cannot be read'}; "
                "the next run takes its lock file over)")
    if not lock:
        return "in use by an unknown process (its lock file cannot be read yet)"
    if state == LockState.ELSEWHERE:
        return f"in use by {holder} (another host, so not checked here; its lock file)"
    return f"in use by {holder} (its lock file)"


@app.command()
def snapshot(
    out: Path = typer.Argument(..., help="Output folder of `hydrojam sweep`, `reproduce`, `design-map`, `run --replicas` or `run`, in progress."),
    dest: Path = typer.Option(..., "-o", "--out", help="Folder for the snapshots: <name>.vtu (ParaView) and <name>.png per unfinished run."),
) -> None:
    """The current state of every unfinished run in OUT, as files: its last accepted state on
    the load path, or at s = 1 its release's current centre (not an equilibrium yet), read from
    its checkpoint; DEST/<key>.vtu and DEST/<key>.png (as final.png). Nothing runs; a run going
    on elsewhere is drawn at its last checkpoint. Exit status 0, 2 for a folder that is not
    hydrojam's or a DEST that cannot be a folder.
    """
    from hydrojam.study.snapshot import write_snapshots
    from hydrojam.study.status import StatusError

    if not out.is_dir():
        raise InputError(f"{out}: {'not a folder' if out.exists() else 'no such folder'}")
    if dest.exists() and not dest.is_dir():
        raise InputError(f"--out: {dest} exists and is not a folder")
    from hydrojam._io import FolderKindError, check_folder_kind

    try:
        check_folder_kind(dest, FolderKind.SNAPSHOTS)
    except FolderKindError as err:
        raise InputError(f"--out: {err}") from None
    console = Console(stderr=True)
    try:
        shots = write_snapshots(out, dest, on_run=lambda name, points: console.print(
            f"drawing {_point_label(points) if points else name}...", highlight=False))
    except StatusError as err:
        raise InputError(str(err)) from None
    if not shots:
        console.print(f"hydrojam: no unfinished run with a checkpoint in {out}: nothing drawn", soft_wrap=True)
        return
    for shot in shots:
        label = _point_label(shot.points) if shot.points else shot.name
        where = "its release under way" if shot.releasing else f"s = {shot.s:.3f}"
        m = shot.metrics
        console.print(f"{label}: {where}, {m['bending_angle_deg']:.2f} deg, tip ({m['tip_dx_mm']:.1f}, "
                      f"{m['tip_dz_mm']:.1f}) mm: {shot.vtu}, {shot.png}", soft_wrap=True, highlight=False)


def _flat(data: dict, prefix: str = "") -> dict:
    """A nested design dump as dotted leaf fields ("membrane.shear_modulus": 0.046)."""
    out = {}
    for key, value in data.items():
        if isinstance(value, dict):
            out.update(_flat(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def _paper_commands(out: Path, name: str, replicas: int) -> str | None:
    """For the folder of a paper study in progress (``reproduce``'s, by its study's name, with
    ``replicas`` per point): the commands that write its interim report and go on with it, with
    the study's ``--sweep`` subset and its model choices (``--set``, read as the fields where its
    base design differs from the paper's); None for another study."""
    from hydrojam.paper.study import paper_base, paper_sweeps, reproduce_command, study_kind
    from hydrojam.study.spec import load_study

    kind = study_kind(name)
    if kind is None:
        return None
    quick, dimension = kind
    overrides, sweeps = [], ""
    try:
        study = load_study(out / "study.toml")
    except (OSError, ValueError):
        study = None
    if study is not None:
        own = _flat(study.base.model_dump(exclude={"replicas"}))
        paper = _flat(paper_base(quick, dimension=dimension).model_dump(exclude={"replicas"}))
        overrides = [f"{k}={own[k]!r}" if isinstance(own[k], str) else f"{k}={own[k]}"
                     for k in own if k in paper and own[k] != paper[k]]
        names = [sw.name for sw in study.sweeps]
        if names != [sw.name for sw in paper_sweeps(dimension)]:
            sweeps = "".join(f" --sweep {n}" for n in names)
    command = reproduce_command(quick, dimension, replicas, overrides) + sweeps
    return f"report so far: {command} -o {out} --report-only\ngo on: {command} -o {out}"


def _file_system_error(err: OSError) -> str | None:
    """One line for a file-system error, naming the path ("afile/sub: Not a directory"), or None
    for another OSError (a bug, a network error: left to propagate)."""
    if err.errno not in _FILE_SYSTEM_ERRORS and err.filename is None:
        return None
    what = err.strerror or str(err)
    if err.filename is None:
        return what
    where = os.fspath(err.filename)
    if err.filename2 is not None:
        where += f" -> {os.fspath(err.filename2)}"
    return f"{where}: {what}"


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``hydrojam`` command; returns the exit status. SIGINT and SIGTERM stop
    a command cleanly (its lock released, its workers closed) with one line saying what stopped
    it and where it stands: exit status 130 and 143 (:mod:`hydrojam._interrupt`)."""
    from hydrojam._interrupt import stop_on_signals

    with stop_on_signals():
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    from hydrojam._interrupt import interruption

    try:
        _check_environment(sys.argv[1:] if argv is None else list(argv))
        # without standalone mode click returns a typer.Exit's code instead of raising it
        status = app(args=argv, prog_name="hydrojam", standalone_mode=False)
    except InputError as err:
        print(f"hydrojam: error: {err}", file=sys.stderr)
        return 2
    except _click_exc.NoArgsIsHelpError as err:  # a bare `hydrojam`: the help, not an error
        print(err.format_message())
        return 0
    except _click_exc.UsageError as err:
        print(f"hydrojam: error: {err.format_message()}", file=sys.stderr)
        return 2
    except _Stopped as err:
        print(f"hydrojam: {err}", file=sys.stderr)
        return err.stop.exit_status
    except typer.Abort:
        print("hydrojam: aborted", file=sys.stderr)
        return 130
    except typer.Exit as ex:
        stop = interruption(ex.__cause__)  # typer's Exit(130) for a KeyboardInterrupt
        if stop is None:
            return ex.exit_code
        print(f"hydrojam: stopped by {stop.words} before it finished; run the same command again", file=sys.stderr)
        return stop.exit_status
    except OSError as err:
        line = _file_system_error(err)
        if line is None:
            raise
        print(f"hydrojam: error: {line}", file=sys.stderr)
        return 2
    except BaseException as err:  # a stop outside a command's guard, or a numba kernel's SystemError from it
        stop = interruption(err)
        if stop is None:
            raise
        print(f"hydrojam: stopped by {stop.words} before it finished; run the same command again", file=sys.stderr)
        return stop.exit_status
    return status if isinstance(status, int) and not isinstance(status, bool) else 0


if __name__ == "__main__":
    sys.exit(main())


def run() -> None:
    """Console-script wrapper: exit with :func:`main`'s status."""
    sys.exit(main())
