"""The decision vector's movable entries as a parameter model: :class:`FreeColumns`.

Every fitted body has ten entries in the decision vector ``z`` (:mod:`.layout`), and those
the fit holds (a CoM that is not free, a mass that is not free, the inertia of a body whose
inertia is held) are fixed variables: bounds with ``lower == upper``, which IPOPT removes
from its problem. Their Jacobian columns are never used, yet cost as much as the others: on
a chain whose segments free only a mass and one inertia, a third or more of the columns.
:class:`FreeColumns` presents the same model with only the movable columns, so the FRF
derivatives are formed for those alone; the evaluator writes zeros in the fixed columns (the
derivative along a variable that cannot move).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..cost.problem import ParameterModel


def movable(lower: np.ndarray, upper: np.ndarray) -> np.ndarray | None:
    """Indices of the entries ``lower < upper`` (both ``(size,)``), or None when all are."""
    free = np.flatnonzero(~(np.asarray(lower) == np.asarray(upper)))
    return None if free.size == np.asarray(lower).size else free


def _columns(value: Any, free: np.ndarray) -> Any:
    """``value`` with its last axis (the decision vector's) reduced to ``free``; a dict of
    such arrays entry by entry."""
    if isinstance(value, dict):
        return {k: np.asarray(v)[..., free] for k, v in value.items()}
    return np.asarray(value)[..., free]


class FreeColumns:
    """``pmodel`` with the derivatives along the entries ``free`` only (module docstring).

    The values are taken at the whole decision vector ``z`` ``(pmodel.size,)``; every
    ``*_jacobian`` method returns its arrays with the last axis reduced to ``free``
    ``(n_free,)``. The optional parts of the protocol (gains, mixes, Rayleigh coefficients,
    a modifier) exist exactly when ``pmodel`` has them.
    """

    def __init__(self, pmodel: ParameterModel, free: np.ndarray):
        self.pmodel = pmodel
        self.free = np.asarray(free, dtype=int)

    @property
    def size(self) -> int:
        return int(self.free.size)

    def values(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.pmodel.values(z)

    def jacobian(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dpi, dk, dd = self.pmodel.jacobian(z)
        f = self.free
        return dpi[:, :, f], dk[:, f], dd[:, f]

    def __getattr__(self, name: str) -> Any:
        if name in ("pmodel", "free"):  # not set yet (a copy being built)
            raise AttributeError(name)
        attr = getattr(self.pmodel, name)  # AttributeError when the model has no such part
        if not name.endswith("_jacobian") or not callable(attr):
            return attr
        fn: Callable[..., Any] = attr
        return lambda *a, **k: _columns(fn(*a, **k), self.free)
