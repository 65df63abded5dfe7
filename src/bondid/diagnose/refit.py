"""The diagnosis's refits as clients of the one optimisation core (:mod:`bondid.optim`).

A refit is a :class:`~bondid.optim.FitProblem` over the (augmented) model:

* the nominal parameters (:class:`Nominal`): URDF names with the bounds of ``bondid.fit``
  (:func:`bondid.optim.bounds.default_bounds` around the nominal model, for every origin);
* the new parameters of the accepted effects and of the candidate (:class:`NewVar`), just
  more names: a structural one is its first member's URDF parameter (the *leader*), its other
  members tied to it with the ratios of their factors (:mod:`bondid.optim.tied`); a modifier
  one (delay, lag) is a parameter of the problem's FRF modifier (one modifier per problem,
  composed of every modifier effect, :class:`bondid.diagnose.augmented.ComposedModifier`).
  A new parameter whose members the core cannot tie (several link masses: the core ties
  joint springs and dampers only) is held at its start;
* the noise-scaled prior of ``bondid.fit`` toward the nominal model's values
  (:mod:`bondid.optim.prior`, width :data:`bondid.fit.defaults.DEFAULT_WIDTH`) on the nominal
  parameters only: a new parameter has no model value to be pulled toward.

Solves are :func:`bondid.optim.search.run_search` schedules (direct with the presolve, or a
short presolve-then-log pair); a point of a refit is a :class:`State` (named values ``x`` and
the modifier's ``θ``), and every problem at a state is a :meth:`FitProblem.restrict` of the one
built here (nothing is linearised again).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from ..cost.modifier import FrfModifier
from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..exceptions import ComputationError
from ..fit.defaults import DEFAULT_WIDTH
from ..model.document import UrdfDocument
from ..optim.problem import FitProblem
from ..optim.result import conditional_std

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..optim.prior import NominalPrior
    from ..optim.result import FitResult
    from ..optim.search import SearchResult, Step


@dataclass(frozen=True)
class Nominal:
    """The nominal parameters of every refit of a diagnosis.

    Attributes:
        names: URDF parameter names ``(n,)``.
        lower, upper: their bounds ``(n,)`` (SI), around the nominal model's values.
        centre: the nominal model's values of ``names`` ``(n,)`` (the prior's centre).
        prior_width: relative width of the prior (0 = none).
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    centre: np.ndarray
    prior_width: float = DEFAULT_WIDTH


def nominal_space(
    doc: UrdfDocument, names: Sequence[str], f_max_hz: float | None = None,
    prior_width: float = DEFAULT_WIDTH,
) -> Nominal:  # fmt: skip
    """:class:`Nominal` of ``names`` around ``doc``'s values (``bondid.fit``'s default bounds,
    ``f_max_hz``: the data's highest frequency)."""
    from ..model.parameters import get_parameters
    from ..optim.bounds import default_bounds

    lo, hi = default_bounds(doc, list(names), f_max_hz=f_max_hz)
    centre = get_parameters(doc, list(names))
    return Nominal(tuple(names), lo, hi, centre, prior_width)


def nominal_space_for(doc: UrdfDocument, names: Sequence[str], data: Sequence[FrfData]) -> Nominal:
    """:func:`nominal_space` with the bounds of a fit on ``data`` (their highest frequency)."""
    return nominal_space(doc, names, max(float(d.freq_hz.max()) for d in data))


@dataclass(frozen=True)
class NewVar:
    """One new parameter of a refit (see the module docstring).

    Attributes:
        name: readable name (the candidate's parameter name).
        initial, lower, upper: start and bounds (SI of the candidate's parameter).
        leader: the URDF parameter it is fitted as (structural), else None.
        factor: ``leader value = factor · value``.
        ties: the other members ``((name, factor relative to the leader), ...)``.
        theta: index into the FRF modifier's parameters (modifier), else None.
        held: not fitted (members the core cannot tie).
        linear: a modifier parameter fitted on a linear scale (signed, may be 0), of typical
            size ``scale`` (:class:`bondid.cost.modifier.FrfModifier`); else on a log scale.
    """

    name: str
    initial: float
    lower: float
    upper: float
    leader: str | None = None
    factor: float = 1.0
    ties: tuple[tuple[str, float], ...] = ()
    theta: int | None = None
    held: bool = False
    linear: bool = False
    scale: float = 1.0


