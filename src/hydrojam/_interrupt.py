"""A run stopped by a signal: SIGINT (Ctrl-C) and SIGTERM (``kill``, a batch system's time limit)
raise :class:`Interrupted` in the main thread, so that every clean-up runs (a folder's lock
released, a sweep's workers closed) and the command can say where it stopped. The exit status of
a stopped command is 128 + the signal's number: 130 for SIGINT, 143 for SIGTERM.

Only the standard library is imported here: the command line's entry point installs the handlers
before it imports anything else (:mod:`hydrojam.__main__`).
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["Interrupted", "SIGNALS", "interruption", "signals_blocked", "stop_on_signals"]

#: the signals that stop a command cleanly
SIGNALS = (signal.SIGINT, signal.SIGTERM)

#: what each signal is, in a message's words
_WORDS = {signal.SIGINT: "SIGINT (Ctrl-C)", signal.SIGTERM: "SIGTERM"}


class Interrupted(KeyboardInterrupt):
    """A stop by the signal ``signum`` (a KeyboardInterrupt, so that whatever cleans up after
    Ctrl-C cleans up after SIGTERM too)."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signum)
        self.signum = int(signum)

    @property
    def words(self) -> str:
        """The signal in a message's words: "SIGINT (Ctrl-C)", "SIGTERM"."""
        try:
            return _WORDS.get(self.signum) or signal.Signals(self.signum).name
        except ValueError:
            return f"signal {self.signum}"

    @property
    def exit_status(self) -> int:
        """128 + the signal's number: 130 for SIGINT, 143 for SIGTERM."""
        return 128 + self.signum


def interruption(err: BaseException | None) -> Interrupted | None:
    """The stop behind ``err``: ``err`` itself, or an exception it was raised from or while
    handling (``__cause__``, ``__context__``): a numba kernel interrupted while it returns reports
    a SystemError raised from the KeyboardInterrupt, and typer turns one into ``Exit(130)``. A
    plain KeyboardInterrupt is taken as SIGINT. None where no interrupt is behind it."""
    seen = set()
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        if isinstance(err, Interrupted):
            return err
        if isinstance(err, KeyboardInterrupt):
            return Interrupted(signal.SIGINT)
        err = err.__cause__ or err.__context__
    return None


class _State:
    stopping = False  # a signal was raised: the next ones wait for its clean-up to end


def _handler(signum, frame) -> None:
    if _State.stopping:
        return  # the first signal's clean-up (locks, workers) runs to its end
    _State.stopping = True
    raise Interrupted(signum)


@contextlib.contextmanager
def stop_on_signals():
    """While the block runs, SIGINT and SIGTERM raise :class:`Interrupted` in the main thread
    (once: a signal that comes while the first one's clean-up runs is ignored); the previous
    handlers are restored after. Outside the main thread (nothing can be installed there) the
    block just runs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    stopping = _State.stopping
    for s in SIGNALS:
        signal.signal(s, _handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
        _State.stopping = stopping


@contextlib.contextmanager
def signals_blocked():
    """SIGINT blocked in the calling thread while the block runs: threads started in it, and
    the processes they start, inherit the mask, so that a local dask cluster's worker processes
    do not get the terminal's Ctrl-C (the command stops them itself; each would print a
    traceback). A SIGINT that comes meanwhile waits and is delivered when the block ends. Where
    signal masks do not exist (Windows), the block just runs."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
