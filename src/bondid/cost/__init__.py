"""Costs: residual kinds and the multi-data-set FRF problem with exact Jacobian."""

from .problem import CostOptions, FrfProblem, ParameterModel, db_rms
from .residuals import NORMS, RESIDUAL_KINDS

__all__ = ["NORMS", "RESIDUAL_KINDS", "CostOptions", "FrfProblem", "ParameterModel", "db_rms"]
