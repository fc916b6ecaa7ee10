"""The ``hydrojam`` command's entry point (also ``python -m hydrojam``): SIGINT and SIGTERM are
handled from the first moment (:mod:`hydrojam._interrupt`), so that a stop while the command
line's modules are still being imported says so in one line, without a traceback."""

import sys

from hydrojam._interrupt import interruption, stop_on_signals


def run() -> None:
    """Run the command line (:func:`hydrojam.cli.main`) and exit with its status; a stop by a
    signal before it starts: one line, exit status 128 + the signal's number."""
    with stop_on_signals():
        try:
            from hydrojam.cli import main
        except BaseException as err:
            stop = interruption(err)
            if stop is None:
                raise
            print(f"hydrojam: stopped by {stop.words} while starting; nothing was run", file=sys.stderr)
            sys.exit(stop.exit_status)
        status = main()
    sys.exit(status)


if __name__ == "__main__":
    run()
