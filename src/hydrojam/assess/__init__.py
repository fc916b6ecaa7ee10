"""Assessing an actuator as a jamming actuator: stiffness, blocked force, confinement and the
vacuum-jamming baseline. ``assess(design, loads)`` gives the numbers,
``write_report`` the report; the pieces live in loading, chamber, confinement and design_map."""

from hydrojam.assess.assessment import Assessment, assess
from hydrojam.assess.report import write_report
from hydrojam.assess.spec import AssessError, Loads, load_loads, loads_from_dict

__all__ = ["AssessError", "Assessment", "Loads", "assess", "load_loads", "loads_from_dict", "write_report"]
