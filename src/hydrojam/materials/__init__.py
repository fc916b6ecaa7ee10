"""Materials: energy densities W(F) with P = dW/dF and dP/dF (elastomers, the PNIPAM gel), the
gel's material-point swelling and one particle's swelling kinetics.

The lowest layer: it imports nothing else of hydrojam but the shared helpers. The names below are its public API (the
most used are also in :mod:`hydrojam` itself); they are loaded on first use.
"""

from __future__ import annotations

from hydrojam._lazy import lazy_api

_PUBLIC = {
    "hydrojam.materials.energies": ['Material', 'MaterialResponse', 'NeoHookean', 'Yeoh', 'Hydrogel', 'HydrogelParams', 'KT_OVER_NU_MPA', 'bulk_modulus', 'nominal_stresses', 'reference_chemical_potential', 'WATER_RANGE_K'],
    "hydrojam.materials.swelling": ['SwellingState', 'Transition', 'free_swelling', 'constrained_swelling', 'swelling_curve', 'transition_temperature', 'equilibrium_stretches', 'free_stretches', 'effective_chemical_potential', 'osmotic_modulus', 'free_log_volume'],
    "hydrojam.materials.kinetics": ['DEFAULT_DIFFUSIVITY', 'time_constant', 'mean_log_swelling'],
    "hydrojam.materials.plots": ['plot_swelling_curve'],
}
__all__, __getattr__, __dir__ = lazy_api(__name__, _PUBLIC, globals())
