"""hydrojam.paper.reproduce end to end over cached points, and the reproduce command's option checks.

No simulation runs: every point is already in the cache.
"""

from __future__ import annotations

import re

import pytest
from paper_synthetic import paper_like, write_point

from hydrojam.paper import claims as pclaims, study as pstudy
from hydrojam.paper.reproduce import reproduce


def test_reproduce_end_to_end_from_cached_points(tmp_path):
    """reproduce() with hydrojam.sweep.run_sweep: every point of the quick study is already in
    OUT/points/<key>/ (point.json ok, paper-like metrics, a tiny final.vtu), so nothing is
    simulated; the table, the six figures and the report come out."""
    pytest.importorskip("hydrojam.study.sweep")
    import json

    study = pstudy.paper_study(quick=True)
    done = set()
    for p in study.points():
        if p.key in done:
            continue
        done.add(p.key)
        metrics = paper_like(p.design)
        metrics.update(converged=True, stabilisation_released=True, newton_iterations=900)
        write_point(tmp_path, {"point_dir": f"points/{p.key}"}, bend=-0.5, design=p.design)
        record = {"key": p.key, "status": "ok", "error": None, "metrics": metrics, "wall_time_s": 60.0}
        (tmp_path / "points" / p.key / "point.json").write_text(json.dumps(record))
    seen = []
    table, report = reproduce(tmp_path, quick=True, on_point=lambda o, d, t: seen.append((d, t)))
    assert seen[-1] == (11, 11) and len(table.rows) == 13
    text = report.read_text(encoding="utf-8")
    assert report == tmp_path / "report.md"
    assert len(list((tmp_path / "figures").glob("*.png"))) == 6
    verdicts = {c.claim.id: c.verdict for c in pclaims.check_claims(table)}
    assert verdicts == {c.id: "agree" for c in pclaims.paper_claims(2)}
    assert "11 distinct points" in text and "compute time summed over points 11 min" in text
    assert "(this run: 0 of the 11 points computed, the others reused" in text
    # the command line over the same cache: nothing to simulate, exit status 0, report rewritten
    from hydrojam.cli import main

    report.unlink()
    assert main(["reproduce", "--quick", "-o", str(tmp_path), "--quiet"]) == 0
    assert report.is_file()


