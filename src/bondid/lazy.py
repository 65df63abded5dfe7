"""Lazy public names for packages whose submodules load heavy dependencies."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_getattr(package: str, where: Mapping[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` that imports ``package.<where[name]>`` on first access.

    Args:
        package: the package's ``__name__``.
        where: public name → submodule that defines it, relative to the package
            (``"solver"``, or ``"..optim.result"`` for a module of a sibling package).
    """

    def __getattr__(name: str) -> Any:
        if name in where:
            module = where[name]
            module = module if module.startswith(".") else f".{module}"
            return getattr(importlib.import_module(module, package), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
