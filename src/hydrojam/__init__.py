"""hydrojam: simulator for active particle jamming actuators (PNIPAM hydrogel particles in an
elastomer chamber). Units: mm, MPa, mJ, K; chemical potential in k_B T.

``import hydrojam`` loads the materials and the design schema only: the names that need gmsh or
ipctk (the model, the simulation, studies) are imported on first use.
"""

from hydrojam._version import __version__

from hydrojam.actuator.design import Design, DesignError, apply_overrides, default_design, load_design, write_design
from hydrojam.materials.energies import KT_OVER_NU_MPA, Hydrogel, HydrogelParams, Material, MaterialResponse, NeoHookean, Yeoh
from hydrojam.materials.swelling import (
    SwellingState,
    Transition,
    constrained_swelling,
    free_swelling,
    nominal_stresses,
    reference_chemical_potential,
    swelling_curve,
    transition_temperature,
)

_LAZY = {
    "ActuatorModel": "hydrojam.actuator.model",
    "build_model": "hydrojam.actuator.model",
    "measure": "hydrojam.actuator.model",
    "SimulationResult": "hydrojam.actuator.simulate",
    "simulate": "hydrojam.actuator.simulate",
    "Study": "hydrojam.study.spec",
    "load_study": "hydrojam.study.spec",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'hydrojam' has no attribute {name!r}")

__all__ = [
    "ActuatorModel",
    "Design",
    "DesignError",
    "SimulationResult",
    "Study",
    "apply_overrides",
    "build_model",
    "default_design",
    "load_design",
    "load_study",
    "measure",
    "simulate",
    "write_design",
    "KT_OVER_NU_MPA",
    "Hydrogel",
    "HydrogelParams",
    "Material",
    "MaterialResponse",
    "NeoHookean",
    "Yeoh",
    "SwellingState",
    "Transition",
    "constrained_swelling",
    "free_swelling",
    "nominal_stresses",
    "reference_chemical_potential",
    "swelling_curve",
    "transition_temperature",
]
