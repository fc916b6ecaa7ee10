"""Every script in examples/ runs as a user would run it (a fresh interpreter, another working
folder, an output folder given) and prints what it promises: documentation cannot rot.

The scripts are found with a glob, so a new example is run without touching this file; the key
figures of the known ones are checked against documented or physical values below.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))


def _run(script: Path, cwd: Path, out: Path) -> str:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), *filter(None, [env.get("PYTHONPATH")])])
    proc = subprocess.run([sys.executable, str(script), str(out)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"{script.name} exited {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


def _number(pattern: str, text: str) -> float:
    m = re.search(pattern, text)
    assert m, f"{pattern!r} not in the output:\n{text}"
    return float(m.group(1))


def _check_swelling_curve(stdout: str, out: Path) -> None:
    """README / docs/model.md: at mu = 0 the transition is discontinuous at 305.4 K, and at 275 K
    the free gel swells to 2.16 x its as-prepared size. The bounds are the documented values'
    last digit (the root finders behind them are converged to 1e-9 K and 1e-14)."""
    assert _number(r"transition: T = ([\d.]+) K", stdout) == pytest.approx(305.4, abs=0.05)
    assert "(discontinuous" in stdout
    assert _number(r"\n\s*275\.0\s+([\d.]+)", stdout) == pytest.approx(2.16, abs=0.005)
    assert (out / "swelling_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _check_one_actuator(stdout: str, out: Path) -> None:
    """The printed figures are the ones written to metrics.json (to their printed 2 decimals); the
    actuator bends toward the strain-limit layer (positive angle, tip moving to -x and down).
    No tighter bound on the angle: a column of particles has many equilibria and round-off
    selects among them (docs/actuator.md, "Path dependence")."""
    metrics = json.loads((out / "metrics.json").read_text())
    angle = _number(r"bending angle:\s+(-?[\d.]+) deg", stdout)
    assert angle == pytest.approx(metrics["bending_angle_deg"], abs=0.005)
    assert _number(r"dx = (-?[\d.]+) mm", stdout) == pytest.approx(metrics["tip_dx_mm"], abs=0.005)
    assert metrics["converged"] is True and "converged: True" in stdout
    assert angle > 10.0 and metrics["tip_dx_mm"] < 0 and metrics["tip_dz_mm"] < 0
    for name in ("design.toml", "history.csv", "centreline.csv", "final.png"):
        assert (out / name).is_file(), name


def _check_custom_sweep(stdout: str, out: Path) -> None:
    """Both points finished; the colder gel swells more and bends the actuator further (the
    paper's temperature trend, Fig. 6). A rerun loads the cached points and prints the same table."""
    rows = re.findall(r"\n\s*(\d+\.\d)\s+(-?[\d.]+)\s+(-?[\d.]+)\s+(-?[\d.]+)\s+(\w+)", stdout)
    assert [(T, status) for T, *_, status in rows] == [("285.0", "ok"), ("295.0", "ok")]
    assert float(rows[0][1]) > float(rows[1][1])
    assert (out / "results.csv").is_file()


def _check_gel_layer(stdout: str, out: Path) -> None:
    """The swollen layer is homogeneous, which quadratic elements represent exactly, so the only
    error is the solver's: it stops at a residual below rtol = 1e-6 of the forces in play. The
    strain error is that residual over the tangent stiffness; the forces in play (the network
    and mixing stresses, which balance) are O(10) times the swollen gel's tangent modulus, so
    the relative error is O(1e-5); 1e-3 bounds it on any machine."""
    assert _number(r"relative error:\s+([\d.e+-]+)", stdout) < 1e-3
    fe = _number(r"finite elements:\s+([\d.]+)", stdout)
    assert fe == pytest.approx(3.45, abs=0.005)  # README: thickness x 3.45
    assert (out / "gel_layer.csv").is_file()


CHECKS = {
    "swelling_curve.py": _check_swelling_curve,
    "one_actuator.py": _check_one_actuator,
    "custom_sweep.py": _check_custom_sweep,
    "gel_layer_on_substrate.py": _check_gel_layer,
}


def test_examples_are_found():
    assert set(CHECKS) <= {p.name for p in EXAMPLES}


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(script, tmp_path):
    out = tmp_path / "out"
    stdout = _run(script, tmp_path, out)
    check = CHECKS.get(script.name)
    if check is not None:
        check(stdout, out)
    if script.name == "custom_sweep.py":
        assert _run(script, tmp_path, out) == stdout  # the rerun: every point from the cache


def test_examples_readme_lists_every_example():
    readme = (ROOT / "examples" / "README.md").read_text()
    assert [p.name for p in EXAMPLES if p.name not in readme] == []
