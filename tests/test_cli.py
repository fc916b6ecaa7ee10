"""The `hydrojam` command line: outputs, and one-line errors with exit status 2."""

import errno
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from hydrojam.cli import main


def run(capsys, *args):
    rc = main(list(args))
    out, err = capsys.readouterr()
    return rc, out, err


def test_swell_json_has_the_documented_keys(capsys):
    rc, out, _ = run(capsys, "swell", "--temperatures", "275,285,295,310", "--json")
    assert rc == 0
    data = json.loads(out)
    assert data["mu0"] == pytest.approx(-0.0343, abs=1e-4)
    assert 300 < data["transition_temperature"] < 310
    pts = data["points"]
    assert [p["T"] for p in pts] == [275, 285, 295, 310]
    assert set(pts[0]) == {"T", "stretch", "stretch_rel", "J", "branch"}
    assert [p["branch"] for p in pts] == ["swollen", "swollen", "swollen", "collapsed"]
    for p in pts:
        assert p["stretch_rel"] == pytest.approx(p["stretch"] / 1.5)
        assert p["J"] == pytest.approx(p["stretch"] ** 3)
    assert pts[0]["stretch"] > pts[1]["stretch"] > pts[2]["stretch"] > pts[3]["stretch"]


def test_swell_range_csv_and_table(capsys):
    rc, out, _ = run(capsys, "swell", "--t-min", "280", "--t-max", "290", "--t-step", "5", "--csv")
    assert rc == 0
    lines = out.strip().splitlines()
    assert lines[0] == "T,stretch,stretch_rel,J,branch"
    assert [float(l.split(",")[0]) for l in lines[1:]] == [280.0, 285.0, 290.0]
    rc, out, _ = run(capsys, "swell", "--temperatures", "280")
    assert rc == 0 and "transition" in out and "swollen" in out


def test_swell_plot_writes_png(tmp_path, capsys):
    png = tmp_path / "curve.png"
    rc, _, _ = run(capsys, "swell", "--temperatures", "275,295,310", "--plot", str(png))
    assert rc == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["curve.png"]  # no temporary left behind


@pytest.mark.parametrize(
    "args, option, allowed",
    [
        (["--nnu", "-1"], "--nnu", "(0"),
        (["--lambda0", "0.9"], "--lambda0", "(1.0"),
        (["--temperatures", "abc"], "--temperatures", "273.15"),
        (["--temperatures", "200"], "--temperatures", "273.15"),
        (["--mu", "0.5"], "--mu", "<= 0"),
        (["--t-step", "0"], "--t-step", "> 0"),
        (["--nnu", "abc"], "--nnu", ""),
        (["--no-such-option"], "--no-such-option", ""),
    ],
)
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, args, option, allowed):
    png = tmp_path / "x.png"
    rc, out, err = run(capsys, "swell", *args, "--plot", str(png))
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert option in lines[0] and allowed in lines[0]
    assert "Traceback" not in err and out == ""
    assert not png.exists()


def test_installed_command_exits_2_without_traceback(tmp_path):
    exe = Path(sys.executable).with_name("hydrojam")
    res = subprocess.run([str(exe), "swell", "--nnu", "-1"], capture_output=True, text=True)
    assert res.returncode == 2
    assert res.stderr.strip().count("\n") == 0 and "--nnu" in res.stderr
    assert "Traceback" not in res.stderr


# ---------------------------------------------------------------------------------------------
# hydrojam init / run


def test_init_writes_the_default_design_and_refuses_to_overwrite(tmp_path, capsys):
    from hydrojam.actuator.design import default_design, load_design

    path = tmp_path / "design.toml"
    rc, _, _ = run(capsys, "init", str(path))
    assert rc == 0 and load_design(path) == default_design()
    assert "# as-prepared particle diameter d [mm]" in path.read_text()
    rc, _, err = run(capsys, "init", str(path))
    assert rc == 2 and "--force" in err
    rc, _, _ = run(capsys, "init", str(path), "--force", "--set", "particle_layers=7")
    assert rc == 0 and load_design(path).particle_layers == 7


