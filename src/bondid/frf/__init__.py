"""FRF computation: the engine of :mod:`bondid.linear.response`, the receptance/mobility/accelerance
conversions of :mod:`bondid.data.quantity` and the derivatives (:mod:`.jacobian`) handed on."""

from ..data.quantity import QUANTITIES, convert_quantity, quantity_factor
from ..linear.response import dynamic_stiffness, frf, omega, solve_columns

__all__ = [
    "QUANTITIES",
    "convert_quantity",
    "dynamic_stiffness",
    "frf",
    "omega",
    "quantity_factor",
    "solve_columns",
]
