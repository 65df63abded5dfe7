"""Sensitivity and identifiability: which parameters the data can determine, band by band.

* :mod:`.sweep` — the one-at-a-time sweep (each parameter alone over 50..150 %).
* :mod:`.local` — derivative-based sensitivities per frequency band, channel and direction
  from one exact Jacobian, with automatic bands from the model's modes (:mod:`bondid.modes.bands`).
* :mod:`.identifiability` — singular values (Fisher information), pinned-down combinations
  and the recommended subset to free (:func:`recommend_subset`, used by ``--free auto``).

Command line: ``python -m bondid.sensitivity --model URDF --data FILE...``.
"""

from ..modes.bands import Band, Feature, automatic_bands, model_features
from ._common import Setup, make_setup, reference_scales
from .identifiability import (
    Identifiability,
    analyse_identifiability,
    estimate_noise,
    identifiability,
    recommend_subset,
)
from .local import LocalSensitivity, analyse_local, linearise_cost, local_sensitivity
from .sweep import SweepResult, default_scales, run_sweep, sensitivity_sweep

__all__ = [
    "Band",
    "Feature",
    "Identifiability",
    "LocalSensitivity",
    "Setup",
    "SweepResult",
    "analyse_identifiability",
    "analyse_local",
    "automatic_bands",
    "default_scales",
    "estimate_noise",
    "identifiability",
    "linearise_cost",
    "local_sensitivity",
    "make_setup",
    "model_features",
    "recommend_subset",
    "reference_scales",
    "run_sweep",
    "sensitivity_sweep",
]
