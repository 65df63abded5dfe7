"""The NLP handed to IPOPT through ``casadi.nlpsol``: numeric least squares, symbolic constraints.

The FRF residual ``r(z)`` is computed in numpy by :class:`bondid.cost.FrfProblem` (exact
Jacobian ``J = ∂r/∂z``) and enters CasADi through :class:`casadi.Callback` objects:

* objective ``f(z) = ‖r‖²`` (residual only, no Jacobian: IPOPT's line-search trial points),
* ``grad_f``: ``(f, 2 Jᵀ r)``,
* ``hess_lag``: the Gauss–Newton Hessian of the Lagrangian ``λ_f · 2 JᵀJ + Σ λ_g,i ∇² g_i``;
  the objective part drops the second-order residual terms (and is Levenberg–Marquardt damped
  far from the solution, see :class:`Evaluator`); the constraint part comes from CasADi's
  symbolic Hessians (SX) and is by default CONVEXIFIED (negative eigenvalues clipped to 0):
  the exact ``Σ λ ∇² g`` of the inertia equalities is indefinite, which made IPOPT regularise
  the whole Hessian by ``δ ≈ 1…100`` every iteration and crawl. Limited-memory quasi-Newton on
  the scalar cost needs hundreds of iterations on this problem; Gauss–Newton tens.

:class:`Evaluator` caches the last ``(z, r, J)`` so that ``f``, ``grad_f`` and ``hess_lag`` at
the same ``z`` cost one Jacobian evaluation.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import interrupt
from ..cost.problem import FrfProblem, ParameterModel
from ..exceptions import ComputationError, ConfigError


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
        prior: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
    ):
        self.problem = problem
        self.pmodel = pmodel
        #: extra residual rows ``z -> (r (m,), J (m, n))`` appended to the data's (a prior,
        #: :mod:`bondid.fit.prior`); None = none
        self.prior = prior
        self._jac: tuple[bytes, np.ndarray, np.ndarray] | None = None
        self._res: tuple[bytes, np.ndarray] | None = None
        self.n_residual = 0
        self.n_jacobian = 0
        self.damping = damping
        self.lam = 1e-3 if damping else 0.0
        self._prev: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # z, r, J

    def _fail(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        extra = 0 if self.prior is None else int(self.prior.size)  # type: ignore[attr-defined]
        r = np.full(self.problem.n_residuals + extra, np.nan)
        return r, np.full((r.size, n), np.nan)

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
            r = self._fail(z.size)[0]
        self.n_residual += 1
        self._res = (key, r)
        return r

    def residual_and_jacobian(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z = np.ascontiguousarray(z, dtype=float).reshape(-1)
        key = z.tobytes()
        if self._jac is not None and self._jac[0] == key:
            return self._jac[1], self._jac[2]
        try:
            with np.errstate(all="ignore"):
                r, J = self.problem.residual_and_jacobian(self.pmodel, z)
                if self.prior is not None:
                    rp, Jp = self.prior(z)
                    r, J = np.concatenate([r, rp]), np.vstack([J, Jp])
        except (np.linalg.LinAlgError, FloatingPointError, ValueError, ComputationError):
            r, J = self._fail(z.size)
        self.n_jacobian += 1
        self._jac = (key, r, J)
        return r, J

    def cost(self, z: np.ndarray) -> float:
        r = self.residual(z)
        return float(r @ r)

    def cost_and_gradient(self, z: np.ndarray) -> tuple[float, np.ndarray]:
        r, J = self.residual_and_jacobian(z)
        return float(r @ r), 2.0 * (J.T @ r)

    def _update_damping(self, z: np.ndarray, r: np.ndarray) -> None:
        prev = self._prev
        if prev is None or np.array_equal(prev[0], z):
            return
        z0, r0, J0 = prev
        Js = J0 @ (z - z0)
        predicted = -(2.0 * float(r0 @ Js) + float(Js @ Js))
        actual = float(r0 @ r0) - float(r @ r)
        rho = actual / predicted if predicted > 0 else -1.0
        if rho > 0.75:
            self.lam = self.lam / 3.0 if self.lam > 1e-12 else 0.0
        elif rho < 0.25:
            self.lam = min(max(2.0 * self.lam, 1e-6), 1e6)

    def gauss_newton(self, z: np.ndarray) -> np.ndarray:
        """``2 (JᵀJ + λ D)`` ``(n, n)`` at ``z`` (see the class docstring)."""
        z = np.ascontiguousarray(z, dtype=float).reshape(-1)
        r, J = self.residual_and_jacobian(z)
        H = J.T @ J
        if self.damping and np.all(np.isfinite(r)):
            self._update_damping(z, r)
            self._prev = (z.copy(), r, J)
            if self.lam > 0:
                d = np.diag(H).copy()
                H = H + self.lam * np.diag(d + 1e-9 * max(float(d.max()), 1e-300))
        return 2.0 * H


def _callback_class() -> tuple[Any, Any]:
    import casadi

    class NumpyCallback(casadi.Callback):  # type: ignore[misc]
        """A CasADi function of dense column inputs evaluated by a Python function."""

        def __init__(
            self,
            name: str,
            in_sizes: list[int],
            out_shapes: list[tuple[int, int]],
            fn: Callable,
            jacobian: Callable[[Any], Any] | None = None,
        ):
            casadi.Callback.__init__(self)
            self._in = in_sizes
            self._out = out_shapes
            self._fn = fn
            self._jac = jacobian
            self.construct(name, {"enable_fd": False})

        def has_jacobian(self) -> bool:
            return self._jac is not None

        def get_jacobian(self, name: str, inames: Any, onames: Any, opts: Any) -> Any:
            # only used for the one-input objective: d f / d z
            z = casadi.MX.sym("z", self._in[0])
            nominal = [casadi.MX.sym(f"out{i}", *s) for i, s in enumerate(self._out)]
            assert self._jac is not None
            return casadi.Function(name, [z, *nominal], [self._jac(z)], inames, onames, opts)

        def get_n_in(self) -> int:
            return len(self._in)

        def get_n_out(self) -> int:
            return len(self._out)

        def get_sparsity_in(self, i: int) -> Any:
            return casadi.Sparsity.dense(self._in[i], 1)

        def get_sparsity_out(self, i: int) -> Any:
            return casadi.Sparsity.dense(*self._out[i])

        def eval(self, arg: Any) -> Any:  # type: ignore[override]
            out = self._fn(*[np.asarray(a, dtype=float).reshape(-1) for a in arg])
            return [
                casadi.DM(np.asarray(o, dtype=float).reshape(s))
                for o, s in zip(out, self._out, strict=True)
            ]

    class IterationCallback(casadi.Callback):  # type: ignore[misc]
        """IPOPT's per-iteration hook: records the objective, calls ``progress``."""

        def __init__(
            self, nx: int, ng: int, record: Callable[[float, np.ndarray, np.ndarray], None]
        ):
            casadi.Callback.__init__(self)
            self._nx, self._ng = nx, ng
            self._record = record
            self.construct("fit_iteration", {})

        def get_n_in(self) -> int:
            return casadi.nlpsol_n_out()

        def get_n_out(self) -> int:
            return 1

        def get_name_in(self, i: int) -> str:
            return casadi.nlpsol_out(i)

        def get_name_out(self, i: int) -> str:
            return "ret"

        def get_sparsity_in(self, i: int) -> Any:
            name = casadi.nlpsol_out(i)
            if name == "f":
                return casadi.Sparsity.dense(1, 1)
            if name in ("x", "lam_x"):
                return casadi.Sparsity.dense(self._nx, 1)
            if name in ("g", "lam_g"):
                return casadi.Sparsity.dense(self._ng, 1)
            return casadi.Sparsity(0, 0)

        def eval(self, arg: Any) -> Any:  # type: ignore[override]
            names = casadi.nlpsol_out()
            self._record(
                float(arg[names.index("f")]),
                np.asarray(arg[names.index("x")], dtype=float).reshape(-1),
                np.asarray(arg[names.index("g")], dtype=float).reshape(-1),
            )
            # non-zero asks IPOPT to stop (User_Requested_Stop): a Ctrl-C that CasADi caught
            return [1 if interrupt.requested() else 0]

    return NumpyCallback, IterationCallback


