"""The outcome of a fit (:class:`FitResult`) and the parameter statistics at the solution.

Standard deviations (:func:`parameter_statistics`). The residual of
:class:`bondid.cost.FrfProblem` is ``r = e · √(w / W)`` (``e`` the raw residual of each of the
``N`` real entries, ``w`` its weight, ``W = Σw``), so ``‖r‖²`` is the weighted mean square.
If the raw errors are independent with variances ``σ₀²/w``, the weighted least-squares
estimate has covariance ``σ₀² (J_eᵀ diag(w) J_e)⁻¹`` with ``σ₀² = eᵀdiag(w)e / (N − n)``; in terms
of the scaled ``r`` and its Jacobian ``J`` in the NAMED parameters this is

    cov = s² (JᵀJ)⁻¹,    s² = ‖r‖² / (N − n),

(the factors ``W`` cancel). The inverse is taken through the SVD of the column-normalised ``J``;
singular values below ``rcond`` times the largest define the null space, and a parameter with a
non-negligible component in it is not identifiable: its std and correlations are NaN. The
covariance is that of the linearised, unconstrained problem (a parameter at an active bound is
reported as if the bound were absent).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..jsonsafe import number as _num
from ..model.document import UrdfDocument


def parameter_statistics(
    J: np.ndarray, r: np.ndarray, *, rcond: float = 1e-9, null_tol: float = 1e-6
) -> tuple[np.ndarray, np.ndarray]:
    """Std ``(n,)`` and correlation ``(n, n)`` of parameters from the residual Jacobian.

    Args:
        J: ``(N, n)`` Jacobian of the scaled residual w.r.t. the named parameters (SI units).
        r: ``(N,)`` scaled residual at the solution.
        rcond: relative singular-value cut-off of the column-normalised ``J``.
        null_tol: a parameter whose squared component in the null space exceeds this is NaN.

    Returns:
        ``std`` in the parameters' units (NaN where not identifiable) and the correlation
        matrix (1 on the diagonal of identifiable parameters, NaN in unidentifiable rows).
    """
    N, n = J.shape
    std = np.full(n, np.nan)
    corr = np.full((n, n), np.nan)
    if n == 0:
        return std, corr
    s2 = float(r @ r) / max(N - n, 1)
    norms = np.linalg.norm(J, axis=0)
    live = norms > 0
    if not np.any(live):
        return std, corr
    Js = J[:, live] / norms[live]
    _, sv, Vt = np.linalg.svd(Js, full_matrices=False)
    keep = sv > rcond * sv[0]
    null = Vt[~keep]
    weak = np.sum(null**2, axis=0) > null_tol if null.size else np.zeros(Js.shape[1], bool)
    V = Vt[keep].T
    cov_s = (V / sv[keep] ** 2) @ V.T * s2
    cov = cov_s / np.outer(norms[live], norms[live])
    idx = np.flatnonzero(live)
    ok = idx[~weak]
    sub = cov[np.ix_(~weak, ~weak)]
    sd = np.sqrt(np.clip(np.diag(sub), 0.0, None))
    std[ok] = sd
    with np.errstate(invalid="ignore", divide="ignore"):
        corr[np.ix_(ok, ok)] = sub / np.outer(sd, sd)
    corr[ok, ok] = 1.0
    return std, corr


def conditional_std(std: np.ndarray, corr: np.ndarray, i: int, given: Sequence[int]) -> float:
    """Std of parameter ``i`` with the parameters ``given`` held at their values (the others
    free), from the marginal ``std`` ``(n,)`` and ``corr`` ``(n, n)`` of
    :func:`parameter_statistics`: ``√(Σᵢᵢ − Σᵢ_G Σ_GG⁺ Σ_Gᵢ)`` (the Gaussian conditional, a
    pseudo-inverse where the given ones are collinear); never above the marginal std."""
    s_i = float(std[i])
    g = [int(j) for j in given if int(j) != i]
    if not g or not math.isfinite(s_i):
        return s_i
    sg = np.asarray(std, float)[g]
    c_ig = np.asarray(corr, float)[i, g] * s_i * sg
    c_gg = np.asarray(corr, float)[np.ix_(g, g)] * np.outer(sg, sg)
    if not (np.all(np.isfinite(c_ig)) and np.all(np.isfinite(c_gg))):
        return s_i
    var = s_i**2 - float(c_ig @ np.linalg.pinv(c_gg, rcond=1e-10, hermitian=True) @ c_ig)
    return math.sqrt(min(max(var, 0.0), s_i**2))


@dataclass
class FitResult:
    """Outcome of :func:`bondid.fit.fit` (arrays are ``(n,)`` in the named parameters' SI units).

    Attributes:
        status: IPOPT's ``return_status`` (e.g. ``"Solve_Succeeded"``), or
            ``"Converged_Stalled"`` when the stall test stopped the last solve
            (:mod:`bondid.optim.stall`; ``stop_reason`` says why), or ``"failed"``.
        success: True when the fit converged (``Solve_Succeeded``,
            ``Solved_To_Acceptable_Level`` or ``Converged_Stalled``).
        names: the free named parameters (URDF form).
        initial, fitted, lower, upper, std: per parameter; ``std`` NaN where not identifiable.
            ``initial`` is the search's start; ``bondid.fit`` reports the model's values
            there and the kept search's start, when it differs, in ``start``.
        correlation: ``(n, n)``.
        cost_initial, cost_final: the cost (``cost_name``) at the (projected) start and at the
            solution; ``cost_history``: the cost at every IPOPT iteration.
        iterations, wall_s: IPOPT iterations and wall time of the whole fit (s).
        active_constraints: readable names of the constraints active at the solution.
        document: the fitted model (a copy; the input is untouched).
        notes: remarks (start projected into the feasible set, bounds widened, ...).
    """

    status: str
    success: bool
    names: list[str]
    initial: np.ndarray
    fitted: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    std: np.ndarray
    correlation: np.ndarray
    cost_initial: float
    cost_final: float
    cost_name: str
    iterations: int
    wall_s: float
    cost_history: list[float]
    active_constraints: list[str]
    document: UrdfDocument
    notes: list[str] = field(default_factory=list)
    #: IPOPT's own return status (``status`` is ``"failed"`` when IPOPT failed outright)
    solver_status: str | None = None
    #: why the fit failed (None when it did not); ``fitted`` is then the best point reached
    failure: str | None = None
    #: fitted FRF-modifier parameters by name (a fit with a :class:`bondid.cost.modifier.
    #: FrfModifier`, e.g. a diagnosis candidate's delay); empty otherwise
    modifiers: dict[str, float] = field(default_factory=dict)
    #: why the last solve stopped when the stall test stopped it (``status`` is then
    #: ``"Converged_Stalled"``); None otherwise
    stop_reason: str | None = None
    #: the kept search's start ``(n,)`` and its cost when it is not ``initial`` (a fallback
    #: start of a multistart); None otherwise
    start: np.ndarray | None = None
    cost_start: float | None = None

    def parameter(self, name: str) -> float:
        """Fitted value of ``name``."""
        return float(self.fitted[self.names.index(name)])

    def to_json_dict(self) -> dict[str, Any]:
        """The spec's ``fit.json`` content (NaN and ±inf become ``null``)."""
        return {
            "status": self.status,
            "success": self.success,
            "cost_initial": _num(self.cost_initial),
            "cost_final": _num(self.cost_final),
            "cost_name": self.cost_name,
            "iterations": int(self.iterations),
            "wall_s": float(self.wall_s),
            "parameters": [
                {
                    "name": n,
                    "initial": _num(self.initial[i]),
                    "fitted": _num(self.fitted[i]),
                    "lower": _num(self.lower[i]),
                    "upper": _num(self.upper[i]),
                    "std": _num(self.std[i]),
                    **({} if self.start is None else {"start": _num(self.start[i])}),
                }
                for i, n in enumerate(self.names)
            ],
            "correlation": [[_num(v) for v in row] for row in self.correlation],
            "active_constraints": list(self.active_constraints),
            "cost_history": [_num(c) for c in self.cost_history],
            "notes": list(self.notes),
            "solver_status": self.solver_status or self.status,
            "failure": self.failure,
            "stop_reason": self.stop_reason,
            **({} if self.cost_start is None else {"cost_start": _num(self.cost_start)}),
            **({"modifiers": dict(self.modifiers)} if self.modifiers else {}),
        }
