"""The constrained FRF fit: :func:`fit`, :class:`FitResult`, :func:`default_bounds`.

Submodules import numpy-only code at import time; CasADi is imported when a fit is built.
"""

from .bounds import DEFAULT_REL, default_bounds
from .result import FitResult
from .solver import fit, prepare

__all__ = ["DEFAULT_REL", "FitResult", "default_bounds", "fit", "prepare"]
