"""`hydrojam sweep --plot`: chosen metrics against each sweep's varied field, drawn from the
table (hydrojam.study.plots); the points' records written by hand, nothing run."""

from __future__ import annotations

import json

import pytest

from hydrojam.cli import main
from hydrojam.study.spec import study_from_dict, write_study


@pytest.fixture
def replicated(tmp_path):
    """Three temperatures of two replicas each: two points ok, the third failed."""
    study = study_from_dict({"name": "bi", "design": {"particle_layers": 1, "mesh": {"size": 4.0},
                                                      "replicas": {"count": 2}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [280, 290, 300]}}]})
    out = tmp_path / "out"
    write_study(out / "study.toml", study)
    for p in study.points():
        ok = p.index < 2
        (out / "points" / p.key).mkdir(parents=True)
        (out / "points" / p.key / "point.json").write_text(json.dumps(
            {"key": p.key, "status": "ok" if ok else "failed", "error": None if ok else "boom", "wall_time_s": 1.0,
             "metrics": {"bending_angle_deg": 4.0 - 8.0 * p.index + p.replica, "twist_deg": 0.0} if ok else None}))
    (out / "bi.toml").write_bytes((out / "study.toml").read_bytes())
    return out


def test_sweep_plot_draws_the_metrics_against_the_varied_field(replicated, capsys):
    out = replicated
    assert main(["sweep", str(out / "bi.toml"), "-o", str(out), "--table-only",
                 "--plot", "bending_angle_deg,twist_deg"]) == 1  # its failed point
    figure = out / "figures" / "temperature.png"
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"figure: {figure}" in capsys.readouterr().err.replace("\n", "")


@pytest.mark.parametrize(("plot", "expected"), [
    ("bending_angle", "--plot: unknown metric 'bending_angle' (allowed: bending_angle_deg, bending_plane_deg"),
    (",", "--plot: give one or more metrics, comma-separated, of: bending_angle_deg"),
])
def test_sweep_plot_refuses_an_unknown_metric_before_any_work(replicated, capsys, plot, expected):
    out = replicated
    assert main(["sweep", str(out / "bi.toml"), "-o", str(out), "--table-only", "--plot", plot]) == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1, err
    assert not (out / "figures").exists() and not (out / "results.csv").exists()