@pytest.mark.parametrize("args", [["--workers", "0"], ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"]])
def test_reproduce_command_refuses_bad_options_before_any_work(tmp_path, capsys, args):
    from hydrojam.cli import main

    out = tmp_path / "out"
    assert main(["reproduce", "--quick", "-o", str(out), *args]) == 2
    assert "--workers" in capsys.readouterr().err and not out.exists()


def _cache_points(out, study):
    import json

    for p in study.points():
        if (out / "points" / p.key / "point.json").exists():
            continue
        metrics = paper_like(p.design)
        metrics.update(converged=True, stabilisation_released=True, newton_iterations=900)
        write_point(out, {"point_dir": f"points/{p.key}"}, bend=-0.5, design=p.design)
        record = {"key": p.key, "status": "ok", "error": None, "metrics": metrics, "wall_time_s": 60.0}
        (out / "points" / p.key / "point.json").write_text(json.dumps(record))


def test_reproduce_one_sweep_then_the_rest_into_the_same_folder(tmp_path):
    """--sweep temperature runs only the temperature sweep (its claims decided, the others
    undetermined); a later full run into the same folder adds the other sweeps."""
    from hydrojam.cli import main

    _cache_points(tmp_path, pstudy.paper_study(quick=True, sweeps=["temperature"]))
    assert main(["reproduce", "--quick", "--sweep", "temperature", "-o", str(tmp_path), "--quiet"]) == 0
    assert sorted(p.name for p in (tmp_path / "figures").glob("*.png")) == ["temperature_shapes.png",
                                                                          "temperature_trends.png"]
    _cache_points(tmp_path, pstudy.paper_study(quick=True))
    table, _ = reproduce(tmp_path, quick=True)
    assert {r["sweep"] for r in table.rows} == {"temperature", "particle_layers", "strain_limit_thickness"}
    assert len(list((tmp_path / "figures").glob("*.png"))) == 6


def test_reproduce_refuses_an_unknown_sweep(tmp_path, capsys):
    from hydrojam.cli import main

    out = tmp_path / "out"
    assert main(["reproduce", "--quick", "--sweep", "temprature", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--sweep" in err and "temperature, particle_layers, strain_limit_thickness" in err and not out.exists()


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("hydrojam: error: ") and "\n" not in err and "Traceback" not in err
    return err


@pytest.mark.parametrize("args, says", [
    (["--dimension", "1"], "--dimension: allowed 2 or 3 (got 1)"),
    (["--dimension", "4", "--quick"], "--dimension: allowed 2 or 3 (got 4)"),
    (["--compare-2d", "elsewhere"], "--compare-2d: only with --dimension 3"),
    (["--dimension", "3", "--quick", "--compare-2d", "elsewhere"], "--compare-2d: elsewhere: no such folder"),
])
def test_reproduce_refuses_bad_dimension_and_comparison_before_any_work(tmp_path, capsys, monkeypatch, args, says):
    from hydrojam.cli import main

    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    assert main(["reproduce", "-o", str(out), *args]) == 2
    assert says in _one_error_line(capsys) and not out.exists()


@pytest.mark.parametrize("held, run", [((True, 2), ["--dimension", "3", "--quick"]),
                                       ((True, 3), ["--quick"]),
                                       ((False, 3), ["--dimension", "3", "--quick"])])
def test_reproduce_refuses_an_out_holding_the_other_study(tmp_path, capsys, held, run):
    """A 2D and a 3D study (or a quick and a full one) never share a folder: exit 2, one line
    naming both studies, nothing written into it."""
    from hydrojam.cli import main
    from hydrojam.study.spec import write_study

    write_study(tmp_path / "study.toml", pstudy.paper_study(held[0], dimension=held[1]))
    before = (tmp_path / "study.toml").read_bytes()
    assert main(["reproduce", "-o", str(tmp_path), *run]) == 2
    err = _one_error_line(capsys)
    want = pstudy.study_name("--quick" in run, 3 if "3" in run else 2)
    assert f"another study, {pstudy.study_name(*held)!r}" in err and f"not {want!r}" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.toml"]
    assert (tmp_path / "study.toml").read_bytes() == before


def _cache_3d_points(out, study):
    import json

    from paper_synthetic import write_point_3d

    for p in study.points():
        if (out / "points" / p.key / "point.json").exists():
            continue
        metrics = paper_like(p.design)
        metrics["bending_angle_deg"] -= 10.0
        metrics.update(converged=True, stabilisation_released=True, newton_iterations=900)
        write_point_3d(out, {"point_dir": f"points/{p.key}"}, bend=-0.3, design=p.design)
        record = {"key": p.key, "status": "ok", "error": None, "metrics": metrics, "wall_time_s": 600.0}
        (out / "points" / p.key / "point.json").write_text(json.dumps(record))


def test_reproduce_3d_from_cached_points_with_the_2d_comparison(tmp_path):
    """`reproduce --dimension 3 --quick --compare-2d OUT2D` over cached points of both studies:
    nothing is simulated; the 3D report has the verdicts, the shapes and trends figures of its four
    sweeps (the strip width too) and the 2D-against-3D table of the 10 designs the 2D study shares."""
    from hydrojam.cli import main

    two, three = tmp_path / "two", tmp_path / "three"
    _cache_points(two, pstudy.paper_study(quick=True))
    assert main(["reproduce", "--quick", "-o", str(two), "--quiet", "--sweep", "temperature"]) == 0
    _cache_3d_points(three, pstudy.paper_study(quick=True, dimension=3))
    page = tmp_path / "page.md"
    page.write_text("# p\n<!-- reproduce: paper-3d-quick -->\n<!-- /reproduce: paper-3d-quick -->\n"
                    "<!-- reproduce: paper-3d-quick time -->\n<!-- /reproduce: paper-3d-quick time -->\n"
                    "<!-- reproduce: paper-3d-quick compare -->\n<!-- /reproduce: paper-3d-quick compare -->\n"
                    "<!-- reproduce: paper-3d-quick figures -->\n<!-- /reproduce: paper-3d-quick figures -->\n",
                    encoding="utf-8")
    assert main(["reproduce", "--dimension", "3", "--quick", "-o", str(three), "--quiet",
                 "--compare-2d", str(two), "--write-results", str(page)]) == 0
    written = page.read_text(encoding="utf-8")
    # the page's figures: each sweep's trends figure, copied beside the page and linked from it
    shown = sorted(p.name for p in (tmp_path / "_static" / "paper-3d-quick").iterdir())
    assert shown == sorted(f"{sw.name}_trends.png" for sw in pstudy.paper_sweeps(3))
    for name in shown:
        assert (tmp_path / "_static" / "paper-3d-quick" / name).read_bytes() == (three / "figures" / name).read_bytes()
        assert f"](_static/paper-3d-quick/{name})" in written.split("<!-- reproduce: paper-3d-quick figures -->")[1]
    assert "Conditions: `hydrojam reproduce --dimension 3 --quick`" in written and "15 of 15 runs finished" in written
    assert "| strain_limit_width | 12 mm |" in written and "| paper-3d-quick | claims |" in written
    cost = written.split("<!-- reproduce: paper-3d-quick time -->")[1]
    assert "| `hydrojam reproduce --dimension 3 --quick` | 15 of 15 | 900-900 (mean 900) | 10.0 min | 2.5 h |" in cost
    # the page's 2D-against-3D section: each statement's verdict in both, then the points' table
    compare = written.split("<!-- reproduce: paper-3d-quick compare -->")[1]
    assert compare.startswith("\n| statement | 2D | 3D |\n|---|---|---|\n| T-angle | ")
    assert "| hw-angle | — (3D only) | " in compare and "| PL-angle | — | agree |" in compare  # 2D ran T only
    assert "Both reproduce: " in compare and f"(the 2D study in `{two}`)" in compare
    assert "| point | θ 2D [deg] | θ 3D [deg] |" in compare and "## 2D against 3D" not in compare
    assert "paper-3d-quick" in (three / "study.toml").read_text()
    assert len(list((three / "figures").glob("*.png"))) == 8
    text = (three / "report.md").read_text(encoding="utf-8")
    assert "| hw-angle |" in text and "strip width" in text
    assert "**quick, 3D**" in text and "## 2D against 3D" in text
    rows = [line for line in text.split("## 2D against 3D")[1].split("## Model")[0].splitlines()
            if line.startswith("| ") and not line.startswith("| point")]
    assert len(rows) == 11
    assert sum("bends less in 3D (θ -10.0°" in line for line in rows) == 3  # the 2D temperature sweep only
    assert sum("not run in 2D" in line for line in rows) == 8
    page = (three / "report.html").read_text(encoding="utf-8")  # the report as one page that opens offline
    assert not re.search(r'(src|href)="https?:', page)
    figures = sorted(p.name for p in (three / "figures").glob("*.png"))
    assert all(f"figures/{name}" in text for name in figures)  # the figures the Markdown names, inlined
    assert page.count('<img src="data:image/png;base64,') == len(figures) and "## 2D against 3D" not in page
    assert "<h2>2D against 3D (the same designs)</h2>" in page and "<h2>Final states in 3D</h2>" in page
    assert len(re.findall(r'<div class="hj-scene" data-scene=', page)) == 15  # each of the 15 runs' final.vtu, once


@pytest.mark.slow
def test_reproduce_3d_runs_a_tiny_study_end_to_end(tmp_path, monkeypatch):
    """One mild 3D point simulated (PL 1, mesh 4 mm, 300 K, μ -0.025: seconds): the point folder,
    a 3D final.vtu drawn as its section, the report in 3D."""
    from hydrojam.actuator.design import apply_overrides
    from hydrojam.paper import reproduce as preproduce
    from hydrojam.study.spec import Study, SweepSpec

    def tiny(quick=False, sweeps=None, replicas=1, dimension=2, overrides=()):
        base = apply_overrides(pstudy.paper_base(quick, replicas, dimension, overrides),
                               ["particle_layers=1", "stimulus.temperature=300.0", "stimulus.mu=-0.025"])
        return Study(name=pstudy.study_name(quick, dimension), base=base,
                     sweeps=[SweepSpec(name="temperature", vary={"stimulus.temperature": [300.0]})])

    monkeypatch.setattr(preproduce, "paper_study", tiny)
    table, report = preproduce.reproduce(tmp_path, quick=True, dimension=3, workers=1)
    (r,) = table.rows
    assert r["status"] == "ok" and 0.0 < r["bending_angle_deg"] < 2.0
    assert (tmp_path / r["point_dir"] / "final.vtu").is_file()
    assert (tmp_path / "figures" / "temperature_shapes.png").read_bytes()[:4] == b"\x89PNG"
    text = report.read_text(encoding="utf-8")
    assert "in 3D" in text and "*No 2D results given.*" in text


def test_reproduce_report_only_writes_an_interim_report(tmp_path, monkeypatch, capsys):
    """`reproduce --report-only` on a quick study in progress: PL 15 stopped at s = 0.5 (its
    history.csv), h = 12 mm not started, the others finished. Nothing runs; the table, the six
    figures and the report say which points are not finished, and the claims of their sweeps
    stay undetermined with what the finished points read. Exit status 0: nothing failed."""
    from hydrojam.cli import main
    from hydrojam.study import sweep as sweep_mod
    from hydrojam.study.spec import write_study

    study = pstudy.paper_study(quick=True)
    write_study(tmp_path / "study.toml", study)
    key = {(p.sweep, p.index): p.key for p in study.points()}
    pl15, h12 = key[("particle_layers", 4)], key[("strain_limit_thickness", 3)]
    _cache_points(tmp_path, study)
    h12_record = (tmp_path / "points" / h12 / "point.json").read_bytes()
    for k in (pl15, h12):
        (tmp_path / "points" / k / "point.json").unlink()
    (tmp_path / "points" / pl15 / "history.csv").write_text(
        "step,s,bending_angle_deg,wall_time_s\n0,0.0,0.0,0.1\n1,0.5,40.0,600.0\n")
    monkeypatch.setattr(sweep_mod, "_local_cluster", lambda n: pytest.fail("a point was run"))
    assert main(["reproduce", "--quick", "-o", str(tmp_path), "--report-only"]) == 0
    assert "11 distinct points (13 rows): 9 ok, 0 not converged, 0 failed, 2 not finished" in capsys.readouterr().err
    assert not (tmp_path / "points" / pl15 / "point.json").exists()
    assert len(list((tmp_path / "figures").glob("*.png"))) == 6
    text = (tmp_path / "report.md").read_text(encoding="utf-8")
    assert "9 converged, 0 not converged, 0 failed, **2 not finished**." in text
    assert "**An interim report**: 2 of the 11 points are not finished" in text
    assert "Nothing was run for this report (`--report-only`)" in text
    assert "| not finished: s = 0.500 reached (40.0 deg) |" in text
    assert "| not started |" in text
    verdicts = {c.claim.id: c for c in pclaims.check_claims(sweep_mod.SweepTable.read(tmp_path))}
    assert {c.verdict for cid, c in verdicts.items() if cid.startswith("PL-")} == {"undetermined"}
    assert verdicts["PL-dx"].summary.startswith("not final, PL 15 not finished; the finished points alone read agree")
    assert {verdicts[c].verdict for c in ("T-angle", "T-displacement", "T-linear", "T-dx-dominant")} == {"agree"}
    # one point left: said in the singular
    (tmp_path / "points" / h12 / "point.json").write_bytes(h12_record)
    assert main(["reproduce", "--quick", "-o", str(tmp_path), "--report-only"]) == 0
    text = (tmp_path / "report.md").read_text(encoding="utf-8")
    assert ("**An interim report**: 1 of the 11 points is not finished (its row says where it stands); every "
            "statement of its sweeps is undetermined until it finishes.") in text
    assert "runs it on from its checkpoint and rewrites this report" in text


@pytest.mark.parametrize("args, says, made", [
    (["--report-only"], "no such folder (--report-only writes the results of a study already run", False),
    (["--report-only"], "holds no study yet (no study.toml)", True),
    (["--report-only", "--workers", "2"], "--workers: nothing runs with --report-only", True),
])
def test_reproduce_report_only_refuses_a_folder_without_a_study(tmp_path, capsys, args, says, made):
    from hydrojam.cli import main

    out = tmp_path / "out"
    if made:
        out.mkdir()
    assert main(["reproduce", "--quick", "-o", str(out), *args]) == 2
    assert says in _one_error_line(capsys)
    assert (list(out.iterdir()) == []) if made else not out.exists()


def test_reproduce_report_only_needs_the_replicas_of_the_study_in_the_folder(tmp_path, capsys):
    """A folder holding the study with 2 replicas per point: --report-only without --replicas 2
    would show replica 0 alone as each point; refused, nothing written."""
    from hydrojam.cli import main
    from hydrojam.study.spec import write_study

    write_study(tmp_path / "study.toml", pstudy.paper_study(True, replicas=2))
    assert main(["reproduce", "--quick", "-o", str(tmp_path), "--report-only"]) == 2
    assert "replicas: " in (err := _one_error_line(capsys)) and "with 2 per point (got 1)" in err
    assert "(--replicas 2)" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.toml"]


def test_reproduce_3d_states_are_reported_apart(tmp_path):
    """Replicas in two states (column_folds 0: arc, 1: folded, 40 deg lower): results.csv names each
    point's states, replicas.csv each run's; the report's section "States" gives each state's runs
    and θ and every statement's verdict per state; each state gets its own shapes figure. The
    temperature sweep: arc at every temperature in replicas 0 and 1 with θ falling in T (T-angle
    agrees on the arc runs), folded replica 2 at 275 and 285 K only (checked on the folded runs over
    275-285 K, the part of the range where the state occurs: agrees there too)."""
    import csv
    import json

    from paper_synthetic import write_point_3d

    study = pstudy.paper_study(quick=True, sweeps=["temperature"], replicas=3, dimension=3)
    for p in study.points():
        metrics = paper_like(p.design)
        T = p.design.stimulus.temperature
        folded = p.replica == 2 and T < 290.0
        metrics["bending_angle_deg"] += (-40.0 if folded else 0.0) + 0.1 * p.replica
        metrics.update(converged=True, stabilisation_released=True, newton_iterations=900,
                       column_folds=1 if folded else 0)
        write_point_3d(tmp_path, {"point_dir": f"points/{p.key}"}, bend=-0.3, design=p.design)
        record = {"key": p.key, "status": "ok", "error": None, "metrics": metrics, "wall_time_s": 600.0}
        (tmp_path / "points" / p.key / "point.json").write_text(json.dumps(record))
    table, report = reproduce(tmp_path, quick=True, sweeps=["temperature"], replicas=3, dimension=3)
    states = {r["stimulus.temperature"]: r["states"] for r in csv.DictReader(open(tmp_path / "results.csv"))}
    assert states == {"275.0": "arc 2; folded 1", "285.0": "arc 2; folded 1", "295.0": "arc"}
    runs = list(csv.DictReader(open(tmp_path / "replicas.csv")))
    assert sorted(r["states"] for r in runs) == ["arc"] * 7 + ["folded"] * 2
    text = report.read_text(encoding="utf-8")
    section = text.split("## States", 1)[1].split("###", 1)[0]
    assert "| temperature | 295 K | 3, " in section and "| 0 |" in section  # no folded run at 295 K
    line = next(ln for ln in section.splitlines() if ln.startswith("| T-angle |"))
    assert "**agree**:" in line.split("|")[3] and "**agree**:" in line.split("|")[4]
    assert "checked on the points run, 275 K to 285 K" in line.split("|")[4]
    for state in ("arc", "folded"):
        assert (tmp_path / "figures" / f"temperature_shapes_{state}.png").is_file()
        assert f"(figures/temperature_shapes_{state}.png)" in text
