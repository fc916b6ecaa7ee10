"""The paper's Section IV: its sweeps (``study``), its statements as data checked against hydrojam
(``claims``), the figures, ``report.md``, the whole run (``reproduce``) and the 2D-against-3D
table (``compare``). The names below are the public API, loaded on first use.
"""

from __future__ import annotations

from hydrojam._lazy import lazy_api

_PUBLIC = {
    "hydrojam.paper.reproduce": ['reproduce'],
    "hydrojam.paper.study": ['PaperSweep', 'PAPER_SWEEPS', 'QUICK_MESH_SIZE', 'paper_study', 'paper_base', 'paper_sweeps', 'study_name', 'DIMENSIONS', 'reproduce_command', 'study_kind'],
    "hydrojam.paper.claims": ['Claim', 'Trend', 'ClaimResult', 'PAPER_CLAIMS', 'check_claim', 'check_claims', 'check_state_claims', 'Verdict', 'ANGLE_TOL', 'DISPLACEMENT_TOL'],
    "hydrojam.paper.figures": ['plot_shapes', 'plot_trends', 'write_figures'],
    "hydrojam.paper.report": ['write_report', 'MODEL_DIFFERENCES'],
    "hydrojam.paper.compare": ['compare_points', 'PointComparison', 'CompareError', 'read_2d_results'],
    "hydrojam.paper.sections": ["SectionError", "check_page", "compare_lines"],
}
__all__, __getattr__, __dir__ = lazy_api(__name__, _PUBLIC, globals())
