"""A study's points on disk: what became of each (:class:`PointStatus`, the ``status`` its
point.json and its row in the table hold)."""

from __future__ import annotations

import enum

__all__ = ["FINISHED", "PointStatus"]


class PointStatus(enum.StrEnum):
    """What became of a point: one run of one design. Each member is the text the files hold
    (point.json's ``status``, the table's ``status`` column), and equal to it as a string.

    Attributes
    ----------
    OK : str
        "ok": the run reached the target stimulus.
    NOT_CONVERGED : str
        "not_converged": the run stopped early; its metrics are its last converged state's.
    FAILED : str
        "failed": the run raised (or its worker died); no metrics.
    UNFINISHED : str
        "unfinished": not finished yet, started or not (a table written without running, and
        ``hydrojam status`` for a run with a checkpoint or an accepted state).
    NOT_STARTED : str
        "not started": nothing written yet (``hydrojam status`` only).
    """

    OK = "ok"
    NOT_CONVERGED = "not_converged"
    FAILED = "failed"
    UNFINISHED = "unfinished"
    NOT_STARTED = "not started"


#: the statuses of a finished point: its point.json is loaded, not run again
FINISHED = frozenset({PointStatus.OK, PointStatus.NOT_CONVERGED})
