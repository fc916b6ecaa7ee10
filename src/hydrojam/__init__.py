"""hydrojam: simulator for active particle jamming actuators (PNIPAM hydrogel particles in an
elastomer chamber). Units: mm, MPa, mJ, K; chemical potential in k_B T.

``import hydrojam`` loads nothing but its version: each name below is imported from its module
on first use (the materials and the design schema need numpy and pydantic; the model, the
simulation and studies gmsh and ipctk). The command line's entry point (:mod:`hydrojam.__main__`)
relies on it: it installs its signal handlers before anything heavy is imported.
"""

from hydrojam._lazy import lazy_api
from hydrojam._version import __version__

_PUBLIC = {
    "hydrojam.actuator.model": ["ActuatorModel", "build_model", "measure"],
    "hydrojam.actuator.design": ["Design", "DesignError", "apply_overrides", "default_design", "load_design",
                                 "write_design"],
    "hydrojam.actuator.simulate": ["SimulationResult", "simulate"],
    "hydrojam.study.spec": ["Study", "load_study"],
    "hydrojam.materials.energies": ["KT_OVER_NU_MPA", "Hydrogel", "HydrogelParams", "Material", "MaterialResponse",
                                    "NeoHookean", "Yeoh"],
    "hydrojam.materials.swelling": ["SwellingState", "Transition", "constrained_swelling", "free_swelling",
                                    "nominal_stresses", "reference_chemical_potential", "swelling_curve",
                                    "transition_temperature"],
}
__all__, __getattr__, __dir__ = lazy_api(__name__, _PUBLIC, globals())