BAD_DESIGNS = [
    ("cavity_width = 15.0\n", "cavity_width"),
    ("strain_limit_thickness = -1.0\n", "strain_limit_thickness"),
    ("particle_layers = 0\n", "particle_layers"),
    ("particle_diameterr = 16.0\n", "particle_diameterr"),
    ("[stimulus]\ntemperature = 400.0\n", "stimulus.temperature"),
    ("dimension = 3\ncavity_depth = 15.0\n", "cavity_depth"),  # spheres deeper than the 3D cavity
    ("[mesh]\nsymmetry = false\n", "mesh.symmetry"),  # a 2D design has no depth to cut
    # time-resolved stimulus (issue 16): each bad schedule, and a diffusivity <= 0, refused before any work
    ("[stimulus]\nschedule = [[0, 300], [60, 275], [60, 280]]\n", "stimulus.schedule: times must increase"),
    ("[stimulus]\nschedule = [[0, 300], [60, 275], [30, 280]]\n", "stimulus.schedule: times must increase"),
    ("[stimulus]\nschedule = [[10, 300], [60, 275]]\n", "stimulus.schedule: the first time must be 0"),
    ("[stimulus]\nschedule = [[0, 300], [60, 270]]\n", "stimulus.schedule: point 1: temperature must be in liquid water's range [273.15, 373.15] K"),
    ("[stimulus]\nschedule = [[0, 380], [60, 300]]\n", "stimulus.schedule: point 0: temperature"),
    ("[stimulus]\nschedule = [[0, 300]]\n", "stimulus.schedule: needs 2 to 1000"),
    ("[stimulus]\nschedule = [[0, 300, 1], [60, 275]]\n", "stimulus.schedule: point 0: expected a list of [time_s, temperature_K]"),
    ("[stimulus]\nschedule = 300\n", "stimulus.schedule: expected a list"),
    ("[stimulus]\nschedule = [[0, nan], [60, 275]]\n", "stimulus.schedule"),
    ("[stimulus]\npath = \"linear\"\nschedule = [[0, 300], [60, 275]]\n", "stimulus.path: only 'swelling' with a schedule"),
    ("[hydrogel]\ndiffusivity = 0.0\n", "hydrogel.diffusivity: must be > 0; allowed range (0, 0.01] mm^2/s"),
    ("[hydrogel]\ndiffusivity = -1e-4\n", "hydrogel.diffusivity: must be > 0"),
    ("[hydrogel]\ndiffusivity = 1.0\n", "hydrogel.diffusivity: must be <= 0.01"),
    # lengths the geometry cannot build: an upper bound, or the mesh against the smallest feature
    ("strain_limit_thickness = 1e308\n", "strain_limit_thickness: must be <= 1000"),
    ("side_wall_thickness = 5000.0\n", "side_wall_thickness: must be <= 1000"),
    ("cavity_length = 1e300\n", "cavity_length: must be <= 200000"),
    ("end_wall_thickness = 1e-9\n", "end_wall_thickness: too thin for mesh.size 2 mm"),
    ("cavity_width = 5e4\n", "mesh.size: the mesh would have about"),
    ("[mesh]\nsize = 1e-4\n", "mesh.size: the mesh would have about"),
    ("clearance = 1e-12\n", "clearance: must be >= 1e-6 x the actuator's larger size"),
    # multi-chamber designs: a third chamber in 2D, a chamber's water outside the liquid range, a misfit
    ("[[chambers]]\n[[chambers]]\n[[chambers]]\n", "chambers: 2D takes 2 chambers"),
    ("[[chambers]]\n[[chambers]]\ntemperature = 380.0\n", "chambers.1.temperature: must be <= 373.15"),
    ("[[chambers]]\ncavity_width = 12.0\n[[chambers]]\n", "chambers.0.cavity_width: chamber 0's particles do not fit"),
    # three chambers round the axis: only the whole 3D actuator, one column of equal spheres each
    ("dimension = 3\n[[chambers]]\n[[chambers]]\n[[chambers]]\n", "mesh.symmetry: must be false with three chambers"),
    ("dimension = 3\nstrain_limit_position = \"-x\"\n[mesh]\nsymmetry = false\n[[chambers]]\n[[chambers]]\n"
     "[[chambers]]\n", "strain_limit_position: with three chambers round the axis allowed: 'none', 'core'"),
    ("dimension = 3\nchamber_wall_thickness = 0.5\n[mesh]\nsymmetry = false\n[[chambers]]\n[[chambers]]\n"
     "[[chambers]]\n", "chamber_wall_thickness: too thin for mesh.size 2 mm"),
]


