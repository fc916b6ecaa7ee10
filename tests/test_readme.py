"""Every Python example and every `hydrojam` command in the README runs (documentation cannot rot)."""

import re
import shlex
from pathlib import Path

import pytest

from hydrojam.cli import main

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


@pytest.mark.parametrize("block", re.findall(r"```python\n(.*?)```", README, re.S))
def test_python_examples_run(block):
    exec(compile(block, "README.md", "exec"), {})


COMMANDS = [line.split("#")[0].strip() for blk in re.findall(r"```sh\n(.*?)```", README, re.S)
            for line in blk.splitlines() if line.strip().startswith("hydrojam ")]


@pytest.mark.parametrize("command", COMMANDS)
def test_cli_commands_run(command, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = shlex.split(command.split(">")[0])[1:]
    assert main(argv) == 0
    assert COMMANDS  # the README shows at least one command
