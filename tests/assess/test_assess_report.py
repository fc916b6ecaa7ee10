"""`hydrojam assess`: bad loads refused before any work (exit 2, one line, nothing written), the
report from Python and from the command line, and its plain-words conclusion."""

import json

import pytest

from hydrojam import Design, write_design
from hydrojam.assess.assessment import assess
from hydrojam.assess.report import conclusion, write_report
from hydrojam.assess.spec import AssessError, Loads, loads_from_dict
from hydrojam.cli import main

QUICK = Design(particle_layers=1, mesh={"size": 4.0})


@pytest.fixture
def design_file(tmp_path):
    path = tmp_path / "design.toml"
    write_design(path, QUICK)
    return path


def _refused(command, design_file, tmp_path, capsys, *args) -> str:
    """Run ``hydrojam COMMAND DESIGN -o OUT ARGS``: exit status 2 and nothing written; its stderr."""
    out = tmp_path / "out"
    assert main([command, str(design_file), "-o", str(out), *args]) == 2
    assert not out.exists()
    return capsys.readouterr().err


@pytest.mark.parametrize("args, words", [
    (["--max-force", "-1"], "--max-force: must be > 0; allowed range (0, 10.0] N/mm"),
    (["--max-force", "nan"], "--max-force: must be a finite number"),
    (["--vacuum-kpa", "150"], "--vacuum-kpa: must be <= 101.325; allowed range (0, 101.325] kPa"),
    (["--temperatures", "250,275"], "--temperatures: each temperature must be in liquid water's range"),
    (["--temperatures", "cold"], "--temperatures: expected comma-separated numbers"),
    (["--pneumatic-angle", "400"], "--pneumatic-angle: must be <= 360"),
    (["--pneumatic-angle", "-5"], "--pneumatic-angle: must be > 0"),
    (["--pneumatic-max-kpa", "0"], "--pneumatic-max-kpa: must be > 0"),
    (["--pneumatic-max-kpa", "5000"], "--pneumatic-max-kpa: must be <= 1000"),
    (["--pneumatic-max-kpa", "inf"], "--pneumatic-max-kpa: must be a finite number"),
    (["--replicas", "0"], "--replicas: must be in [1, "),
    (["--replicas", "2", "--workers", "0"], "--workers: must be >= 1"),
    (["--workers", "2"], "--workers: only with --replicas N > 1"),
    (["--replicas", "2", "--scheduler", "nope://x"], "--scheduler:"),
    (["--set", "dimension=3", "--pneumatic-angle", "0"], "--pneumatic-angle: must be > 0"),
])
def test_bad_loads_are_refused_before_any_work(tmp_path, design_file, capsys, args, words):
    err = _refused("assess", design_file, tmp_path, capsys, *args)
    assert words in err and len(err.strip().splitlines()) == 1


def test_unknown_key_in_a_loads_file_is_refused(tmp_path, design_file, capsys):
    loads = tmp_path / "loads.toml"
    loads.write_text("vacuum_presure = 50\n")
    err = _refused("assess", design_file, tmp_path, capsys, "--loads", str(loads))
    assert "vacuum_presure: unknown key (allowed: max_force, temperatures, vacuum_pressure" in err
    with pytest.raises(AssessError, match="baseline_particles.shear_modulus"):
        loads_from_dict({"baseline_particles": {"shear_modulus": -1}})


@pytest.mark.parametrize("text, words", [
    ('max_force = "0.001"\n', "max_force: expected a number, got '0.001' (str)"),
    ("max_force = true\n", "max_force: expected a number, got True (bool)"),
    ('vacuum_pressure = "80"\n', "vacuum_pressure: expected a number, got '80' (str)"),
    ("vacuum_pressure = false\n", "vacuum_pressure: expected a number, got False (bool)"),
    ('temperatures = ["275", 285]\n', "temperatures.0: expected a number, got '275' (str)"),
    ("temperatures = [275, true]\n", "temperatures.1: expected a number, got True (bool)"),
    ("temperatures = 275\n", "temperatures: expected a list, got 275 (int)"),
    ("temperatures = [250]\n", "temperatures: each temperature must be in liquid water's range"),
    ("vacuum = 1\n", "vacuum: expected true or false, got 1 (int)"),
    ('blocking = "yes"\n', "blocking: expected true or false, got 'yes' (str)"),
    ('[baseline_particles]\nshear_modulus = "1"\n', "baseline_particles.shear_modulus: expected a number"),
    ("[baseline_particles]\nshear_mod = 1\n", "baseline_particles.shear_mod: unknown key"),
    ("max_force = 0.001\nblocked = false\n", "blocked: unknown key (allowed: max_force"),
])
def test_a_loads_file_is_as_strict_as_a_design_file(tmp_path, design_file, capsys, text, words):
    """Wrong types (strings or booleans for numbers, integers for booleans) and unknown keys are
    refused with one line naming the field, exit status 2, before anything is written."""
    loads = tmp_path / "loads.toml"
    loads.write_text(text)
    err = _refused("assess", design_file, tmp_path, capsys, "--loads", str(loads))
    assert f"{loads}: {words}" in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err


