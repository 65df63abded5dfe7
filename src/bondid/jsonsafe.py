"""JSON-safe numbers: what bondid writes into (and reads back from) its JSON results.

JSON has no NaN or infinity and knows nothing of NumPy, so every result goes through
:func:`json_safe` before ``json.dump``, and every number read from a result file goes
through :func:`number` before arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import PurePath
from typing import Any

import numpy as np


def number(value: Any, *, finite: bool = True) -> float | None:
    """``value`` as a float when it is a real number, else None.

    Real numbers are ``int``, ``float`` and NumPy integer/floating scalars; ``bool`` (and
    ``numpy.bool_``) are not numbers here. With ``finite=True`` NaN and ±inf also give None
    (they are not valid JSON); ``finite=False`` keeps them (a report shows an infinite bound
    as ∞).
    """
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        return None
    v = float(value)
    if finite and not math.isfinite(v):
        return None
    return v


def json_safe(value: Any) -> Any:
    """``value`` with every part made valid for ``json.dump``, structure kept.

    Arrays (any shape) and tuples become (nested) lists, mappings become dicts with their
    keys as strings, paths become strings, floats (Python or NumPy) that are NaN or ±inf
    become None, NumPy integers become ``int`` and ``numpy.bool_`` becomes ``bool``;
    everything else (str, int, bool, None, ...) is returned as it is.
    """
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, float | np.floating):
        return number(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, PurePath):
        return str(value)
    return value
