"""A solve's :class:`~.ipopt.Solution` read back in the named parameters: the
:class:`~bondid.optim.result.FitResult` (values, statistics, active constraints, fitted model)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..consistency.log_cholesky import pi_from_theta
from ..consistency.pseudo_inertia import second_moment_com

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .ipopt import Solution
    from .problem import FitProblem
    from .result import FitResult

_ACTIVE_TOL = 1e-6  # slack (scaled units) below which a bound or inequality counts as active
_SINGULAR = 1e-6  # min/max principal second moment below which a body is on the boundary


def active_constraints(problem: FitProblem, z: np.ndarray) -> list[str]:
    """Readable names of the bounds and constraints active at ``z`` (equalities left out),
    and of the bodies whose pseudo-inertia is on the boundary of the consistent set."""
    active: list[str] = []
    for label, i in problem.var_labels:
        lo, hi = problem.lbz[i], problem.ubz[i]
        if lo == hi:
            continue
        if np.isfinite(lo) and z[i] - lo <= _ACTIVE_TOL * max(1.0, abs(lo)):
            active.append(f"{label} lower bound")
        if np.isfinite(hi) and hi - z[i] <= _ACTIVE_TOL * max(1.0, abs(hi)):
            active.append(f"{label} upper bound")
    cons = problem.constraints()
    g = np.asarray(problem.nlp().g_fn(z), dtype=float).reshape(-1) if cons.size else np.zeros(0)
    for label, lo, hi, gk in zip(cons.labels, cons.lower, cons.upper, g, strict=True):
        name: str | None = None
        if lo == hi:
            continue  # equality (a fixed parameter): always active, not reported
        if label.endswith("com in hull"):
            name = label if hi - gk <= _ACTIVE_TOL else None
        elif np.isfinite(lo) and gk - lo <= _ACTIVE_TOL * max(1.0, abs(lo)):
            name = f"{label} lower bound"
        elif np.isfinite(hi) and hi - gk <= _ACTIVE_TOL * max(1.0, abs(hi)):
            name = f"{label} upper bound"
        if name is not None and name not in active:
            active.append(name)
    for blk in problem.layout.blocks:
        sigma = np.linalg.eigvalsh(second_moment_com(pi_from_theta(blk.theta(z))))
        if sigma[0] <= _SINGULAR * sigma[-1]:
            active.append(f"{blk.link} pseudo-inertia")
    return active


def fit_result(
    problem: FitProblem,
    solution: Solution,
    *,
    initial: np.ndarray,
    cost_initial: float,
    iterations: int,
    wall_s: float,
    notes: Sequence[str] = (),
) -> FitResult:
    """The :class:`FitResult` of ``solution`` (a solve of ``problem``); ``initial``,
    ``cost_initial``, ``iterations`` and ``wall_s`` describe the whole search."""
    from .result import FitResult, parameter_statistics

    z = solution.z
    doc = problem.document(z)
    r, J = problem.named_residual_and_jacobian(z, doc)
    std, corr = parameter_statistics(J, r)
    return FitResult(
        status="failed" if solution.failed else solution.status,
        success=solution.success,
        solver_status=solution.status,
        failure=solution.failure,
        names=list(problem.names),
        initial=np.asarray(initial, dtype=float).copy(),
        fitted=problem.values(z),
        lower=problem.lower.copy(),
        upper=problem.upper.copy(),
        std=std,
        correlation=corr,
        cost_initial=float(cost_initial),
        cost_final=float(r @ r),
        cost_name=problem.options.name,
        iterations=int(iterations),
        wall_s=float(wall_s),
        cost_history=list(solution.history),
        active_constraints=active_constraints(problem, z),
        document=doc,
        notes=list(notes),
        modifiers=_modifiers(problem, z),
        stop_reason=solution.stop_reason,
    )


def _modifiers(problem: FitProblem, z: np.ndarray) -> dict[str, float]:
    """The FRF modifier's parameters at ``z`` by name (empty without a modifier)."""
    mod = problem.frf.modifier
    if mod is None:
        return {}
    return {n: float(v) for n, v in zip(mod.names, problem.theta(z), strict=True)}
