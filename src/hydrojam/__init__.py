"""hydrojam: simulator for active particle jamming actuators (PNIPAM hydrogel particles in an
elastomer chamber). Units: mm, MPa, mJ, K; chemical potential in k_B T."""

from .design import Design, DesignError, apply_overrides, default_design, load_design, write_design
from .materials import KT_OVER_NU_MPA, Hydrogel, HydrogelParams, Material, MaterialResponse, NeoHookean, Yeoh
from .swelling import (
    SwellingState,
    Transition,
    constrained_swelling,
    free_swelling,
    nominal_stresses,
    reference_chemical_potential,
    swelling_curve,
    transition_temperature,
)

from .model import ActuatorModel, build_model, measure
from .simulate import SimulationResult, simulate
from .study import Study, load_study

__version__ = "0.1.0"

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
