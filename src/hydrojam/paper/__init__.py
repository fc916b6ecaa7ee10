"""The paper's Section IV: its sweeps (``study``), its statements as data checked against hydrojam
(``claims``), the figures, ``report.md``, the whole run (``reproduce``) and the 2D-against-3D
table (``compare``). The names below are the public API, loaded on first use.
"""

from __future__ import annotations

import importlib

_PUBLIC = {
    "hydrojam.paper.reproduce": ['reproduce'],
    "hydrojam.paper.study": ['PaperSweep', 'PAPER_SWEEPS', 'QUICK_MESH_SIZE', 'paper_study', 'paper_base', 'study_name'],
    "hydrojam.paper.claims": ['Claim', 'Trend', 'ClaimResult', 'PAPER_CLAIMS', 'check_claim', 'check_claims', 'ANGLE_TOL', 'DISPLACEMENT_TOL'],
    "hydrojam.paper.figures": ['plot_shapes', 'plot_trends', 'write_figures'],
    "hydrojam.paper.report": ['write_report', 'MODEL_DIFFERENCES'],
    "hydrojam.paper.compare": ['compare_points', 'PointComparison', 'CompareError'],
}
_MODULE_OF = {name: module for module, names in _PUBLIC.items() for name in names}

__all__ = [name for names in _PUBLIC.values() for name in names]

def __getattr__(name: str):
    if name in _MODULE_OF:
        value = getattr(importlib.import_module(_MODULE_OF[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