@pytest.mark.parametrize("text, field", BAD_DESIGNS)
def test_run_refuses_bad_designs_before_any_work(tmp_path, capsys, text, field):
    """Exit status 2, one line naming the field, and OUT not even created."""
    design = tmp_path / "bad.toml"
    design.write_text(text)
    out = tmp_path / "out"
    rc, _, err = run(capsys, "run", str(design), "-o", str(out))
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hydrojam: error:") and field in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("override, words", [
    ("strain_limit_thickness=1e308", "--set strain_limit_thickness=1e308: strain_limit_thickness: must be <= 1000; "
                                     "allowed range (0, 1000.0] mm (got 1e+308)"),
    ("side_wall_thickness=1e308", "side_wall_thickness: must be <= 1000"),
    ("end_wall_thickness=inf", "end_wall_thickness: must be a finite number"),
    ("cavity_width=1e308", "cavity_width: must be <= 200000"),
    ("strain_limit_thickness=0.5", "strain_limit_thickness: too thin for mesh.size 2 mm: must be >= 1 mm"),
    ("side_wall_thickness=1e-300", "side_wall_thickness: too thin for mesh.size 2 mm: must be >= 0.5 mm"),
    ("particle_diameter=1000", "mesh.size: the mesh would have about 2.9e+06 elements"),
])
def test_run_refuses_lengths_it_cannot_build_before_any_work(tmp_path, capsys, override, words):
    """A length that the geometry cannot build (gmsh's boolean operations fail, or the mesh is
    slivers or millions of elements) is refused like any bad field: exit status 2, one line, no
    traceback, OUT not created."""
    out = tmp_path / "out"
    rc, _, err = run(capsys, "run", str(write_default(tmp_path)), "-o", str(out), "--set", override)
    assert rc == 2 and not out.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in err


def write_default(tmp_path) -> Path:
    from hydrojam import default_design, write_design

    path = tmp_path / "design.toml"
    write_design(path, default_design())
    return path


def test_run_with_a_schedule_writes_time_and_the_angle_time_figure(tmp_path, capsys):
    """A time-resolved run (issue 16): history.csv has a filled time column from 0 to the
    schedule's end, metrics.json the time fields, and angle_time.png is written."""
    import csv
    import json

    design = tmp_path / "d.toml"
    design.write_text("particle_layers = 1\n[hydrogel]\ndiffusivity = 1e-2\n"
                      "[stimulus]\nschedule = [[0, 300], [60, 275], [1e5, 275]]\n[mesh]\nsize = 4\n")
    out = tmp_path / "out"
    rc, _, err = run(capsys, "run", str(design), "-o", str(out), "--no-vtu", "-q")
    assert rc == 0, err
    assert (out / "angle_time.png").stat().st_size > 0
    rows = list(csv.DictReader((out / "history.csv").open()))
    times = [float(r["time_s"]) for r in rows]
    assert times[0] == 0.0 and times[-1] == 1e5 and all(b > a for a, b in zip(times, times[1:]))
    m = json.loads((out / "metrics.json").read_text())
    assert m["time_s"] == 1e5 and 0 < m["time_to_90_percent_angle_s"] < 1e5
    assert m["temperature_K"] == 275.0
    assert "schedule" in (out / "design.toml").read_text()


