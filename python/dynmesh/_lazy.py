"""A package's names loaded on first use (PEP 562), so that importing the package costs only
what is used: ``python -m dynmesh decode`` must not import numpy."""

from __future__ import annotations

import importlib
from collections.abc import Callable


def lazy_names(package: str, homes: dict[str, str], namespace: dict, *,
               submodules: bool = False) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for the package ``package`` whose globals are ``namespace``:
    a name in ``homes`` comes from the submodule ``homes[name]`` when first asked for, and is
    kept. With ``submodules`` any other name is tried as a submodule (``dynmesh.api`` without
    importing it first); without, the import system looks for one itself."""

    def __getattr__(name: str):
        home = homes.get(name)
        if home is not None:
            value = getattr(importlib.import_module(f".{home}", package), name)
            namespace[name] = value
            return value
        if submodules:
            try:
                return importlib.import_module(f".{name}", package)
            except ModuleNotFoundError as e:
                if e.name != f"{package}.{name}":
                    raise
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(homes))

    return __getattr__, __dir__