def test_integers_are_numbers_in_a_loads_file():
    """As in a design file, an integer is accepted where a number is meant."""
    loads = loads_from_dict({"max_force": 1, "vacuum_pressure": 50, "temperatures": [275, 285]})
    assert (loads.max_force, loads.vacuum_pressure, loads.temperatures) == (1.0, 50.0, (275.0, 285.0))


def test_assess_from_the_command_line_writes_the_report(tmp_path, design_file, capsys):
    """Stiffness part only (no blocked force, no vacuum): report.md, assessment.json (no NaN),
    the figures; exit status 0."""
    loads = tmp_path / "loads.toml"
    loads.write_text("blocking = false\nvacuum = false\n")
    out = tmp_path / "out"
    assert main(["assess", str(design_file), "-o", str(out), "--loads", str(loads), "-q"]) == 0
    report = (out / "report.md").read_text()
    assert "stiffness ratio" in report and "## The answer" in report and "per mm of depth" in report
    assert "## Against the authors' later numbers" in report and "| | active particles | vacuum jamming | pneumatic |" in report
    values = json.loads((out / "assessment.json").read_text())["values"]
    assert values["stiffness_ratio"] > 1.0
    assert values["swelling_pressure"] > 100 * values["contact_pressure_mean"] > 0
    assert values["pneumatic_pressure_kPa"] > 0 and values["stiffness_active_over_pneumatic"] > 0
    assert (out / "load_deflection.png").stat().st_size > 0 and (out / "confinement.png").stat().st_size > 0
    page = (out / "report.html").read_text()  # the same report in one file: its figures inlined
    assert "<h2>The answer</h2>" in page and "<table>" in page
    assert page.count('src="data:image/png;base64,') == 2 and 'src="load_deflection.png"' not in page
    import meshio

    vtu = meshio.read(out / "actuated.vtu")
    assert vtu.point_data["contact_pressure"].max() == pytest.approx(values["contact_pressure_max"], rel=1e-9)


@pytest.mark.slow
def test_full_assessment_of_a_one_layer_actuator(tmp_path):
    """Every part, from Python: the blocked force falls with T (the gel swells less), the vacuum
    baseline stiffens the chamber, and the conclusion names the reported 9x-30x range and says
    whether the wall holds the gel."""
    a = assess(QUICK, Loads(temperatures=(275.0, 295.0)))
    v = a.values
    assert a.blocked[0]["force_x"] > a.blocked[1]["force_x"] > 0
    assert v["stiffness_ratio_vacuum"] > 1.0 and v["vacuum_pressure_kPa"] > 0
    text = " ".join(conclusion(a))
    assert "9x-30x" in text and "does not hold the gel" in text
    write_report(a, tmp_path)
    assert (tmp_path / "blocked_force.png").exists()


@pytest.mark.slow
def test_design_map_runs_as_a_cached_sweep(tmp_path):
    """Two membranes as a study sweep: one row per point with the map's values, the figure; a
    stiffer membrane presses harder on the particles; a rerun loads the points from the cache."""
    from hydrojam.assess.design_map import MODULUS, design_map

    rows = design_map(QUICK, [2.0], [0.023, 0.2], tmp_path, workers=1)
    assert [r[MODULUS] for r in rows] == [0.023, 0.2]
    assert rows[1]["contact_pressure_mean"] > rows[0]["contact_pressure_mean"] > 0
    assert (tmp_path / "design_map.png").exists()
    seen = []
    design_map(QUICK, [2.0], [0.023, 0.2], tmp_path, workers=1, on_point=lambda o, d, n: seen.append(o.cached))
    assert seen == [True, True]


