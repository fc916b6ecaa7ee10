"""Provenance in metrics.json: the source commit and dirty flag, the CPU and MKL's dispatched
instruction set; each "unknown" on any failure, never an error."""

import json
import re
import subprocess
from pathlib import Path

import pytest

from hydrojam.actuator import provenance
from hydrojam.actuator.provenance import (UNKNOWN, cpu_model, machine_provenance, mkl_provenance, run_provenance,
                                          source_provenance)

PACKAGE = Path(provenance.__file__).resolve().parent


def _git(*args) -> str | None:
    try:
        return subprocess.run(["git", "-C", str(PACKAGE), *args], capture_output=True, text=True, timeout=10,
                              check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None


def test_run_provenance_has_the_source_cpu_and_mkl_fields():
    p = run_provenance()
    assert set(p["source"]) == {"commit", "dirty"}
    assert set(p["machine"]) == {"cpu", "cpu_count", "mkl"}
    assert set(p["machine"]["mkl"]) == {"instruction_set", "cbwr", "version"}
    assert "MKL_CBWR" in p["environment"] and "MKL_ENABLE_INSTRUCTIONS" in p["environment"]
    json.dumps(p, allow_nan=False)


def test_the_commit_is_the_checkout_s_where_the_package_is_tracked():
    """In a git checkout (an editable install, as the tests run) the commit is HEAD's and the
    dirty flag git's own; an installed copy says "unknown"."""
    src = source_provenance()
    head = _git("rev-parse", "HEAD") if _git("ls-files", "--error-unmatch", "provenance.py") is not None else None
    if head is None:
        assert src == {"commit": UNKNOWN, "dirty": UNKNOWN}
    else:
        assert src["commit"] == head and re.fullmatch(r"[0-9a-f]{40}", head)
        assert src["dirty"] is bool(_git("status", "--porcelain", "--untracked-files=no"))


@pytest.mark.parametrize("error", [FileNotFoundError("git"), subprocess.TimeoutExpired("git", 10),
                                   subprocess.CalledProcessError(128, "git")])
def test_no_git_or_no_checkout_gives_unknown(monkeypatch, error):
    def fail(*args, **kwargs):
        raise error

    monkeypatch.setattr(provenance.subprocess, "run", fail)
    assert source_provenance() == {"commit": UNKNOWN, "dirty": UNKNOWN}


def test_cpu_model_is_a_name():
    assert isinstance(cpu_model(), str) and cpu_model()
    assert machine_provenance()["cpu_count"] >= 1


def test_mkl_instruction_set_is_a_known_branch_or_unknown():
    mkl = mkl_provenance()
    known = set(provenance._MKL_BRANCHES.values()) - {"OFF", "AUTO"}
    assert mkl["instruction_set"] in known | {UNKNOWN}
    if mkl["version"] != UNKNOWN:  # MKL loaded (pypardiso's); its auto branch may be AUTO itself (AMD EPYC)
        assert "Math Kernel Library" in mkl["version"]


def test_mkl_branch_set_by_cbwr_is_the_one_recorded(monkeypatch):
    """MKL_CBWR set (read by MKL when it starts): a fake runtime whose CBWR branch is AVX2."""
    class FakeFunction:
        def __init__(self, value):
            self.value = value

        def __call__(self, *args):
            return self.value

    class FakeMKL:
        MKL_CBWR_Get = FakeFunction(10)
        MKL_CBWR_Get_Auto_Branch = FakeFunction(14)

        def MKL_Get_Version_String(self, buf, n):
            buf.value = b"MKL test"

    monkeypatch.setattr(provenance, "_mkl_library", lambda: FakeMKL())
    assert mkl_provenance() == {"instruction_set": "AVX2", "cbwr": "AVX2", "version": "MKL test"}
    FakeMKL.MKL_CBWR_Get = FakeFunction(1)  # off: MKL picks, here AVX512_E1
    assert mkl_provenance()["instruction_set"] == "AVX512_E1"


@pytest.mark.parametrize("library", [lambda: None, lambda: object(), lambda: 1 / 0])
def test_no_mkl_or_an_old_one_gives_unknown(monkeypatch, library):
    """No MKL, one without the CBWR functions, a failing lookup: unknown, never an error."""
    monkeypatch.setattr(provenance, "_mkl_library", library)
    assert mkl_provenance()["instruction_set"] == UNKNOWN
