"""Linearisation with Pinocchio: the linear model and its affine parameter structure."""

from .affine import AffineModel, build_affine_model, linearise, pi_from_inertial
from .linear_model import LinearModel
from .operating_point import configuration, parse_operating_point

__all__ = [
    "AffineModel",
    "LinearModel",
    "build_affine_model",
    "configuration",
    "linearise",
    "parse_operating_point",
    "pi_from_inertial",
]
