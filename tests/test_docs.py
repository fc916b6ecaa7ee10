"""The documentation site builds without a warning (a broken reference, a missing page, a bad
docstring fails the suite), and the docstrings' examples run as doctests."""

from __future__ import annotations

import doctest
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# the modules whose docstrings carry examples: the material, swelling, small FE solves
DOCTEST_MODULES = ["hydrojam.materials.energies", "hydrojam.materials.swelling", "hydrojam.fem",
                   "hydrojam.fem.solver.path"]


@pytest.mark.parametrize("name", DOCTEST_MODULES)
def test_docstring_examples_run(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS, verbose=False)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0


def test_the_site_builds_without_warnings(tmp_path):
    """sphinx-build -W: every warning is an error (as `make docs`, with -n for references too)."""
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    pytest.importorskip("numpydoc")
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", "-d", str(tmp_path / "doctrees"),
         str(ROOT / "docs"), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-5000:]
    assert (tmp_path / "html" / "index.html").is_file()
    api = (tmp_path / "html" / "api" / "fem.html").read_text()
    assert "solve_path" in api and "Parameters" in (tmp_path / "html" / "api" / "materials.html").read_text()
    # the design's keys, a table's under its dotted name, with the range its model enforces
    actuator = (tmp_path / "html" / "api" / "actuator.html").read_text()
    from hydrojam._validation import field_range
    from hydrojam.actuator.design import Design

    for key in ("particle_layers", "mesh.size", "stimulus.temperature"):
        assert f">{key}<" in actuator
    assert field_range(Design, "particle_layers") in actuator