def test_run_refuses_a_bad_override_and_a_missing_file(tmp_path, capsys):
    design = tmp_path / "d.toml"
    run(capsys, "init", str(design))
    rc, _, err = run(capsys, "run", str(design), "-o", str(tmp_path / "o"), "--set", "particle_layers=0")
    assert rc == 2 and "particle_layers" in err and not (tmp_path / "o").exists()
    rc, _, err = run(capsys, "run", str(tmp_path / "missing.toml"), "-o", str(tmp_path / "o"))
    assert rc == 2 and "missing.toml" in err


def test_run_writes_every_output(tmp_path, capsys):
    """The as-prepared stimulus (nothing moves, so it is quick): every documented file appears,
    the pvd lists the VTU files, metrics.json has the documented keys and no NaN."""
    from hydrojam.actuator.design import default_design, load_design

    d = default_design()
    design = tmp_path / "d.toml"
    run(capsys, "init", str(design), "--set", "particle_layers=1",
        "--set", f"stimulus.mu={d.hydrogel.mu0!r}", "--set", f"stimulus.temperature={d.hydrogel.T0!r}")
    out = tmp_path / "out"
    rc, _, _ = run(capsys, "run", str(design), "-o", str(out), "--quiet")
    assert rc == 0
    for name in ("design.toml", "metrics.json", "history.csv", "centreline.csv", "results.pvd", "final.png", "report.html"):
        assert (out / name).is_file(), name
    text = (out / "metrics.json").read_text()
    assert "NaN" not in text
    m = json.loads(text)
    for key in ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm", "curling_index", "converged",
                "wall_time_s", "newton_iterations"):
        assert key in m
    assert m["converged"] is True
    resolved = load_design(out / "design.toml")
    assert resolved.cavity_width == pytest.approx(16.2) and resolved.particle_layers == 1
    pvd = (out / "results.pvd").read_text()
    files = [line.split('file="')[1].split('"')[0] for line in pvd.splitlines() if "file=" in line]
    assert files and all((out / f).is_file() for f in files)


def test_run_that_stops_early_exits_1_with_its_last_state_written(tmp_path, capsys, monkeypatch):
    """A solver that stops early: exit status 1, results from the last converged state with
    "converged": false, and no NaN (the run's own early stop is stood in for by a simulate that
    returns the as-prepared state unconverged)."""
    import sys

    from hydrojam.actuator.model import measure
    from hydrojam.actuator.simulate import SimulationResult, StepState

    sim = sys.modules["hydrojam.actuator.simulate"]

    def stops_early(model, on_step=None, **kw):
        X = model.mesh.points
        mu, T = model.stimulus(0.0)
        state = StepState(0, 0.0, mu, T, X.copy(), measure(model, X), 0, 0.0)
        if on_step is not None:
            on_step(state)
        return SimulationResult(model, [state], False, "load step failed at s = 0.05 (test)", 0.0, 0, 1,
                                {"total": 0.0}, {})

    monkeypatch.setattr(sim, "simulate", stops_early)
    design = tmp_path / "d.toml"
    run(capsys, "init", str(design), "--set", "particle_layers=1")
    out = tmp_path / "out"
    rc, _, err = run(capsys, "run", str(design), "-o", str(out), "--quiet")
    assert rc == 1 and "stopped early" in err
    m = json.loads((out / "metrics.json").read_text())
    assert m["converged"] is False and m["s_reached"] == 0.0


# ---------------------------------------------------------------------------------------------
# defects found by trying the command as a new user would (issue 11, section 6)


def _one_error_line(rc, out, err, *needles):
    assert rc == 2, (rc, err)
    assert "Traceback" not in err and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hydrojam: error: "), err
    for needle in needles:
        assert needle in lines[0], lines[0]


