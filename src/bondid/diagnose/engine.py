"""The diagnosis refit engine: bounded least squares over log-scaled, possibly tied parameters.

A refit *variable* (:mod:`.variables`) ``v > 0`` is refitted as ``u = ln v`` within its
bounds. It either sets named URDF parameters linearly (``URDF value = factor · v`` for each
of its ``members``; one variable may set several, e.g. one shear stiffness for every segment of
a lumped chain, or one scale for a link's whole inertia tensor) or it is a parameter of an FRF
*modifier* (a delay or a lag, see :class:`bondid.diagnose.effects.base.Effect`). The model
FRF of data set ``b`` is

    H_b(ω; v) = G(ω; θ) ⊙ C Z(ω; v)⁻¹ B,      Z = K − ω²M + jωD,

and the residual is the spec's complex-log error in dB (``cost = ‖r‖²`` = the weighted mean
square, weights = coherence when present). Its Jacobian is exact: for a variable acting on
joint springs/dampers only, ``∂H/∂v = −Y diag(∂k + jω∂d) X`` (``X = Z⁻¹B``, ``Y = CZ⁻¹``),
for one acting on link inertials ``−Y (∂K_g − ω²∂M) X`` with the affine bases of
:class:`bondid.linear.affine.AffineModel`, and ``H ∂G/∂θ`` for modifier parameters.
The optimiser is SciPy's trust-region reflective least squares with that Jacobian.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..cost.problem import CostOptions, FrfProblem
from ..cost.residuals import RESIDUAL_KINDS, residual, residual_jacobian
from ..data.measurement import FrfData
from ..exceptions import ComputationError, ConfigError
from ..frf.directions import Directions
from ..frf.engine import dynamic_stiffness, omega, solve_columns
from ..linear.parameter_map import ParameterMap
from ..model.document import UrdfDocument
from ..model.parameters import parameter_infos
from .variables import COM_HALF_WIDTH, Variable, nominal_variables

__all__ = ["COM_HALF_WIDTH", "ModifierFn", "Refit", "RefitOutcome", "Variable", "nominal_variables"]

#: The modifier callback: (values (n_θ,), freq_hz, outputs, inputs) -> (G, dG).
ModifierFn = Callable[
    [np.ndarray, np.ndarray, tuple[str, ...], tuple[str, ...]], tuple[np.ndarray, np.ndarray]
]


@dataclass
class RefitOutcome:
    """Result of :meth:`Refit.solve`: values ``(n,)``, cost, std ``(n,)``, status text."""

    values: np.ndarray
    cost: float
    std: np.ndarray
    nfev: int
    status: str


class Refit:
    """Residuals and exact Jacobian of a model with refit variables on data sets.

    Args:
        doc: the (augmented) model; variables' members must be its parameters.
        datasets: measured FRFs in receptance.
        variables: the refit variables (nominal and new).
        modifier: optional FRF modifier callback (values of the modifier variables in the
            order of their ``modifier`` index).
        options: cost options (complex-log, coherence weights by default).
    """

    def __init__(
        self,
        doc: UrdfDocument,
        datasets: Sequence[FrfData],
        variables: Sequence[Variable],
        *,
        modifier: ModifierFn | None = None,
        options: CostOptions | None = None,
    ):
        self.doc = doc
        self.variables = list(variables)
        self.problem = FrfProblem(doc, datasets, options or CostOptions())
        if self.problem.options.kind != "complex_log":
            raise ConfigError("the diagnosis refit uses the complex_log residual")
        order = [p.name for p in parameter_infos(doc)]
        named = sorted({m for v in self.variables for m, _ in v.members}, key=order.index)
        self.pmap = ParameterMap(doc, self.problem.affines[0], named)
        n_var = len(self.variables)
        self.T = np.zeros((len(named), n_var))
        for k, var in enumerate(self.variables):
            for m, fac in var.members:
                self.T[named.index(m), k] += fac
        self.mod_idx = [k for k, v in enumerate(self.variables) if v.modifier is not None]
        self.modifier = modifier
        if self.mod_idx and modifier is None:
            raise ConfigError("modifier variables given without a modifier")
        self.is_log = np.array([v.log for v in self.variables], bool)
        self.lower = self._to_u(np.array([v.lower for v in self.variables]))
        self.upper = self._to_u(np.array([v.upper for v in self.variables]))
        self.u0 = np.clip(
            self._to_u(np.array([v.initial for v in self.variables])), self.lower, self.upper
        )
        total = sum(float(b.weight.sum()) for b in self.problem.blocks)
        self._norm = 1.0 / np.sqrt(total)
        self._cache: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        #: residual kind being minimised (see :meth:`solve`)
        self.kind = "complex_log"
        #: evaluations used by all solves so far
        self.nfev = 0

    # -- model ------------------------------------------------------------------------------
    def _to_u(self, v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, float)
        return np.where(self.is_log, np.log(np.where(self.is_log, v, 1.0)), v)

    def values(self, u: np.ndarray) -> np.ndarray:
        """Variable values (SI) at ``u``."""
        u = np.asarray(u, float)
        return np.where(self.is_log, np.exp(np.where(self.is_log, u, 0.0)), u)

    def _mod_values(self, v: np.ndarray) -> np.ndarray:
        out = np.zeros(len(self.mod_idx))
        for k in self.mod_idx:
            out[int(self.variables[k].modifier)] = v[k]  # type: ignore[arg-type]
        return out

    def _matrices(self, block, values):
        aff = block.affine.with_values(*values)
        return aff, aff.mass_matrix(), aff.stiffness_matrix(), aff.damping_matrix()

    def frf(self, u: np.ndarray, freq_hz: np.ndarray | None = None) -> list[np.ndarray]:
        """Model FRF per data set ``(n_out, n_in_model, n_f)`` on ``freq_hz`` (default: the
        frequencies each data set uses)."""
        v = self.values(u)
        values = self.pmap.values(self.T @ v)
        mv = self._mod_values(v)
        out = []
        for b in self.problem.blocks:
            f = b.freq_hz if freq_hz is None else np.asarray(freq_hz, float)
            aff, M, K, D = self._matrices(b, values)
            Z = dynamic_stiffness(M, K, D, omega(f))
            X = solve_columns(Z, aff.B)
            H = np.einsum("on,fni->oif", aff.C, X)
            if self.modifier is not None:
                G, _ = self.modifier(mv, f, aff.outputs, aff.inputs)
                H = H * G
            out.append(H)
        return out

    def residual(self, u: np.ndarray) -> np.ndarray:
        """Scaled residuals ``(n_r,)``; ``‖r‖²`` = weighted mean square complex-log error."""
        rs = []
        for b, H in zip(self.problem.blocks, self.frf(u), strict=True):
            Hs = H[b.rows, b.cols, b.fidx]
            r = residual(self.kind, Hs, b.Hm)
            rs.append((r * (np.sqrt(b.weight) * self._norm)).reshape(-1))
        out = np.concatenate(rs)
        if not np.all(np.isfinite(out)):
            raise ComputationError("the refit model gives non-finite FRF values")
        return out

    def cost(self, u: np.ndarray) -> float:
        r = self.residual(u)
        return float(r @ r)

    def residual_and_jacobian(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``(n_r,)`` and the exact Jacobian ``(n_r, n_var)`` w.r.t. ``u = ln v``."""
        u = np.asarray(u, float)
        key = np.r_[u, RESIDUAL_KINDS.index(self.kind)]
        if self._cache is not None and np.array_equal(self._cache[0], key):
            return self._cache[1], self._cache[2]
        v = self.values(u)
        named = self.T @ v
        values = self.pmap.values(named)
        dpi, dk, dd = self.pmap.jacobian(named)
        dv = np.where(self.is_log, v, 1.0)
        Tv = self.T * dv[None, :]
        dpi_v = dpi @ Tv if dpi.size else np.zeros((dpi.shape[0], 10, len(v)))
        dk_v, dd_v = dk @ Tv, dd @ Tv
        mv = self._mod_values(v)
        rs, Js = [], []
        for b in self.problem.blocks:
            aff, M, K, D = self._matrices(b, values)
            w = omega(b.freq_hz)
            Z = dynamic_stiffness(M, K, D, w)
            X = solve_columns(Z, aff.B)  # (f, n, n_in)
            Yt = solve_columns(np.swapaxes(Z, 1, 2), aff.C.T)  # (f, n, n_out)
            Xs = X[b.fidx, :, b.cols]  # (s, n)
            Ys = Yt[b.fidx, :, b.rows]  # (s, n)
            ws = w[b.fidx]
            Hs = np.einsum("sn,sn->s", aff.C[b.rows], Xs)
            dR = Directions.build(aff, dpi_v, dk_v, dd_v).derivatives(Ys, Xs, ws)
            dH = dR[0] + 1j * dR[1]  # (s, n_var)
            if self.modifier is not None:
                G, dG = self.modifier(mv, b.freq_hz, aff.outputs, aff.inputs)
                Gs = G[b.rows, b.cols, b.fidx]
                dGs = dG[b.rows, b.cols, b.fidx]  # (s, n_mod)
                dH = dH * Gs[:, None]
                for k in self.mod_idx:
                    dH[:, k] = Hs * dGs[:, int(self.variables[k].modifier)] * dv[k]  # type: ignore[arg-type]
                Hs = Hs * Gs
            sw = np.sqrt(b.weight) * self._norm
            r = residual(self.kind, Hs, b.Hm)
            J = residual_jacobian(self.kind, Hs, b.Hm, dH)
            r = r * sw
            J = J * sw[None, :, None]
            rs.append(r.reshape(-1))
            Js.append(J.reshape(-1, len(v)))
        r_all, J_all = np.concatenate(rs), np.concatenate(Js)
        if not (np.all(np.isfinite(r_all)) and np.all(np.isfinite(J_all))):
            raise ComputationError("the refit model gives non-finite FRF values or derivatives")
        self._cache = (key, r_all, J_all)
        return r_all, J_all

    # -- solving ------------------------------------------------------------------------------
    def solve(
        self,
        u0: np.ndarray | None = None,
        *,
        free: Sequence[int] | None = None,
        max_nfev: int = 40,
        pre_nfev: int = 0,
    ) -> tuple[np.ndarray, RefitOutcome]:
        """Bounded least squares from ``u0`` (default: the initial values).

        With ``pre_nfev > 0`` a first stage minimises the normalised complex error
        ``(Hs − Hm)/|Hm|`` (the seed's eq. 6.3) for up to ``pre_nfev`` evaluations before the
        complex-log error. The log error is infinite where the model has a zero the data do not
        have, so when a cross term's static gain must change sign on the way to the optimum
        (a CoM coordinate a few tenths of a millimetre off), the log cost has a wall the
        local search cannot cross; the normalised error is bounded there (−1) and smooth.
        Measured on a blind case (50 nominal + 2 new parameters from nominal values): log
        error alone stalls at cost 35 in 150 evaluations, 40 normalised + 80 log reach 3.56
        (the truth's 3.51).

        Args:
            u0: start ``(n_var,)`` in log units.
            free: indices of the variables to move (default all); the others stay at ``u0``.
            max_nfev: SciPy's function-evaluation limit (complex-log stage).
            pre_nfev: evaluations of the normalised-complex stage (0 = none).

        Returns:
            ``(u, outcome)``: the solution in log units and its :class:`RefitOutcome`
            (cost = the complex-log cost).
        """
        n0 = self.nfev
        u = np.clip(self.u0 if u0 is None else np.asarray(u0, float), self.lower, self.upper)
        idx = np.arange(len(self.variables)) if free is None else np.asarray(list(free), int)
        if pre_nfev > 0 and idx.size:
            self.kind = "normalised_complex"
            try:
                u = self._least_squares(u, idx, pre_nfev)[0]
            finally:
                self.kind = "complex_log"
        if idx.size == 0:
            r = self.residual(u)
            return u, RefitOutcome(self.values(u), float(r @ r), np.full(0, np.nan), 1, "")
        u, message = self._least_squares(u, idx, max_nfev)
        r, J = self.residual_and_jacobian(u)
        std = self.std(r, J, u)
        return u, RefitOutcome(self.values(u), float(r @ r), std, self.nfev - n0, message)

    def _least_squares(
        self, u_start: np.ndarray, idx: np.ndarray, max_nfev: int
    ) -> tuple[np.ndarray, str]:
        """SciPy's trust-region reflective least squares of the current :attr:`kind` over the
        variables ``idx``; returns ``(u, message)``."""
        from scipy.optimize import least_squares

        def full(z: np.ndarray) -> np.ndarray:
            u = u_start.copy()
            u[idx] = z
            return u

        lo, hi = self.lower[idx], self.upper[idx]
        z0 = np.clip(u_start[idx], lo + 1e-12, hi - 1e-12) if np.all(hi > lo) else u_start[idx]
        res = least_squares(
            lambda z: self.residual_and_jacobian(full(z))[0],
            z0,
            jac=lambda z: self.residual_and_jacobian(full(z))[1][:, idx],
            bounds=(lo, hi),
            method="trf",
            x_scale="jac",  # from nominal: ~2× lower cost in 60 evaluations than x_scale=1
            ftol=1e-7,
            xtol=1e-7,
            gtol=1e-8,
            max_nfev=max_nfev,
        )
        self.nfev += int(res.nfev)
        return full(res.x), str(res.message)

    def std(self, r: np.ndarray, J: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Standard deviation of each variable ``(n_var,)`` [SI] from the Jacobian at ``u``:
        ``cov(u) = ‖r‖²/(N − p)·(JᵀJ)⁺``; ``std(v) = v·std(u)`` for log variables."""
        n, p = J.shape
        if n <= p:
            return np.full(p, np.nan)
        JtJ = J.T @ J
        scale = np.sqrt(np.maximum(np.diag(JtJ), 1e-300))
        cov = np.linalg.pinv(JtJ / np.outer(scale, scale), rcond=1e-12) / np.outer(scale, scale)
        var_u = np.diag(cov) * float(r @ r) / (n - p)
        v = self.values(u)
        return np.where(self.is_log, v, 1.0) * np.sqrt(np.maximum(var_u, 0.0))

    def scan(self, u0: np.ndarray, exponents: np.ndarray, grid: Sequence[float]) -> np.ndarray:
        """Start point from a 1-D scan: ``u = u0 + exponents·ln s`` for ``s`` in ``grid``
        (clipped to the bounds); returns the best ``u`` (``u0`` included)."""
        best_u, best_c = np.asarray(u0, float), self._safe_cost(u0)
        for s in grid:
            u = np.clip(u0 + np.asarray(exponents) * np.log(s), self.lower, self.upper)
            c = self._safe_cost(u)
            if c < best_c:
                best_u, best_c = u, c
        return best_u

    def scan_starts(
        self,
        u0: np.ndarray,
        exponents: np.ndarray,
        grid: Sequence[float],
        n_starts: int = 3,
        min_ratio: float = 1.5,
    ) -> list[np.ndarray]:
        """Up to ``n_starts`` start points: the lowest local minima of the scan profile
        ``cost(u0 + exponents·ln s)`` over ``grid`` (increasing), at least ``min_ratio``
        apart in ``s``, best first."""
        g = np.asarray(grid, float)
        us = [np.clip(u0 + np.asarray(exponents) * np.log(s), self.lower, self.upper) for s in g]
        c = np.array([self._safe_cost(u) for u in us])
        left = np.r_[np.inf, c[:-1]]
        right = np.r_[c[1:], np.inf]
        minima = [int(i) for i in np.flatnonzero((c <= left) & (c <= right) & np.isfinite(c))]
        minima.sort(key=lambda i: c[i])
        chosen: list[int] = []
        for i in minima:
            if all(abs(np.log(g[i] / g[j])) >= np.log(min_ratio) for j in chosen):
                chosen.append(i)
            if len(chosen) == n_starts:
                break
        return [us[i] for i in chosen] or [np.asarray(u0, float)]

    def _safe_cost(self, u: np.ndarray) -> float:
        try:
            return self.cost(u)
        except ComputationError:
            return float("inf")

    # -- named results ----------------------------------------------------------------------
    def frf_for_data(self, u: np.ndarray) -> list[np.ndarray]:
        """Model FRF per data set on its whole frequency grid, columns in the data's input
        order: ``(n_out, n_in_data, n_freq)`` each (what :func:`gap_report` takes)."""
        out = []
        for b in self.problem.blocks:
            ds = b.data
            H = self.frf_at(u, b, ds.freq_hz)
            cols = [b.affine.inputs.index(i) for i in ds.inputs]
            out.append(H[:, cols, :])
        return out

    def frf_at(self, u: np.ndarray, block, freq_hz: np.ndarray) -> np.ndarray:
        """Model FRF ``(n_out, n_in_model, n_f)`` of one data set's block at ``freq_hz``."""
        v = self.values(u)
        aff, M, K, D = self._matrices(block, self.pmap.values(self.T @ v))
        f = np.asarray(freq_hz, float)
        X = solve_columns(dynamic_stiffness(M, K, D, omega(f)), aff.B)
        H = np.einsum("on,fni->oif", aff.C, X)
        if self.modifier is not None:
            H = H * self.modifier(self._mod_values(v), f, aff.outputs, aff.inputs)[0]
        return H

    def named_values(self, u: np.ndarray) -> dict[str, float]:
        """URDF parameter values set by the structural variables at ``u``."""
        vals = self.T @ self.values(u)
        return dict(zip(self.pmap.names, (float(x) for x in vals), strict=True))
