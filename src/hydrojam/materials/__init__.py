"""Materials: energy densities W(F) with P = dW/dF and dP/dF (elastomers, the PNIPAM gel), the
gel's material-point swelling and one particle's swelling kinetics.

The lowest layer: it imports nothing else of hydrojam. The names below are its public API (the
most used are also in :mod:`hydrojam` itself); they are loaded on first use.
"""

from __future__ import annotations

import importlib

_PUBLIC = {
    "hydrojam.materials.energies": ['Material', 'MaterialResponse', 'NeoHookean', 'Yeoh', 'Hydrogel', 'HydrogelParams', 'KT_OVER_NU_MPA', 'bulk_modulus', 'nominal_stresses', 'reference_chemical_potential'],
    "hydrojam.materials.swelling": ['SwellingState', 'Transition', 'free_swelling', 'constrained_swelling', 'swelling_curve', 'transition_temperature', 'equilibrium_stretches'],
    "hydrojam.materials.kinetics": ['DEFAULT_DIFFUSIVITY', 'time_constant', 'mean_log_swelling'],
    "hydrojam.materials.plots": ['plot_swelling_curve'],
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
