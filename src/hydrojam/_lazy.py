"""A package's public API loaded on first use (PEP 562): a subpackage's ``__init__`` names its
public names by module, and importing the package imports none of those modules (so that
``import hydrojam.fem`` starts neither gmsh nor ipctk)."""

from __future__ import annotations

import importlib
from collections.abc import Callable


def lazy_api(package: str, public: dict[str, list[str]],
             namespace: dict) -> tuple[list[str], Callable[[str], object], Callable[[], list[str]]]:
    """``(__all__, __getattr__, __dir__)`` for the package named ``package`` whose public names
    are ``public`` (module -> names) and whose module globals are ``namespace``: a name is
    imported from its module when first read, then kept in ``namespace``."""
    module_of = {name: module for module, names in public.items() for name in names}
    names = [name for group in public.values() for name in group]

    def __getattr__(name: str):
        if name in module_of:
            value = getattr(importlib.import_module(module_of[name]), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names))

    return names, __getattr__, __dir__