@dataclass
class NlpOutcome:
    """What IPOPT returned: ``z`` (size,), status, iterations, multipliers and the history."""

    z: np.ndarray
    status: str
    success: bool
    iterations: int
    lam_x: np.ndarray
    lam_g: np.ndarray
    g: np.ndarray
    cost: float
    history: list[float] = field(default_factory=list)
    wall_s: float = 0.0
    #: the lowest-cost iterate that met the constraints (to 1e-6), and its cost (kept so that
    #: a failed solve still reports the best point it reached); None when there was none
    best_z: np.ndarray | None = None
    best_cost: float = float("inf")


class FitNlp:
    """``min ‖r(z)‖²`` s.t. ``lbz ≤ z ≤ ubz``, ``lbg ≤ g(z) ≤ ubg``, as CasADi functions.

    Args:
        evaluator: residuals and Jacobian (numpy).
        n: size of ``z``.
        constraints: ``zsym -> (g, lbg, ubg)`` building the CasADi SX constraint column.
        constraint_hessian: ``"convexified"`` (default), ``"exact"`` or ``"none"``: how
            ``Σ λ_g ∇² g`` enters ``hess_lag``.

    Attributes:
        cost_fn: CasADi ``z -> f`` (the NLP's objective).
        grad_fn: CasADi ``(z, p) -> (f, ∇f)`` (IPOPT's ``grad_f``; ``p`` is empty).
        hess_fn: CasADi ``(z, p, λ_f, λ_g) -> triu(∇²L)`` (IPOPT's ``hess_lag``).
        g_fn: CasADi ``z -> g``; ``lbg``, ``ubg``: numpy bounds of ``g``.
    """

    def __init__(
        self,
        evaluator: Evaluator,
        n: int,
        constraints: Callable[[Any], tuple[Any, np.ndarray, np.ndarray]],
        constraint_hessian: str = "convexified",
    ):
        import casadi

        if constraint_hessian not in ("convexified", "exact", "none"):
            raise ConfigError(
                f"constraint_hessian {constraint_hessian!r} is invalid; "
                "valid: convexified, exact, none"
            )
        NumpyCallback, self._IterationCallback = _callback_class()
        self.evaluator = evaluator
        self.n = n
        zs = casadi.SX.sym("z", n)
        g_sx, self.lbg, self.ubg = constraints(zs)
        self.ng = ng = int(g_sx.shape[0])
        lam_g_sx = casadi.SX.sym("lam_g", ng)
        self.g_fn = casadi.Function("fit_g", [zs], [g_sx])
        hg_fun = casadi.Function(
            "fit_hess_g", [zs, lam_g_sx], [casadi.hessian(casadi.dot(lam_g_sx, g_sx), zs)[0]]
        )
        self._grad_cb = NumpyCallback(
            "fit_grad", [n], [(1, 1), (n, 1)], lambda z: list(evaluator.cost_and_gradient(z))
        )
        # the objective's Jacobian (needed by CasADi's own derivative machinery) is grad_f
        self._cost_cb = NumpyCallback(
            "fit_cost",
            [n],
            [(1, 1)],
            lambda z: [evaluator.cost(z)],
            jacobian=lambda z: self._grad_cb(z)[1].T,
        )
        self._hg_fun = hg_fun

        def hess_lag(z: np.ndarray, lf: np.ndarray, lg: np.ndarray) -> list[np.ndarray]:
            H = float(lf[0]) * evaluator.gauss_newton(z)
            if ng:
                Hg = np.asarray(hg_fun(z, lg), dtype=float)
                if constraint_hessian == "convexified":
                    w, V = np.linalg.eigh(0.5 * (Hg + Hg.T))
                    Hg = (V * np.maximum(w, 0.0)) @ V.T
                if constraint_hessian != "none":
                    H = H + Hg
            return [H]

        self._hess_cb = NumpyCallback("fit_hess_lag", [n, 1, ng], [(n, n)], hess_lag)
        x = casadi.MX.sym("x", n)
        p = casadi.MX.sym("p", 0, 1)
        lam_f = casadi.MX.sym("lam_f", 1)
        lam_g = casadi.MX.sym("lam_g", ng)
        self.cost_fn = casadi.Function("fit_f", [x], [self._cost_cb(x)])
        f_val, g_val = self._grad_cb(x)
        self.grad_fn = casadi.Function(
            "nlp_grad_f", [x, p], [f_val, g_val], ["x", "p"], ["f", "grad"]
        )
        hess = self._hess_cb(x, lam_f, lam_g)
        self.hess_fn = casadi.Function(
            "nlp_hess_l",
            [x, p, lam_f, lam_g],
            [casadi.triu(hess)],
            ["x", "p", "lam_f", "lam_g"],
            ["hess"],
        )
        self._x = x
        self._p = p

    def gradient(self, z: np.ndarray) -> np.ndarray:
        """∇f ``(n,)`` at ``z`` through the CasADi ``grad_f`` function IPOPT uses."""
        import casadi

        return np.asarray(self.grad_fn(z, casadi.DM(0, 1))[1], dtype=float).reshape(-1)

    def cost(self, z: np.ndarray) -> float:
        """f at ``z`` through the CasADi objective function IPOPT uses."""
        return float(self.cost_fn(z))

    def solve(
        self,
        z0: np.ndarray,
        lbz: np.ndarray,
        ubz: np.ndarray,
        *,
        max_iter: int = 200,
        tol: float = 1e-10,
        progress: Callable[[int, float], None] | None = None,
        ipopt_options: dict[str, Any] | None = None,
    ) -> NlpOutcome:
        """Run IPOPT from ``z0`` (quiet), recording the objective at every iteration.

        Args:
            z0, lbz, ubz: start and bounds ``(n,)`` (±inf allowed).
            max_iter, tol: IPOPT's ``max_iter`` and ``tol``.
            progress: called as ``progress(iteration, cost)`` at every IPOPT iteration.
            ipopt_options: extra IPOPT options (override the defaults).
        """
        import casadi

        history: list[float] = []
        best: dict[str, Any] = {"z": None, "cost": float("inf")}
        lbg, ubg = np.asarray(self.lbg, float), np.asarray(self.ubg, float)

        def record(cost: float, z: np.ndarray, g: np.ndarray) -> None:
            history.append(cost)
            feasible = bool(np.all(g >= lbg - 1e-6) and np.all(g <= ubg + 1e-6))
            if feasible and np.isfinite(cost) and cost < best["cost"]:
                best["z"], best["cost"] = z.copy(), cost
            if progress is not None:
                progress(len(history) - 1, cost)

        it_cb = self._IterationCallback(self.n, self.ng, record)
        ipopt: dict[str, Any] = {
            "print_level": 0,
            "sb": "yes",
            "max_iter": int(max_iter),
            "tol": float(tol),
            "mu_strategy": "monotone",
        }
        ipopt.update(ipopt_options or {})
        opts: dict[str, Any] = {
            "grad_f": self.grad_fn,
            "hess_lag": self.hess_fn,
            "iteration_callback": it_cb,
            "print_time": False,
            "show_eval_warnings": False,
            "ipopt": ipopt,
        }
        nlp = {"x": self._x, "p": self._p, "f": self._cost_cb(self._x), "g": self.g_fn(self._x)}
        solver = casadi.nlpsol("bondid_fit", "ipopt", nlp, opts)
        t0 = time.perf_counter()
        sol = solver(x0=z0, lbx=lbz, ubx=ubz, lbg=self.lbg, ubg=self.ubg)
        interrupt.check()  # a Ctrl-C during the solve stopped IPOPT: stop the run too
        wall = time.perf_counter() - t0
        stats = solver.stats()
        return NlpOutcome(
            z=np.asarray(sol["x"], dtype=float).reshape(-1),
            status=str(stats.get("return_status", "unknown")),
            success=bool(stats.get("success", False)),
            iterations=int(stats.get("iter_count", max(len(history) - 1, 0))),
            lam_x=np.asarray(sol["lam_x"], dtype=float).reshape(-1),
            lam_g=np.asarray(sol["lam_g"], dtype=float).reshape(-1),
            g=np.asarray(sol["g"], dtype=float).reshape(-1),
            cost=float(sol["f"]),
            history=history,
            wall_s=wall,
            best_z=best["z"],
            best_cost=float(best["cost"]),
        )
