"""The per-band sensitivities' bands: kept here as names of :mod:`bondid.modes.bands`, which
holds the one implementation (modes and frequency bands for fit, sensitivity and diagnosis)."""

from ..modes.bands import (
    BAND_CLASSES,
    Band,
    Feature,
    automatic_bands,
    band_masks,
    classify_bands,
    model_features,
)

__all__ = [
    "BAND_CLASSES",
    "Band",
    "Feature",
    "automatic_bands",
    "band_masks",
    "classify_bands",
    "model_features",
]