@pytest.mark.parametrize("args, words", [
    (["--thickness", "1,-2"], "--thickness -2: side_wall_thickness: must be > 0; allowed range (0, 1000.0] mm"),
    (["--modulus", "0.02,soft"], "--modulus: expected comma-separated numbers in MPa"),
    (["--workers", "0"], "--workers: must be >= 1"),
    # each value goes through its design field's own validation (it ended in a pydantic traceback)
    (["--modulus", "20000"], "--modulus 20000: membrane.shear_modulus: must be <= 10000; allowed range (0, 10000.0] MPa"),
    (["--modulus", "0.02,0"], "--modulus 0: membrane.shear_modulus: must be > 0"),
    (["--modulus", "nan"], "--modulus nan: membrane.shear_modulus: must be a finite number"),
    (["--thickness", "inf"], "--thickness inf: side_wall_thickness: must be a finite number"),
    (["--thickness", "5000"], "--thickness 5000: side_wall_thickness: must be <= 1000"),
    (["--thickness", "2,0.5"], "--thickness 0.5: side_wall_thickness: too thin for mesh.size 4 mm"),
])
def test_design_map_refuses_bad_ranges_before_any_work(tmp_path, design_file, capsys, args, words):
    err = _refused("design-map", design_file, tmp_path, capsys, *args)
    assert words in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_design_map_study_validates_every_pair():
    """From Python as well: a point of the map that is not a valid design is a DesignError
    naming the sweep point and the field, before anything runs."""
    from hydrojam.actuator.design import DesignError
    from hydrojam.assess.design_map import map_study

    with pytest.raises(DesignError, match=r"point 1 .*membrane.shear_modulus: must be <= 10000"):
        map_study(QUICK, [2.0], [0.023, 2e4])
    assert len(map_study(QUICK, [1.0, 2.0], [0.023]).points()) == 2


def test_a_3d_design_is_assessable_and_a_replica_folder_keeps_its_loads(tmp_path):
    """A 3D design (half model or whole) passes the assessment's checks; a replicas' folder
    assessed under other loads is refused, naming --out, before anything runs or is written."""
    from hydrojam.assess.assessment import check_assessable
    from hydrojam.assess.replicas import LOADS_FILE, check_replica_folder

    check_assessable(Design(dimension=3, particle_layers=1, mesh={"size": 4.0}))
    check_assessable(Design(dimension=3, particle_layers=1, mesh={"size": 4.0, "symmetry": False}))
    check_replica_folder(tmp_path, Loads())  # nothing there yet
    (tmp_path / LOADS_FILE).write_text(Loads().model_dump_json())
    check_replica_folder(tmp_path, Loads())
    with pytest.raises(AssessError, match="--out: .* holds replicas assessed under other loads"):
        check_replica_folder(tmp_path, Loads(vacuum_pressure=50.0))


def test_the_answer_and_the_trend_are_worded_from_the_numbers():
    """The answer names the units of its dimension, the pneumatic comparison and the designer's
    levers; the blocked force's change over T is a trend only beyond 2 standard errors of the
    difference of the means."""
    from hydrojam.assess.report import answer, authors_table, blocked_trend
    from hydrojam.study.spread import spread

    v = {"stiffness_ratio": 12.0, "stiffness_unactuated": 0.01, "stiffness_actuated": 0.12,
         "stiffness_active_over_pneumatic": 3.0, "pneumatic_angle_deg": 35.0, "pneumatic_pressure_kPa": 20.0,
         "stiffness_pneumatic": 0.04, "swelling_pressure": 7.0, "contact_pressure_mean": 0.005,
         "contact_pressure_max": 0.02, "mean_swelling_ratio": 6.0, "bending_angle_deg": 35.0}
    text = " ".join(answer(v, QUICK, [{"temperature_K": 275.0, "force_x": 0.25}], True))
    assert "within the 9x-30x" in text and "0.12 N/mm" in text and "3x as stiff" in text
    assert "0.25 N at 275 K" in text and "smaller beads for speed" in text and "membrane for confinement" in text
    assert "82 mN/mm" in " ".join(answer(v, QUICK, [{"temperature_K": 275.0, "force_x": 0.082}], False))
    assert any("| 3x |" in row for row in authors_table(v))
    stats = {"blocked_force_275K": spread([5.0, 5.5, 6.0, 5.5]), "blocked_force_295K": spread([9.0, 10.0, 9.5, 9.5])}
    assert "beyond the spread: a trend" in blocked_trend(stats, [275.0, 295.0])
    stats["blocked_force_295K"] = spread([5.0, 7.0, 4.5, 6.5])
    assert "within the spread" in blocked_trend(stats, [275.0, 295.0])
    assert blocked_trend(stats, [275.0]) is None


