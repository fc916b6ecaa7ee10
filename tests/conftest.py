"""Suite-wide settings."""
import pytest


@pytest.fixture(autouse=True)
def _console_width(monkeypatch):
    """Rich wraps and cuts its output at the console's width, which it reads from COLUMNS (80 where
    unset and not a terminal): pin it, so that a runner's terminal cannot change what the CLI tests
    read. Where a path makes a line wrap, the tests compare the text with its whitespace collapsed."""
    monkeypatch.setenv("COLUMNS", "80")