def _listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def test_file_system_errors_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, monkeypatch):
    """An output under a regular file, in an unwritable place or on a full disk: one line naming
    the path, exit status 2, no traceback, and nothing written (not even a temporary)."""
    monkeypatch.chdir(tmp_path)
    Path("afile").write_text("a regular file\n")
    run(capsys, "init", "d.toml", "--set", "particle_layers=1")
    Path("s.toml").write_text('[design]\nparticle_layers = 1\n[[sweep]]\nname = "T"\n'
                              '[sweep.vary]\n"stimulus.temperature" = [295]\n')
    before = _listing(tmp_path)
    _one_error_line(*run(capsys, "run", "d.toml", "-o", "afile/sub", "--quiet"), "afile/sub")
    _one_error_line(*run(capsys, "init", "afile/d.toml"), "afile")
    _one_error_line(*run(capsys, "swell", "--temperatures", "280", "--plot", "afile/x.png"), "afile")
    _one_error_line(*run(capsys, "sweep", "s.toml", "-o", "afile/sub"), "afile/sub")
    if Path("/proc/self").is_dir():  # Linux: a folder where no file can be created, even by root
        _one_error_line(*run(capsys, "init", "/proc/nope.toml"), "/proc/nope.toml")
    assert _listing(tmp_path) == before

    def disk_full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Path, "write_text", disk_full)
    _one_error_line(*run(capsys, "init", "new.toml"), "new.toml", os.strerror(errno.ENOSPC))
    assert _listing(tmp_path) == before


def test_abort_is_reported_not_a_traceback(capsys, monkeypatch):
    import typer

    import hydrojam.cli as cli

    def abort(*args, **kwargs):
        raise typer.Abort()

    monkeypatch.setattr(cli, "_temperatures", abort)
    rc, out, err = run(capsys, "swell")
    assert rc == 130 and err.strip() == "hydrojam: aborted" and out == ""


