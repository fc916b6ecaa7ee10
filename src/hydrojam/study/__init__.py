"""Studies: study files, parallel cached sweeps (dask), their table and figures, replicas of a design and
their spread, and where an output folder stands. It maps a simulation over designs and never
reaches inside one. The names below are the public API, loaded on first use.
"""

from __future__ import annotations

from hydrojam._lazy import lazy_api

_PUBLIC = {
    "hydrojam.study.spec": ['Study', 'StudyError', 'SweepSpec', 'Point', 'load_study', 'study_from_dict', 'write_study', 'design_key', 'validation_message'],
    "hydrojam.study.sweep": ['run_sweep', 'PointOutcome', 'SchedulerError', 'check_address'],
    "hydrojam.study.table": ['SweepTable', 'state_tables', 'run_states', 'NOT_IN_STATE'],
    "hydrojam.study.states": ['STATES', 'state_of'],
    "hydrojam.study.cache": ['PointStatus', 'ROW_STATUSES', 'point_progress'],
    "hydrojam.study.replicas": ['run_replicas', 'replica_study', 'ReplicaSummary', 'summarise', 'REPLICA_STUDY'],
    "hydrojam.study.spread": ['Spread', 'spread'],
    "hydrojam.study.status": ['folder_status', 'FolderStatus', 'RunStatus', 'StatusError', 'current_state'],
    "hydrojam.study.snapshot": ['write_snapshots', 'Snapshot'],
    "hydrojam.study.plots": ['write_sweep_figures', 'plot_sweep', 'check_plot_metrics', 'PLOT_METRICS'],
}
__all__, __getattr__, __dir__ = lazy_api(__name__, _PUBLIC, globals())