@pytest.mark.slow
def test_replicas_of_an_assessment_give_every_figure_with_its_spread(tmp_path, design_file, capsys):
    """`hydrojam assess --replicas 2` (stiffness part only): each replica's report in its point
    folder, the replicas' report with mean ± std, assessment.json with every value's spread over
    both; a rerun loads the points from the cache; other loads in the same folder are refused."""
    loads = tmp_path / "loads.toml"
    loads.write_text("blocking = false\nvacuum = false\npneumatic = false\n")
    out = tmp_path / "out"
    args = ["assess", str(design_file), "-o", str(out), "--loads", str(loads), "--replicas", "2", "--workers", "1", "-q"]
    assert main(args) == 0
    data = json.loads((out / "assessment.json").read_text())
    ratio = data["values"]["stiffness_ratio"]
    assert ratio["n"] == 2 and ratio["std"] is not None and ratio["min"] <= ratio["mean"] <= ratio["max"]
    assert len(list((out / "points").glob("*/report.md"))) == 2
    assert "± " in (out / "report.md").read_text()
    assert main(args) == 0  # cached
    assert _refused_in(out, ["assess", str(design_file), "-o", str(out), "--vacuum-kpa", "50", "--replicas", "2", "-q"],
                       capsys)


def _refused_in(out, args, capsys) -> bool:
    before = sorted(p.name for p in out.iterdir())
    code = main(args)
    err = capsys.readouterr().err
    return code == 2 and "holds replicas assessed under other loads" in err and sorted(p.name for p in out.iterdir()) == before


def test_a_replica_whose_pneumatic_chamber_balloons_is_not_stopped_early(tmp_path, monkeypatch):
    """A replica is stopped early where the single assessment's exit status says so (actuation,
    curves, blocked force), not where a baseline ends short: the empty chamber's pneumatic ramp
    stops at its balloon's limit point, an answer its message reports."""
    from types import SimpleNamespace

    import hydrojam.assess.replicas as replicas_module
    import hydrojam.assess.report as report_module

    def fake(values, curves_ok=True):
        curves = {"actuated": SimpleNamespace(converged=curves_ok)}
        return SimpleNamespace(values=values, curves=curves, blocked=[{"converged": True}])

    monkeypatch.setattr(report_module, "write_report", lambda a, out: out)
    base = {"actuation_converged": True, "vacuum_converged": True, "pneumatic_converged": False,
            "pneumatic_message": "short of 122 deg: a limit point"}
    monkeypatch.setattr(replicas_module, "assess", lambda design, loads: fake(dict(base)))
    v = replicas_module.assess_point(None, tmp_path, None)
    assert v["converged"] is True and v["message"] == "converged"
    monkeypatch.setattr(replicas_module, "assess", lambda design, loads: fake(dict(base), curves_ok=False))
    v = replicas_module.assess_point(None, tmp_path, None)
    assert v["converged"] is False and v["message"] == "stopped early: curves_converged"


def test_the_replicas_report_says_the_pneumatic_chamber_stopped_short(tmp_path):
    """Where the replicas' pneumatic ramps end at the balloon's limit point short of the active
    angle, the replicas' answer says so (their means alone carry no flag) and quotes the message."""
    from hydrojam.assess.replicas import ReplicaAssessment
    from hydrojam.assess.report import write_replica_report
    from hydrojam.study.spread import spread

    values = [{"bending_angle_deg": 122.0 + k, "stiffness_active_over_pneumatic": 12.0 + k, "pneumatic_angle_deg": 25.3,
               "pneumatic_pressure_kPa": 3.17, "stiffness_pneumatic": 0.005, "pneumatic_converged": False,
               "pneumatic_message": "short of 122 deg: a limit point"} for k in range(2)]
    runs = [{"replica": k, "key": f"k{k}", "status": "ok", "error": None, "values": v} for k, v in enumerate(values)]
    stats = {name: spread([v[name] for v in values]) for name in values[0]
             if isinstance(values[0][name], float)}
    loads = Loads(blocking=False, vacuum=False)
    write_replica_report(ReplicaAssessment(Design(), loads, runs, stats, 1.0), tmp_path)
    text = (tmp_path / "report.md").read_text(encoding="utf-8")
    assert "does not bend as far under pressure: short of 122 deg: a limit point" in text
    assert "bends as far" not in text