@pytest.mark.parametrize("umask", [0o027, 0o002])
def test_output_files_get_the_users_permissions(tmp_path, capsys, umask):
    """Files are created 0666 less the umask (as any program's), not the temporary file's 0600."""
    old = os.umask(umask)
    try:
        rc, _, _ = run(capsys, "init", str(tmp_path / "d.toml"))
        assert rc == 0
        rc, _, _ = run(capsys, "swell", "--temperatures", "280,300", "--plot", str(tmp_path / "c.png"))
        assert rc == 0
    finally:
        os.umask(old)
    for name in ("d.toml", "c.png"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o666 & ~umask, name


def test_swell_refuses_too_many_temperatures_at_once(capsys):
    import time

    from hydrojam.cli import MAX_TEMPERATURES

    t0 = time.perf_counter()
    _one_error_line(*run(capsys, "swell", "--t-step", "1e-6"), "--t-step", "--t-min", "--t-max",
                    f"at most {MAX_TEMPERATURES}")
    _one_error_line(*run(capsys, "swell", "--t-step", "5e-324"), "--t-step", f"at most {MAX_TEMPERATURES}")
    many = ",".join(["280"] * (MAX_TEMPERATURES + 1))
    _one_error_line(*run(capsys, "swell", "--temperatures", many), "--temperatures", f"at most {MAX_TEMPERATURES}")
    assert time.perf_counter() - t0 < 10.0  # refused before any work
    rc, out, _ = run(capsys, "swell", "--t-min", "280", "--t-max", "281", "--t-step", "0.5", "--csv")
    assert rc == 0 and len(out.strip().splitlines()) == 4


def test_version_help_alias_and_bare_command(capsys):
    from hydrojam import __version__

    rc, out, err = run(capsys, "--version")
    assert rc == 0 and out.strip() == f"hydrojam {__version__}" and err == ""
    for args in (["-h"], ["--help"], []):
        rc, out, err = run(capsys, *args)
        assert rc == 0 and "Usage: hydrojam" in out and "swell" in out and err == "", args
    for command in ("swell", "init", "run", "sweep", "reproduce"):
        rc, out, _ = run(capsys, command, "-h")
        assert rc == 0 and f"Usage: hydrojam {command}" in out, command


def test_installed_command_version_and_bare_help():
    exe = Path(sys.executable).with_name("hydrojam")
    res = subprocess.run([str(exe)], capture_output=True, text=True)
    assert res.returncode == 0 and "Usage: hydrojam" in res.stdout and res.stderr == ""
    res = subprocess.run([str(exe), "--version"], capture_output=True, text=True)
    assert res.returncode == 0 and res.stdout.startswith("hydrojam ")


@pytest.mark.parametrize(
    "args, option",
    [
        (["--lambda0", "nan"], "--lambda0"),
        (["--nnu", "inf"], "--nnu"),
        (["--t0", "nan"], "--t0"),
        (["--mu", "nan"], "--mu"),
        (["--t-step", "nan"], "--t-step"),
        (["--t-max", "inf"], "--t-max"),
        (["--temperatures", "280,nan"], "--temperatures"),
    ],
)
def test_non_finite_options_have_the_design_files_wording(capsys, args, option):
    _one_error_line(*run(capsys, "swell", *args), f"{option}: must be a finite number")


@pytest.mark.parametrize("text, field", [("[hydrogel]\nlambda0 = nan\n", "hydrogel.lambda0"),
                                         ("[hydrogel]\nA0 = inf\n", "hydrogel.A0"),
                                         ("[mesh]\nsize = nan\n", "mesh.size")])
def test_non_finite_design_values_have_the_same_wording(tmp_path, capsys, text, field):
    design = tmp_path / "bad.toml"
    design.write_text(text)
    _one_error_line(*run(capsys, "run", str(design), "-o", str(tmp_path / "out")), f"{field}: must be a finite number")
    assert not (tmp_path / "out").exists()


def test_running_points_in_the_release_say_how_far_it_has_gone():
    """A sweep's running point at s = 1 shows its release's rounds, iterations and damping (a long
    3D chamber spends hours there); one on its path shows s only."""
    from hydrojam.actuator.checkpoint import ReleaseProgress
    from hydrojam.cli import _running_text
    from hydrojam.study.spec import study_from_dict
    from hydrojam.study.cache import RunningPoint

    study = study_from_dict({"name": "two", "design": {"particle_layers": 1},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [285, 295]}}]})
    a, b = ((p,) for p in study.points())
    text = _running_text([RunningPoint(a, 0.5, 42.0),
                          RunningPoint(b, 1.0, 5400.0, ReleaseProgress(12, 1534, 100.0, 1800.0))])
    on_path, in_release = text.split("; ", 1)
    assert on_path == "temperature[0] stimulus.temperature=285: s = 0.500 after 42 s"
    assert in_release.startswith("temperature[1] stimulus.temperature=295: s = 1.000 after 90 min, ")
    assert in_release.endswith("releasing the stabilisation: 12 rounds, 1534 iterations, damping 100x")


def _names_and_mtime(folder: Path):
    """A folder's names and its modification time: a file made and removed changes the time."""
    return sorted(os.listdir(folder)), folder.stat().st_mtime_ns


@pytest.mark.parametrize("args, target, words", [
    (["init", "{t}", "--force"], "adir.toml", "adir.toml: is a folder, not a file"),
    (["init", "{t}"], "sub/adir.toml", "adir.toml: is a folder, not a file"),  # without --force too
    (["swell", "--temperatures", "280,300", "--plot", "{t}"], "p.png", "--plot: "),
    (["swell", "--temperatures", "280,300", "--plot", "{t}"], "sub/p.png", "--plot: "),
])
def test_a_file_target_that_is_a_folder_is_refused_before_a_temporary_file(tmp_path, capsys, args, target, words):
    """The target is checked before the atomic write makes its temporary file beside it: exit
    status 2, one line, and the parent folder's listing (and its modification time) unchanged."""
    path = tmp_path / target
    path.mkdir(parents=True)
    (path / "keep.txt").write_text("x")
    before, inside = _names_and_mtime(path.parent), _names_and_mtime(path)
    rc, _, err = run(capsys, *[a.format(t=path) for a in args])
    assert rc == 2 and words in err and len(err.strip().splitlines()) == 1
    assert _names_and_mtime(path.parent) == before and _names_and_mtime(path) == inside


