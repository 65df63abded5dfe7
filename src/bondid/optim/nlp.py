"""The fit problem as the CasADi functions IPOPT is given: :class:`Nlp`.

The FRF residual ``r(z)`` is computed in numpy (exact Jacobian ``J = ∂r/∂z``, see
:class:`~.evaluator.Evaluator`) and enters CasADi through :class:`casadi.Callback` objects:

* objective ``f(z) = ‖r‖²`` (residual only, no Jacobian: IPOPT's line-search trial points),
* ``grad_f``: ``(f, 2 Jᵀ r)``,
* ``hess_lag``: the Gauss–Newton Hessian of the Lagrangian ``λ_f · 2 JᵀJ + Σ λ_g,i ∇² g_i``
  (objective part Levenberg–Marquardt damped far from the solution, see
  :class:`~.evaluator.Evaluator`; constraint part from CasADi's symbolic Hessians, by default
  CONVEXIFIED: the exact ``Σ λ ∇² g`` of the inertia equalities is indefinite, which made
  IPOPT regularise the whole Hessian by ``δ ≈ 1…100`` every iteration and crawl).
  Limited-memory quasi-Newton needs hundreds of iterations on this problem; Gauss–Newton tens.

CasADi is imported when an :class:`Nlp` is built, not with this module.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ..exceptions import ConfigError
from .casadi_callbacks import iteration_callback_class, numpy_callback_class
from .constraints import Constraints
from .stall import gauss_newton_decrement

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .evaluator import Evaluator

#: ways of putting the constraints' second derivatives into ``hess_lag``
CONSTRAINT_HESSIANS = ("convexified", "exact", "none")


class Nlp:
    """``min ‖r(z)‖²`` s.t. ``lbz ≤ z ≤ ubz``, ``lbg ≤ g(z) ≤ ubg`` as CasADi functions.

    Args:
        evaluator: residuals and Jacobian (numpy).
        constraints: the symbolic constraints ``g(z)`` with their bounds and labels.
        constraint_hessian: ``"convexified"`` (default), ``"exact"`` or ``"none"``: how
            ``Σ λ_g ∇² g`` enters ``hess_lag``.

    Attributes:
        cost_fn: CasADi ``z -> f`` (the NLP's objective).
        grad_fn: CasADi ``(z, p) -> (f, ∇f)`` (IPOPT's ``grad_f``; ``p`` is empty).
        hess_fn: CasADi ``(z, p, λ_f, λ_g) -> triu(∇²L)`` (IPOPT's ``hess_lag``).
        g_fn: CasADi ``z -> g``.
    """

    def __init__(
        self,
        evaluator: Evaluator,
        constraints: Constraints,
        constraint_hessian: str = "convexified",
    ):
        import casadi

        if constraint_hessian not in CONSTRAINT_HESSIANS:
            raise ConfigError(
                f"constraint_hessian {constraint_hessian!r} is invalid; "
                f"valid: {', '.join(CONSTRAINT_HESSIANS)}"
            )
        NumpyCallback = numpy_callback_class()
        self.evaluator, self.constraints = evaluator, constraints
        self.n = n = int(constraints.zsym.shape[0])
        self.ng = ng = constraints.size
        self.g_fn = casadi.Function("fit_g", [constraints.zsym], [constraints.expr])
        self._jac_g: Any = None  # the constraints' Jacobian, built when the stall test asks
        self._grad_cb = NumpyCallback(
            "fit_grad", [n], [(1, 1), (n, 1)], lambda z: list(evaluator.cost_and_gradient(z))
        )
        # the objective's Jacobian (needed by CasADi's own derivative machinery) is grad_f
        self._cost_cb = NumpyCallback(
            "fit_cost", [n], [(1, 1)], lambda z: [evaluator.cost(z)],
            jacobian=lambda z: self._grad_cb(z)[1].T,
        )  # fmt: skip
        hess_g = _constraint_hessian(constraints, constraint_hessian)
        self._hess_cb = NumpyCallback(
            "fit_hess_lag", [n, 1, ng], [(n, n)],
            lambda z, lf, lg: [float(lf[0]) * evaluator.gauss_newton(z) + hess_g(z, lg)],
        )  # fmt: skip
        self._x = x = casadi.MX.sym("x", n)
        self._p = p = casadi.MX.sym("p", 0, 1)
        lam_f, lam_g = casadi.MX.sym("lam_f", 1), casadi.MX.sym("lam_g", ng)
        self.cost_fn = casadi.Function("fit_f", [x], [self._cost_cb(x)])
        f_val, g_val = self._grad_cb(x)
        self.grad_fn = casadi.Function(
            "nlp_grad_f", [x, p], [f_val, g_val], ["x", "p"], ["f", "grad"]
        )
        self.hess_fn = casadi.Function(
            "nlp_hess_l", [x, p, lam_f, lam_g], [casadi.triu(self._hess_cb(x, lam_f, lam_g))],
            ["x", "p", "lam_f", "lam_g"], ["hess"],
        )  # fmt: skip

    def gradient(self, z: np.ndarray) -> np.ndarray:
        """∇f ``(n,)`` at ``z`` through the CasADi ``grad_f`` function IPOPT uses."""
        import casadi

        return np.asarray(self.grad_fn(z, casadi.DM(0, 1))[1], dtype=float).reshape(-1)

    def cost(self, z: np.ndarray) -> float:
        """f at ``z`` through the CasADi objective function IPOPT uses."""
        return float(self.cost_fn(z))

    def decrement(self, z: np.ndarray, lam_x: np.ndarray, lam_g: np.ndarray) -> float:
        """The Gauss–Newton decrement at ``z`` of the Lagrangian's gradient
        ``∇f + J_gᵀ λ_g + λ_x`` (CasADi's multiplier signs; :func:`.stall.
        gauss_newton_decrement`); the residual Jacobian comes from the evaluator's cache
        when IPOPT has just evaluated it there."""
        import casadi

        r, J = self.evaluator.movable_jacobian(z)
        if not np.all(np.isfinite(r)):
            return float("inf")
        # entries that cannot move (fixed variables) take no Gauss–Newton step: the
        # decrement is taken over the movable ones alone
        cols = self.evaluator.cols
        grad = 2.0 * (J.T @ r) + lam_x[cols]
        if self.ng:
            if self._jac_g is None:
                zs = self.constraints.zsym
                self._jac_g = casadi.Function(
                    "fit_jac_g", [zs], [casadi.jacobian(self.constraints.expr, zs)]
                )
            grad = grad + (np.asarray(self._jac_g(z), dtype=float).T @ lam_g)[cols]
        return gauss_newton_decrement(J, grad)

    def solver(self, record: Callable[..., bool], ipopt: dict) -> tuple[Any, Any]:
        """A ``casadi.nlpsol`` IPOPT instance calling ``record(f, z, g, lam_x, lam_g)`` every
        iteration (True stops it), and its iteration callback (which must outlive the
        solver's calls)."""
        import casadi

        it_cb = iteration_callback_class()(self.n, self.ng, record)
        opts: dict[str, Any] = {
            "grad_f": self.grad_fn, "hess_lag": self.hess_fn, "iteration_callback": it_cb,
            "print_time": False, "show_eval_warnings": False, "ipopt": ipopt,
        }  # fmt: skip
        nlp = {"x": self._x, "p": self._p, "f": self._cost_cb(self._x), "g": self.g_fn(self._x)}
        return casadi.nlpsol("bondid_fit", "ipopt", nlp, opts), it_cb


def _constraint_hessian(
    constraints: Constraints, mode: str
) -> Callable[[np.ndarray, np.ndarray], Any]:
    """``(z, λ_g) -> Σ λ_g,i ∇² g_i`` ``(n, n)`` (convexified, exact or 0, see :class:`Nlp`)."""
    import casadi

    n = int(constraints.zsym.shape[0])
    if constraints.size == 0 or mode == "none":
        return lambda z, lg: np.zeros((n, n))
    lam = casadi.SX.sym("lam_g", constraints.size)
    expr = casadi.hessian(casadi.dot(lam, constraints.expr), constraints.zsym)[0]
    fn = casadi.Function("fit_hess_g", [constraints.zsym, lam], [expr])

    def hess(z: np.ndarray, lg: np.ndarray) -> np.ndarray:
        Hg = np.asarray(fn(z, lg), dtype=float)
        if mode == "convexified":
            w, V = np.linalg.eigh(0.5 * (Hg + Hg.T))
            Hg = (V * np.maximum(w, 0.0)) @ V.T
        return Hg

    return hess
