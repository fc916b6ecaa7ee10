"""Assessing an actuator as a jamming actuator (2D or 3D): stiffness, blocked force, confinement
and the vacuum-jamming and pneumatic baselines. ``assess(design, loads)`` gives the numbers,
``write_report`` the report, ``assess_replicas`` the spread over a design's replicas; the pieces
live in loading, chamber, pneumatic, confinement, replicas and design_map."""

from hydrojam._lazy import lazy_api

_PUBLIC = {
    "hydrojam.assess.assessment": ["Assessment", "assess", "check_assessable"],
    "hydrojam.assess.report": ["write_report", "write_replica_report"],
    "hydrojam.assess.replicas": ["assess_replicas", "check_replica_folder"],
    "hydrojam.assess.spec": ["AssessError", "Loads", "load_loads", "loads_from_dict"],
    "hydrojam.assess.design_map": ["design_map", "map_study", "MAP_VALUES", "MODULUS", "THICKNESS"],
}
__all__, __getattr__, __dir__ = lazy_api(__name__, _PUBLIC, globals())
