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


BLOCKS = [[line.split("#")[0].strip() for line in blk.splitlines() if line.strip().startswith("hydrojam ")]
          for blk in re.findall(r"```sh\n(.*?)```", README, re.S)]
BLOCKS = [b for b in BLOCKS if b]


@pytest.mark.parametrize("commands", BLOCKS, ids=[b[0][:40] for b in BLOCKS])
def test_cli_commands_run(commands, tmp_path, monkeypatch, capsys):
    """The commands of one README block, in order, in one folder (a later one may use what an
    earlier one wrote, as `hydrojam run` uses the design of `hydrojam init`)."""
    monkeypatch.chdir(tmp_path)
    for command in commands:
        argv = shlex.split(command.split(">")[0])[1:]
        assert main(argv) == 0, command
