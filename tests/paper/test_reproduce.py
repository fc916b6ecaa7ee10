"""hydrojam.paper.reproduce end to end over cached points, and the reproduce command's option checks.

No simulation runs: every point is already in the cache.
"""

from __future__ import annotations

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
    assert seen[-1] == (10, 10) and len(table.rows) == 12
    text = report.read_text(encoding="utf-8")
    assert report == tmp_path / "report.md"
    assert len(list((tmp_path / "figures").glob("*.png"))) == 6
    verdicts = {c.claim.id: c.verdict for c in pclaims.check_claims(table)}
    assert verdicts == {c.id: ("undetermined" if c.sweep == "strain_limit_thickness" else "agree")
                        for c in pclaims.PAPER_CLAIMS}
    assert "10 distinct points" in text and "compute time summed over points 10.0 min" in text
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