@pytest.mark.parametrize("args", [["init", "{t}"], ["swell", "--temperatures", "280", "--plot", "{t}"]])
def test_a_file_target_under_a_regular_file_is_refused(tmp_path, capsys, args):
    """A parent that is a regular file: refused naming it, nothing created."""
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    name = "d.toml" if args[0] == "init" else "p.png"
    before = _names_and_mtime(tmp_path)
    rc, _, err = run(capsys, *[a.format(t=blocker / "sub" / name) for a in args])
    assert rc == 2 and f"{blocker}: a parent of the file is not a folder" in err
    assert _names_and_mtime(tmp_path) == before and blocker.read_text() == "x"


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs POSIX permissions, not root")
def test_a_file_target_in_a_read_only_folder_is_refused(tmp_path, capsys):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        rc, _, err = run(capsys, "init", str(folder / "d.toml"))
        assert rc == 2 and "cannot be written into" in err and os.listdir(folder) == []
    finally:
        folder.chmod(0o755)


def test_atomic_path_checks_the_target_first(tmp_path):
    """From Python: atomic_path refuses a folder target without touching its parent."""
    from hydrojam._io import atomic_path, write_text_atomic

    (tmp_path / "t.txt").mkdir()
    (tmp_path / "f.txt").write_text("x")
    before = _names_and_mtime(tmp_path)
    with pytest.raises(IsADirectoryError):
        write_text_atomic(tmp_path / "t.txt", "x")
    with pytest.raises(NotADirectoryError):
        with atomic_path(tmp_path / "f.txt" / "x" / "y.txt"):
            pass
    assert _names_and_mtime(tmp_path) == before


def _folder_of(tmp_path, kind: str) -> Path:
    """A folder holding one kind of output, made by hand (its marker file and a design.toml)."""
    folder = tmp_path / kind.replace(" ", "_")
    folder.mkdir()
    marker = {"study": "study.toml", "study point": "point.json", "assessment": "assessment.json",
              "run": "metrics.json"}[kind]
    (folder / marker).write_text('name = "other"\n' if marker == "study.toml" else "{}\n")
    (folder / "design.toml").write_text("particle_layers = 1\n")
    return folder


def _quick_inputs(tmp_path) -> tuple[Path, Path]:
    design = tmp_path / "d.toml"
    design.write_text("particle_layers = 1\n[mesh]\nsize = 4.0\n")
    study = tmp_path / "s.toml"
    study.write_text('[design]\nparticle_layers = 1\nmesh.size = 4.0\n[[sweep]]\nname = "T"\n'
                     '[sweep.vary]\n"stimulus.temperature" = [295]\n')
    return design, study


@pytest.mark.parametrize("command, kind, found", [
    ("run", "study", "a study"),
    ("run", "study point", "one point of a study"),
    ("run", "assessment", "an assessment"),
    ("run --replicas 2", "run", "a single run"),
    ("assess", "run", "a single run"),
    ("assess", "study", "a study"),
    ("assess --replicas 2", "run", "a single run"),
    ("assess --replicas 2", "assessment", "an assessment"),
    ("sweep", "run", "a single run"),
    ("sweep", "assessment", "an assessment"),
    ("design-map", "run", "a single run"),
    ("snapshot", "run", "a single run"),
])
def test_a_folder_of_another_kind_of_output_is_refused(tmp_path, capsys, command, kind, found):
    """Every command that writes a folder refuses one holding another kind of output (a run's
    files in a study's folder, an assessment overwriting a run's design.toml): exit status 2,
    one line naming what the folder holds, nothing in it changed."""
    design, study = _quick_inputs(tmp_path)
    folder = _folder_of(tmp_path, kind)
    before = _listing(folder), (folder / "design.toml").read_text()
    name, *extra = command.split()
    if name == "snapshot":  # snapshot SRC -o DEST: DEST is the folder written
        args = [name, str(tmp_path), "-o", str(folder)]
    else:
        args = [name, str(study if name == "sweep" else design), "-o", str(folder), *extra, "--quiet"]
    rc, _, err = run(capsys, *args)
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and f"holds the output of {found}" in lines[0] and "Traceback" not in err
    assert (_listing(folder), (folder / "design.toml").read_text()) == before


