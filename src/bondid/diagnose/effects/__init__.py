"""The library of candidate effects (one file per effect) and its registry.

:func:`register` adds an :class:`~.base.Effect` subclass under its ``name``;
:func:`available` lists them (spec order first); :func:`get_effects` resolves a user's
``--effects`` choice. The built-in effects are imported on first use of the registry.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

from ...exceptions import ConfigError
from .base import Candidate, Effect, NewParameter

_REGISTRY: dict[str, type[Effect]] = {}
_BUILTIN = (
    "joint_compliance", "flexible_base", "soft_mounts", "sensor_delay", "actuator_lag",
    "sensor_dynamics", "sensor_misalignment", "drive_spring", "flexible_link", "transducer_gain",
    "actuator_crosstalk",
)  # fmt: skip

E = TypeVar("E", bound=type[Effect])


def register(cls: E) -> E:
    """Class decorator: make an effect available under ``cls.name``."""
    if not cls.name:
        raise ConfigError(f"effect class {cls.__name__} has no name")
    _REGISTRY[cls.name] = cls
    return cls


def _load_builtin() -> None:
    import importlib

    for mod in _BUILTIN:
        importlib.import_module(f"{__name__}.{mod}")


def available() -> dict[str, type[Effect]]:
    """Effect name → class, built-in effects first (spec order)."""
    _load_builtin()
    order = [n for n in _BUILTIN if n in _REGISTRY] + sorted(set(_REGISTRY) - set(_BUILTIN))
    return {n: _REGISTRY[n] for n in order}


def get_effects(names: Sequence[str] | None = None) -> list[Effect]:
    """Instances of the chosen effects (default: all). Raises ConfigError on unknown names."""
    reg = available()
    if not names:
        return [cls() for cls in reg.values()]
    unknown = [n for n in names if n not in reg]
    if unknown:
        raise ConfigError(
            f"--effects: unknown effect(s) {', '.join(unknown)}; valid: {', '.join(reg)}"
        )
    return [reg[n]() for n in dict.fromkeys(names)]


def get_effect(name: str) -> Effect:
    return get_effects([name])[0]


__all__ = [
    "Candidate",
    "Effect",
    "NewParameter",
    "available",
    "get_effect",
    "get_effects",
    "register",
]