@dataclass
class State:
    """A point of a refit: named values ``x`` ``(n,)`` of the problem's names and the FRF
    modifier's parameters ``theta`` ``(n_θ,)``."""

    x: np.ndarray
    theta: np.ndarray

    def copy(self) -> State:
        return State(self.x.copy(), self.theta.copy())


def _prior(
    nominal: Nominal, doc: UrdfDocument
) -> Callable[[FitProblem], NominalPrior | None] | None:
    """``extra_rows`` of a refit of ``doc``: ``bondid.fit``'s prior toward the nominal values,
    on the nominal parameters (and their bodies) only."""
    if not nominal.prior_width > 0:
        return None
    from ..model.parameters import set_parameter
    from ..optim.prior import make_prior, shape_bounds

    keep = set(nominal.names)
    links = {n.split(".", 1)[0] for n in nominal.names}
    centre = doc.copy()  # the augmented model at the nominal values
    for name, v in zip(nominal.names, nominal.centre, strict=True):
        set_parameter(centre, name, float(v))

    def rows(p: FitProblem) -> NominalPrior | None:
        p.var_labels = p.var_labels + shape_bounds(centre, p.layout, p.lbz, p.ubz)
        prior = make_prior(centre, p.layout, p.frf, nominal.prior_width, p.notes, n_z=p.size)
        if prior is None:
            return None
        prior.joints = [(jv, v0) for jv, v0 in prior.joints if jv.name in keep]
        prior.bodies = [(b, u) for b, u in prior.bodies if b.link in links]
        return prior if prior.size else None

    return rows