@pytest.mark.parametrize("command", ["run", "assess", "sweep", "design-map", "run --replicas 2", "assess --replicas 2"])
def test_a_folder_a_live_run_holds_is_refused_by_every_command(tmp_path, capsys, command):
    """The same lock file for every command that writes a folder: one held by a live process
    (this one) is refused before anything is written."""
    import socket

    design, study = _quick_inputs(tmp_path)
    folder = tmp_path / "live"
    folder.mkdir()
    lock = folder / ".hydrojam.lock"
    lock.write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "started": "now"}))
    name, *extra = command.split()
    rc, _, err = run(capsys, name, str(study if name == "sweep" else design), "-o", str(folder), *extra, "--quiet")
    assert rc == 2 and f"in use by process {os.getpid()}" in err and len(err.strip().splitlines()) == 1
    assert _listing(folder) == [".hydrojam.lock"]


def test_folder_kind_reads_the_markers(tmp_path):
    from hydrojam._io import FolderKindError, check_folder_kind, folder_kind

    assert folder_kind(tmp_path / "missing") is None and folder_kind(tmp_path) is None
    for kind in ("study", "study point", "assessment", "run"):
        folder = _folder_of(tmp_path, kind)
        assert folder_kind(folder) == kind
        if kind != "study point":
            check_folder_kind(folder, kind)  # the same kind: a rerun, a resume
        with pytest.raises(FolderKindError, match="choose another output folder"):
            check_folder_kind(folder, "snapshots")


@pytest.mark.parametrize("variable, value, allowed", [("HYDROJAM_BLAS_THREADS", "abc", "positive integer"),
                                                      ("HYDROJAM_SOLVER_THREADS", "0", "positive integer"),
                                                      ("HYDROJAM_IPC_THREADS", "-1", "positive integer"),
                                                      ("HYDROJAM_REUSE_ANALYSIS", "yes", "0 or 1"),
                                                      ("HYDROJAM_COMPILED", "2", "0 or 1")])
def test_an_invalid_environment_variable_is_refused_before_any_work(capsys, tmp_path, monkeypatch, variable, value,
                                                                    allowed):
    """A thread count or switch in the environment that hydrojam cannot use: one line naming it
    and its allowed values, exit status 2, nothing written (the solver would otherwise find it
    only when built, mid-run, after the outputs were begun)."""
    design = tmp_path / "design.toml"
    assert run(capsys, "init", str(design))[0] == 0
    monkeypatch.setenv(variable, value)
    rc, out, err = run(capsys, "run", str(design), "-o", str(tmp_path / "out"), "--set", "particle_layers=1")
    assert rc == 2, err
    assert len(err.strip().splitlines()) == 1 and variable in err and allowed in err, err
    assert "Traceback" not in err and not (tmp_path / "out").exists()


def test_help_and_version_still_answer_with_an_invalid_environment(capsys, monkeypatch):
    """Help and the version run nothing, so an invalid thread count does not stop them."""
    monkeypatch.setenv("HYDROJAM_BLAS_THREADS", "abc")
    for args in (["run", "--help"], ["--version"], ["sweep", "-h"]):
        rc, out, err = run(capsys, *args)
        assert rc == 0 and out and "HYDROJAM_BLAS_THREADS" not in err, (args, err)
