"""The actuator: its design (TOML), geometry, model (bodies, materials, clamp, contact), stimulus
path, simulation, metrics, output files, checkpoints and figures (3D renders, the actuation movie
and the run's HTML page).

``Design`` -> ``build_model(design)`` -> ``simulate(model)`` -> ``SimulationResult`` with its
``metrics``; ``ResultWriter`` writes the files of ``hydrojam run``. The names below are the public
API, loaded on first use (the model needs gmsh and the IPC Toolkit).
"""

from __future__ import annotations

from hydrojam._lazy import lazy_api

_PUBLIC = {
    "hydrojam.actuator.design": ['Design', 'DesignError', 'default_design', 'design_from_dict', 'load_design', 'apply_overrides', 'write_design', 'design_to_toml', 'ElastomerSpec', 'MAX_REPLICAS', 'WATER_RANGE_K', 'with_replicas', 'merge_value', 'toml_value'],
    "hydrojam.actuator.model": ['ActuatorModel', 'build_model', 'measure', 'MEMBRANE', 'MEMBRANE_BODY', 'PARTICLES', 'STRAIN_LIMIT_BODY', 'STRAIN_LIMIT_LAYER', 'centreline_x', 'check_supported', 'outer_faces'],
    "hydrojam.actuator.simulate": ['SimulationResult', 'simulate', 'ACTUATOR_PATH', 'STABILISATION', 'StepState'],
    "hydrojam.actuator.stimulus": ['StimulusPath', 'stimulus_path', 'TimedStimulusPath', 'timed_stimulus_path'],
    "hydrojam.actuator.metrics": ['Metric', 'Gauges', 'metric', 'metric_names', 'bending_angle_deg', 'tip_displacement', 'curling_index', 'centreline_profile', 'STATE_METRICS', 'centreline_points', 'bending_angle_3d_deg'],
    "hydrojam.actuator.results": ['ResultWriter', 'vtu_mesh', 'write_vtu', 'plot_state'],
    "hydrojam.actuator.checkpoint": ['RunCheckpoint', 'CheckpointError', 'load_checkpoint', 'save_checkpoint', 'CHECKPOINT', 'ReleaseProgress', 'release_progress'],
    "hydrojam.actuator.plots": ['plot_actuator', 'plot_angle_time', 'mid_section'],
    "hydrojam.actuator.geometry": ["actuator_2d", "actuator_3d"],
    "hydrojam.actuator.provenance": ["source_provenance"],
    "hydrojam.actuator.render": ['render_state', 'state_surfaces', 'renders_available', 'Renderer', 'swelling_range',
                                 'SWELLING_CMAP'],
    "hydrojam.actuator.movie": ['write_movie', 'NoStates', 'mp4_encoder', 'NO_MP4'],
    "hydrojam.actuator.page": ['write_run_page', 'state_view'],
}
__all__, __getattr__, __dir__ = lazy_api(__name__, _PUBLIC, globals())
