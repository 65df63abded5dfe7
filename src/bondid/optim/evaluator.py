"""Residual, cost, gradient and Gauss–Newton matrix of a fit problem over its decision vector.

:class:`Evaluator` caches the last ``(z, r, J)`` so that the cost, the gradient and the
Hessian IPOPT asks for at the same ``z`` cost one Jacobian evaluation; evaluation failures
(singular matrices, non-finite numbers) become NaN residuals, which IPOPT treats as an invalid
trial point.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from ..cost.problem import FrfProblem, ParameterModel
from ..exceptions import ComputationError
from .free_columns import FreeColumns


class ExtraRows(Protocol):
    """Residual rows appended to the data's (e.g. a prior): ``size`` rows, evaluated as
    ``rows(z) -> (r (size,), ∂r/∂z (size, n))``."""

    @property
    def size(self) -> int: ...

    def __call__(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


class Evaluator:
    """Residual, cost, gradient and Gauss–Newton matrix of ``problem`` over ``pmodel``'s ``z``.

    Two caches: the last point with a Jacobian and the last residual-only point (IPOPT's
    line-search trial points), so trial evaluations do not evict the Jacobian.

    ``gauss_newton`` returns the Levenberg–Marquardt-damped matrix ``2 (JᵀJ + λ D)`` with
    ``D = diag(JᵀJ) + ε·max diag(JᵀJ)`` (``λ = 0`` with ``damping=False``). ``λ`` adapts to how
    well the Gauss–Newton model predicted the cost change over the last step (ratio ρ of actual
    to predicted decrease: ``λ /= 3`` when ρ > 0.75, ``λ *= 2`` when ρ < 0.25, ``λ = 0`` once
    below ``1e-12``): far from the solution the steps are shorter and better conditioned (the
    data leave some directions unidentifiable), near it the damping vanishes and the local
    convergence of Gauss–Newton is kept. Only the step direction changes, not the optimum.
    """

    def __init__(
        self,
        problem: FrfProblem,
        pmodel: ParameterModel,
        *,
        damping: bool = True,
        prior: ExtraRows | None = None,
        free: np.ndarray | None = None,
    ):
        """``free``: indices of the entries of ``z`` that can move (None: all)."""
        self.problem = problem
        self.pmodel = pmodel
        #: extra residual rows ``z -> (r (m,), J (m, n))`` appended to the data's (e.g. a
        #: prior toward the model's values); None = none
        self.prior = prior
        n = pmodel.size
        #: the entries of ``z`` that can move (all, unless ``free`` is given): Jacobians are
        #: formed and kept along those alone (:mod:`.free_columns`); the columns of the
        #: others are 0 wherever a whole Jacobian is returned
        self.cols = np.arange(n) if free is None else np.asarray(free, dtype=int)
        self._data_model: ParameterModel = (
            pmodel if self.cols.size == n else FreeColumns(pmodel, self.cols)
        )
        self._jac: tuple[bytes, np.ndarray, np.ndarray] | None = None  # z, r, J (movable)
        self._res: tuple[bytes, np.ndarray] | None = None
        self.n_residual = 0
        self.n_jacobian = 0
        self.damping = damping
        self.lam = 1e-3 if damping else 0.0
        self._prev: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # z, r, J (movable)

    def reset(self) -> None:
        """Forget the damping history (the start of a new solve)."""
        self.lam = 1e-3 if self.damping else 0.0
        self._prev = None

    def _fail(self) -> tuple[np.ndarray, np.ndarray]:
        extra = 0 if self.prior is None else int(self.prior.size)
        r = np.full(self.problem.n_residuals + extra, np.nan)
        return r, np.full((r.size, self.cols.size), np.nan)

    def residual(self, z: np.ndarray) -> np.ndarray:
        z = np.ascontiguousarray(z, dtype=float).reshape(-1)
        key = z.tobytes()
        if self._jac is not None and self._jac[0] == key:
            return self._jac[1]
        if self._res is not None and self._res[0] == key:
            return self._res[1]
        try:
            with np.errstate(all="ignore"):
                r = self.problem.residual(self.pmodel, z)
                if self.prior is not None:
                    r = np.concatenate([r, self.prior(z)[0]])
        except (np.linalg.LinAlgError, FloatingPointError, ValueError, ComputationError):
            r = self._fail()[0]
        self.n_residual += 1
        self._res = (key, r)
        return r

    def movable_jacobian(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``(n_r,)`` and their Jacobian along the movable entries ``(n_r,
        cols.size)`` (:attr:`cols`) at ``z`` ``(n,)``."""
        z = np.ascontiguousarray(z, dtype=float).reshape(-1)
        key = z.tobytes()
        if self._jac is not None and self._jac[0] == key:
            return self._jac[1], self._jac[2]
        try:
            with np.errstate(all="ignore"):
                r, J = self.problem.residual_and_jacobian(self._data_model, z)
                if self.prior is not None:
                    rp, Jp = self.prior(z)
                    r, J = np.concatenate([r, rp]), np.vstack([J, Jp[:, self.cols]])
        except (np.linalg.LinAlgError, FloatingPointError, ValueError, ComputationError):
            r, J = self._fail()
        self.n_jacobian += 1
        self._jac = (key, r, J)
        return r, J

    def residual_and_jacobian(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``(n_r,)`` and the whole Jacobian ``(n_r, n)`` at ``z`` (0 in the
        columns of entries that cannot move)."""
        r, Jm = self.movable_jacobian(z)
        if self.cols.size == self.pmodel.size:
            return r, Jm
        J = np.zeros((r.size, self.pmodel.size))
        J[:, self.cols] = Jm
        return r, J

    def cost(self, z: np.ndarray) -> float:
        r = self.residual(z)
        return float(r @ r)

    def cost_and_gradient(self, z: np.ndarray) -> tuple[float, np.ndarray]:
        r, J = self.movable_jacobian(z)
        g = np.zeros(self.pmodel.size)
        g[self.cols] = 2.0 * (J.T @ r)
        return float(r @ r), g

    def _update_damping(self, z: np.ndarray, r: np.ndarray) -> None:
        prev = self._prev
        if prev is None or np.array_equal(prev[0], z):
            return
        z0, r0, J0 = prev
        Js = J0 @ (z - z0)[self.cols]
        predicted = -(2.0 * float(r0 @ Js) + float(Js @ Js))
        actual = float(r0 @ r0) - float(r @ r)
        rho = actual / predicted if predicted > 0 else -1.0
        if rho > 0.75:
            self.lam = self.lam / 3.0 if self.lam > 1e-12 else 0.0
        elif rho < 0.25:
            self.lam = min(max(2.0 * self.lam, 1e-6), 1e6)

    def gauss_newton(self, z: np.ndarray) -> np.ndarray:
        """``2 (JᵀJ + λ D)`` ``(n, n)`` at ``z`` (see the class docstring; 0 in the rows and
        columns of entries that cannot move)."""
        z = np.ascontiguousarray(z, dtype=float).reshape(-1)
        r, J = self.movable_jacobian(z)
        Hm = J.T @ J
        if self.damping and np.all(np.isfinite(r)):
            self._update_damping(z, r)
            self._prev = (z.copy(), r, J)
            if self.lam > 0:
                d = np.diag(Hm).copy()
                Hm = Hm + self.lam * np.diag(d + 1e-9 * max(float(d.max()), 1e-300))
        if self.cols.size == self.pmodel.size:
            return 2.0 * Hm
        H = np.zeros((self.pmodel.size, self.pmodel.size))
        H[np.ix_(self.cols, self.cols)] = 2.0 * Hm
        return H
