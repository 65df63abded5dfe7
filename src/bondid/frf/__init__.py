"""FRF computation: the engine, and the receptance/mobility/accelerance conversions of
:mod:`bondid.data.quantity` handed on."""

from ..data.quantity import QUANTITIES, convert_quantity, quantity_factor
from .engine import dynamic_stiffness, frf, omega, solve_columns

__all__ = [
    "QUANTITIES",
    "convert_quantity",
    "dynamic_stiffness",
    "frf",
    "omega",
    "quantity_factor",
    "solve_columns",
]
