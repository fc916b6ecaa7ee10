"""Studies: study files, parallel cached sweeps (dask) and their table, replicas of a design and
their spread, and where an output folder stands. It maps a simulation over designs and never
reaches inside one. The names below are the public API, loaded on first use.
"""

from __future__ import annotations

import importlib

_PUBLIC = {
    "hydrojam.study.spec": ['Study', 'StudyError', 'SweepSpec', 'Point', 'load_study', 'study_from_dict', 'write_study', 'design_key'],
    "hydrojam.study.sweep": ['run_sweep', 'SweepTable', 'PointOutcome', 'SchedulerError'],
    "hydrojam.study.replicas": ['run_replicas', 'replica_study', 'ReplicaSummary', 'summarise'],
    "hydrojam.study.spread": ['Spread', 'spread'],
    "hydrojam.study.status": ['folder_status', 'FolderStatus', 'RunStatus', 'StatusError'],
    "hydrojam.study.snapshot": ['write_snapshots', 'Snapshot'],
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