class Refit:
    """A refit of the nominal and new parameters of ``doc`` on ``data`` (module docstring).

    Args:
        doc: the (augmented) model, new parameters at their start values.
        data: data sets (receptance).
        nominal: the nominal parameters.
        new: the new parameters, accepted effects' first, the candidate's last.
        modifier: the composed FRF modifier function of the modifier parameters, or None.
        options: cost options.
        n_own: how many of ``new`` (the last ones) are the candidate's own.
        ipopt: IPOPT options of every solve over those of ``bondid.fit`` (None: none).
    """

    def __init__(
        self, doc: UrdfDocument, data: Sequence[FrfData], nominal: Nominal,
        new: Sequence[NewVar], modifier: object | None, options: CostOptions, n_own: int,
        ipopt: dict | None = None,
    ):  # fmt: skip
        self.nominal, self.new, self.n_own = nominal, list(new), n_own
        self.ipopt = dict(ipopt or {})
        self.n_nominal = len(nominal.names)
        free = [v for v in self.new if v.leader is not None and not v.held]
        names = [*nominal.names, *(v.leader for v in free)]
        lower = np.r_[nominal.lower, [v.lower * v.factor for v in free]]
        upper = np.r_[nominal.upper, [v.upper * v.factor for v in free]]
        ties = {str(v.leader): list(v.ties) for v in free if v.ties}
        mods = sorted((v for v in self.new if v.theta is not None), key=lambda v: v.theta or 0)
        frf_mod = None
        if mods:
            frf_mod = FrfModifier(
                modifier,  # type: ignore[arg-type]
                tuple(v.name for v in mods), tuple(v.initial for v in mods),
                tuple(v.lower for v in mods), tuple(v.upper for v in mods),
                tuple(v.linear for v in mods), tuple(v.scale for v in mods),
                getattr(modifier, "mixing", None) if getattr(modifier, "mixes", False) else None,
            )  # fmt: skip
        self.modifier = frf_mod
        self.problem = FitProblem(
            doc, data, [str(n) for n in names], options=options, lower=lower, upper=upper,
            ties=ties, modifier=frf_mod, extra_rows=_prior(nominal, doc),
        )  # fmt: skip
        self.state0 = State(self.problem.initial.copy(), self.problem.theta(self.problem.z0))
        self.own = self.new[len(self.new) - n_own :]

    # -- points ------------------------------------------------------------------------------
    def at(self, state: State) -> FitProblem:
        """The problem over every name started at ``state``."""
        th = state.theta if state.theta.size else None
        return self.problem.restrict(start=state.x, theta=th)

    def new_values(self, state: State, own: bool = True) -> np.ndarray:
        """Values (SI) of the candidate's own (or all) new parameters at ``state``."""
        out = []
        for v in self.own if own else self.new:
            if v.theta is not None:
                out.append(float(state.theta[v.theta]))
            elif v.held or v.leader is None:
                out.append(v.initial)
            else:
                out.append(float(state.x[self.problem.names.index(v.leader)]) / v.factor)
        return np.array(out)

    def with_new(self, state: State, values: Sequence[float] | np.ndarray) -> State:
        """``state`` with the candidate's own new parameters at ``values`` (clipped)."""
        out = state.copy()
        for v, val in zip(self.own, values, strict=True):
            val = float(np.clip(val, v.lower, v.upper))
            if v.theta is not None:
                out.theta[v.theta] = val
            elif v.leader is not None and not v.held:
                out.x[self.problem.names.index(v.leader)] = val * v.factor
        return out

    def cost(self, state: State) -> float:
        """The objective (data and prior) at ``state``; inf where the model fails."""
        try:
            p = self.at(state)
            c = p.cost(p.z0)
        except (ComputationError, np.linalg.LinAlgError, ValueError):
            return float("inf")
        return c if np.isfinite(c) else float("inf")

    def data_cost(self, state: State) -> float:
        p = self.at(state)
        return p.data_cost(p.z0)

    @cached_property
    def noise_cost(self) -> float | None:
        """The data cost an exact model would score on the training data
        (:func:`bondid.cost.noise_level.noise_level_cost`, the weights' basis; None without a
        prediction). It depends on the data and weights only (every point of the refit
        restricts the same problem), so it is computed once."""
        from ..cost.noise_level import noise_level_cost

        return noise_level_cost(self.problem.frf, "weights")

    # -- scans -------------------------------------------------------------------------------
    def profile(
        self, state: State, exps: np.ndarray, grid: Sequence[float] | np.ndarray
    ) -> list[State]:
        """States ``values · s^exps`` of the own new parameters for ``s`` in ``grid``."""
        v0 = self.new_values(state)
        return [self.with_new(state, v0 * float(s) ** np.asarray(exps)) for s in grid]

    def costs(self, base: State, states: Sequence[State]) -> np.ndarray:
        """:meth:`cost` of ``states`` that differ from ``base`` in the candidate's own new
        parameters only, on one problem (their decision vectors set directly: a new
        parameter is a joint entry ``value/scale`` or a modifier entry ``ln(θ/θ₀)`` (linear
        ones ``(θ − θ₀)/s``); a state that moves another kind, e.g. a link mass, is costed on
        its own problem)."""
        p = self.at(base)
        joints = {jv.name: jv for jv in p.layout.joints if jv.name_index >= 0}
        theta0 = p.theta(p.z0)
        out = np.full(len(states), np.inf)
        for k, s in enumerate(states):
            z = self._z(p, joints, theta0, base, s)
            if z is None:
                out[k] = self.cost(s)
                continue
            c = p.cost(np.clip(z, p.lbz, p.ubz))
            out[k] = c if np.isfinite(c) else np.inf
        return out

    def _z(
        self, p: FitProblem, joints: dict, theta0: np.ndarray, base: State, s: State
    ) -> np.ndarray | None:
        """The decision vector of ``s`` on ``p`` (started at ``base``), or None when ``s``
        moves a new parameter that is not a joint entry."""
        z = p.z0.copy()
        u = None if self.modifier is None else self.modifier.u_of(s.theta, theta0)
        for v in self.own:
            if v.theta is not None and u is not None:
                z[p.layout.size + v.theta] = u[v.theta]
            elif v.leader is not None and not v.held:
                i = self.problem.names.index(v.leader)
                jv = joints.get(v.leader)
                if jv is not None:
                    z[jv.index] = s.x[i] / jv.scale
                elif s.x[i] != base.x[i]:
                    return None
        return z

    # -- solves ------------------------------------------------------------------------------
    def solve(
        self, state: State, steps: Sequence[Step], *, max_iter: int = 30
    ) -> tuple[State, float, SearchResult]:
        """Run the schedule ``steps`` from ``state`` over every name; returns the new state,
        its objective (:meth:`cost`) and the search (:func:`bondid.optim.search.run_search`)."""
        from ..optim.search import run_search

        sub = self.at(state)
        res = run_search(sub, steps, max_iter=max_iter, ipopt_options=self.ipopt_options())
        out = State(res.result.fitted.copy(), self.state_theta(res.result))
        return out, self.cost(out), res

    def solve_new(self, state: State, max_iter: int) -> tuple[State, float]:
        """One IPOPT solve of the candidate's own new parameters (the others held; the FRF
        modifier's θ free) from ``state``; returns the new state and its objective over
        every name (:meth:`cost`)."""
        names = [str(v.leader) for v in self.own if v.leader is not None and not v.held]
        if not names and not any(v.theta is not None for v in self.own):
            return state, self.cost(state)
        return self.solve_only(state, names, max_iter)

    def solve_only(self, state: State, names: Sequence[str], max_iter: int) -> tuple[State, float]:
        """One IPOPT solve of ``names`` (and the FRF modifier's θ) from ``state``, every other
        name held; returns the new state and its objective over every name (:meth:`cost`)."""
        from ..optim.ipopt import solve

        th = state.theta if state.theta.size else None
        sub = self.problem.restrict(names, start=state.x, theta=th)
        sol = solve(sub, max_iter=max_iter, ipopt_options=self.ipopt_options())
        out = state.copy()
        out.x[[self.problem.names.index(n) for n in names]] = sub.values(sol.z)
        out.theta = sub.theta(sol.z)
        return out, self.cost(out)

    def ipopt_options(self) -> dict | None:
        """IPOPT's options of every solve (those ``bondid.fit`` uses with the prior, then
        :attr:`ipopt`)."""
        from ..optim.prior import with_prior_ipopt

        return with_prior_ipopt(self.nominal.prior_width, self.ipopt or None)

    def result(self, res: SearchResult) -> tuple[FitResult, np.ndarray]:
        """The search's :class:`FitResult` and the std ``(n_θ,)`` of the modifier's θ.

        With a modifier, every std (named parameters and θ) comes from one Jacobian, the
        named columns and ``∂r/∂θ`` together, so a delay or a lag that trades off against a
        stiffness widens both (the core's :class:`FitResult` has the named columns alone).
        """
        import dataclasses

        from ..optim.result import parameter_statistics

        fit = res.result
        if self.modifier is None:
            return fit, np.zeros(0)
        theta = self.state_theta(fit)
        p = self.problem.restrict(start=fit.fitted, theta=theta)
        r, J_named = p.named_residual_and_jacobian(p.z0)
        J_z = p.residual_and_jacobian(p.z0)[1][: p.n_residuals]
        n = self.modifier.size
        J = np.hstack([J_named, J_z[:, p.size - n :] / self.modifier.slope(theta)])  # ∂r/∂θ
        std, _ = parameter_statistics(J, r)
        return dataclasses.replace(fit, std=std[:-n]), std[-n:]

    def new_std(self, fit: FitResult, std_theta: np.ndarray) -> np.ndarray:
        """Std (SI) of every new parameter: the leader's over its factor, θ's (``std_theta``),
        NaN when held."""
        out = []
        for v in self.new:
            if v.theta is not None:
                out.append(float(std_theta[v.theta]) if std_theta.size else np.nan)
            elif v.held or v.leader is None:
                out.append(np.nan)
            else:
                out.append(float(fit.std[fit.names.index(v.leader)]) / v.factor)
        return np.array(out)

    def own_strength_std(self, fit: FitResult, std_theta: np.ndarray) -> np.ndarray:
        """Std (SI) of each of the candidate's own parameters with its other own structural
        parameters held at their fitted values, the nominal ones and the earlier effects'
        free ``(n_own,)``; the marginal std (:meth:`new_std`) where that cannot be taken (a
        modifier's θ, a held member, an unidentified parameter). What the strength test
        divides by (:func:`.scoring.strength_z`, whose docstring says why).
        """
        marginal = self.new_std(fit, std_theta)[len(self.new) - len(self.own) :]
        idx = [fit.names.index(v.leader) if v.leader is not None and not v.held else -1
               for v in self.own]  # fmt: skip
        out = marginal.copy()
        std, corr = np.asarray(fit.std, float), np.asarray(fit.correlation, float)
        for k, (v, i) in enumerate(zip(self.own, idx, strict=True)):
            if i < 0 or not (np.isfinite(std[i]) and std[i] > 0):
                continue
            given = [j for j in idx if j >= 0 and j != i and np.isfinite(std[j]) and std[j] > 0]
            out[k] = conditional_std(std, corr, i, given) / v.factor
        return out

    def state_theta(self, fit: FitResult) -> np.ndarray:
        if self.modifier is None:
            return np.zeros(0)
        return np.array([fit.modifiers[n] for n in self.modifier.names])
