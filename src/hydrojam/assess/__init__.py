"""Assessing an actuator as a jamming actuator (2D or 3D): stiffness, blocked force, confinement
and the vacuum-jamming and pneumatic baselines. ``assess(design, loads)`` gives the numbers,
``write_report`` the report, ``assess_replicas`` the spread over a design's replicas; the pieces
live in loading, chamber, pneumatic, confinement, replicas and design_map."""

from hydrojam.assess.assessment import Assessment, assess
from hydrojam.assess.replicas import assess_replicas
from hydrojam.assess.report import write_report
from hydrojam.assess.spec import AssessError, Loads, load_loads, loads_from_dict

__all__ = ["AssessError", "Assessment", "Loads", "assess", "assess_replicas", "load_loads", "loads_from_dict", "write_report"]
