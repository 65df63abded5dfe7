"""The constrained FRF fit: :func:`fit`, :class:`FitResult`, :func:`default_bounds`.

The public names are imported lazily, so ``python -m bondid.fit`` can choose the BLAS
threading (:mod:`bondid.blas`) before NumPy loads; CasADi is imported when a fit is built.
The optimisation itself lives in :mod:`bondid.optim` (problem, IPOPT, search schedules).
"""

from __future__ import annotations

from ..lazy import lazy_getattr

_LAZY = {
    "DEFAULT_REL": "..optim.bounds",
    "default_bounds": "..optim.bounds",
    "FitResult": "..optim.result",
    "fit": "solver",
}

__all__ = sorted(_LAZY)

__getattr__ = lazy_getattr(__name__, _LAZY)
