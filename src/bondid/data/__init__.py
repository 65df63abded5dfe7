"""Measured FRF data: the :class:`FrfData` container, CSV and UFF 58 files, synthetic noise.

``pyuff`` is imported only when a UFF file is read or written.
"""

from __future__ import annotations

from .csv_format import read_csv, write_csv
from .io import check_against_model, read_frf, write_frf
from .measurement import FrfData
from .noise import add_measurement_noise
from .uff_format import default_channel_map, read_uff58, write_uff58

__all__ = [
    "FrfData",
    "add_measurement_noise",
    "check_against_model",
    "default_channel_map",
    "read_csv",
    "read_frf",
    "read_uff58",
    "write_csv",
    "write_frf",
    "write_uff58",
]
