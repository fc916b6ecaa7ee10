"""The `hydrojam` command line: outputs, and one-line errors with exit status 2."""

import json
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
