"""Checks of a fit's setting values, shared by the study file (:mod:`.study`) and the command
line (:mod:`.options`): each takes the value, where it comes from (the file or option) and its
key, and returns the value in its checked form or raises
:class:`~bondid.exceptions.ConfigError` naming the place, the key and what is valid."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..exceptions import ConfigError

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..modes.bands import Span as Band


def config_error(where: str, key: str, msg: str) -> ConfigError:
    """The error of a bad setting: ``WHERE: KEY: MSG``."""
    return ConfigError(f"{where}: {key}: {msg}")


def check_band(value: Any, where: str, key: str) -> Band:
    """A band ``[f_lo, f_hi]`` in Hz with ``0 <= f_lo < f_hi``."""
    ok = (
        isinstance(value, list | tuple)
        and len(value) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    )
    if ok:
        lo, hi = float(value[0]), float(value[1])
        if math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi:
            return lo, hi
    raise config_error(
        where, key, f"{value!r} is not a band [F_LO, F_HI] in Hz with 0 <= F_LO < F_HI"
    )


def check_bands(value: Any, where: str, key: str) -> list[Band]:
    """A non-empty list of bands (Hz), or one band written flat ``[f_lo, f_hi]``."""
    if not isinstance(value, list) or not value:
        raise config_error(where, key, f"{value!r} is not a non-empty list of [F_LO, F_HI] bands")
    # a single band written flat: [1, 100]
    if len(value) == 2 and all(isinstance(v, int | float) for v in value):
        return [check_band(value, where, key)]
    return [check_band(v, where, f"{key}[{i}]") for i, v in enumerate(value)]


def check_choice(value: Any, valid: tuple[str, ...], where: str, key: str) -> str:
    """One of the strings ``valid``."""
    if not isinstance(value, str) or value not in valid:
        raise config_error(where, key, f"{value!r} is not valid; valid: {', '.join(valid)}")
    return value


def check_int(value: Any, where: str, key: str, minimum: int) -> int:
    """An integer (not a bool) ``>= minimum``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise config_error(where, key, f"{value!r} is not an integer >= {minimum}")
    return int(value)


def check_bool(value: Any, where: str, key: str) -> bool:
    """``true`` or ``false``."""
    if not isinstance(value, bool):
        raise config_error(where, key, f"{value!r} is not true or false")
    return value


def check_names(value: Any, where: str, key: str) -> list[str]:
    """A string (comma/space separated) or a list of strings -> list of tokens."""
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list) or not all(isinstance(v, str) for v in items):
        raise config_error(where, key, f"{value!r} is not a string or a list of strings")
    out: list[str] = []
    for v in items:
        out += [t for t in v.replace(",", " ").split() if t]
    return out


def check_bound(value: Any, where: str, key: str) -> float | tuple[float, float]:
    """A relative fraction (> 0) or an absolute pair ``[lo, hi]`` (lo < hi)."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        v = float(value)
        if math.isfinite(v) and v > 0:
            return v
    elif (
        isinstance(value, list | tuple)
        and len(value) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    ):
        lo, hi = float(value[0]), float(value[1])
        if not (math.isnan(lo) or math.isnan(hi)) and lo < hi:
            return lo, hi
    raise config_error(
        where,
        key,
        f"{value!r} is not a bound; valid: a relative fraction > 0 (0.2 = ±20 %) or an"
        " absolute pair [LO, HI] with LO < HI",
    )


def parse_bound_option(text: str) -> tuple[str, float | tuple[float, float]]:
    """``KEY=FRACTION`` or ``KEY=LO:HI`` (the ``--bound`` option) -> (key, bound)."""
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError(f"--bound {text!r}: not KEY=FRACTION or KEY=LO:HI")
    try:
        parts = [float(v) for v in value.split(":")]
    except ValueError:
        raise ConfigError(f"--bound {text!r}: {value!r} is not FRACTION or LO:HI") from None
    if len(parts) not in (1, 2):
        raise ConfigError(f"--bound {text!r}: {value!r} is not FRACTION or LO:HI")
    return key, check_bound(parts[0] if len(parts) == 1 else parts, "--bound", key)


def check_table(value: Any, where: str, key: str) -> Mapping[str, Any]:
    """A TOML table (a mapping)."""
    if not isinstance(value, dict):
        raise config_error(where, key, f"expected a table ([{key}]), got {type(value).__name__}")
    return value


def check_keys(table: Mapping[str, Any], valid: tuple[str, ...], where: str, prefix: str) -> None:
    """Every key of ``table`` is one of ``valid`` (``prefix``: the table's name)."""
    for k in table:
        if k not in valid:
            name = f"{prefix}.{k}" if prefix else k
            raise config_error(where, name, f"unknown key; valid: {', '.join(valid)}")


def check_path(value: Any, base: Path, where: str, key: str) -> Path:
    """A non-empty path string; a relative one is taken relative to ``base``."""
    if not isinstance(value, str) or not value:
        raise config_error(where, key, f"{value!r} is not a file path")
    p = Path(value)
    return p if p.is_absolute() else base / p
