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


def _steps(block: str) -> list[tuple[str, ...]]:
    """A shell block as steps: ("write", file, text) for a `cat > FILE <<'EOF'` here-document,
    ("run", command) for a `hydrojam ...` line; other lines are not run."""
    steps, lines = [], iter(block.splitlines())
    for line in lines:
        here = re.fullmatch(r"cat > (\S+) <<'(\w+)'", line.strip())
        if here:
            body = []
            for inner in lines:
                if inner == here.group(2):
                    break
                body.append(inner + "\n")
            steps.append(("write", here.group(1), "".join(body)))
        elif line.strip().startswith("hydrojam "):
            steps.append(("run", line.split("#")[0].strip()))
    return steps


BLOCKS = [_steps(blk) for blk in re.findall(r"```sh\n(.*?)```", README, re.S)]
BLOCKS = [b for b in BLOCKS if any(step[0] == "run" for step in b)]


@pytest.mark.parametrize("steps", BLOCKS, ids=[next(s[1] for s in b if s[0] == "run")[:40] for b in BLOCKS])
def test_cli_commands_run(steps, tmp_path, monkeypatch, capsys):
    """The commands of one README block, in order, in one folder (a later one may use what an
    earlier one wrote, as `hydrojam run` uses the design of `hydrojam init`); a here-document
    (`cat > FILE <<'EOF'`) writes its file."""
    monkeypatch.chdir(tmp_path)
    for step in steps:
        if step[0] == "write":
            Path(step[1]).write_text(step[2])
            continue
        command = step[1]
        argv = shlex.split(command.split(">")[0])[1:]
        assert main(argv) == 0, command
