"""FRF computation: the engine and the receptance/mobility/accelerance conversions."""

from .engine import dynamic_stiffness, frf, omega, solve_columns
from .quantity import QUANTITIES, convert_quantity, quantity_factor

__all__ = [
    "QUANTITIES",
    "convert_quantity",
    "dynamic_stiffness",
    "frf",
    "omega",
    "quantity_factor",
    "solve_columns",
]
