"""The constrained FRF fit: :func:`fit` (IPOPT, Gauss–Newton Hessian, physical consistency).

Formulation. Every body with a free inertial parameter is represented by its log-Cholesky
coordinates θ (Rucker & Wensing 2022): ``J(θ) = U Uᵀ`` with ``U`` upper triangular with
exponentiated diagonal, so the pseudo-inertia is positive definite — the body physically
consistent (``m > 0``, ``I_c ≻ 0``, triangle inequalities) — at EVERY iterate, by construction,
with no semidefinite constraint. This was chosen over explicit smooth constraints (e.g. the
eigenvalues or leading minors of ``J``) because those are only enforced at convergence by an
interior-point method, are badly scaled near the boundary and leave the FRF model to be
evaluated at non-physical points (where ``M`` may be indefinite). θ maps smoothly and
one-to-one onto the consistent set and keeps the problem a smooth least-squares problem.
The fit uses the factor's entries in coordinates that separate the URDF quantities (see
:mod:`bondid.optim.layout`): ``m = e^{2α}``, ``c = t`` and the second moment about the
CoM ``Σ_c = V Vᵀ`` — so mass bounds are bounds on α, CoM bounds are bounds on ``t``, the
CoM-in-hull constraint ``A c ≤ b`` is linear, and a fixed mass, CoM or full inertia tensor is a
fixed variable. Fixed inertia components of a body whose other components are free are
equality constraints (symbolic in CasADi); bounds on free inertia components are inequality
constraints on the same expressions. Joint stiffness and damping are scaled by their starting
magnitude and bounded (≥ 0 by default). See :mod:`bondid.optim.layout` and
:mod:`bondid.optim.ipopt`.

The objective ``‖r‖²`` (:class:`bondid.cost.FrfProblem`, exact Jacobian in numpy) is given to
IPOPT with its gradient ``2Jᵀr`` and a Gauss–Newton Hessian ``2JᵀJ`` of the Lagrangian (plus the
constraints' symbolic Hessians, convexified): the least-squares structure converges in tens of
iterations where a quasi-Newton Hessian needs hundreds. It is a LOCAL method: from ±30 % on
every parameter the complex-log cost of lightly damped modes has other basins (measured on the
bonder); use the band continuation or staged schedules (:mod:`bondid.optim.schedules`) or the
multistart for global search. A log-cost fit runs twice, from the start and from a start
presolved on the normalised complex error (:data:`PRESOLVE_ITER`), and keeps the better: the
log cost has walls where a cross term changes sign. The second fit is skipped when the direct
one succeeded with the phase matched nearly everywhere (:data:`WALL_SHARE`; see
:mod:`bondid.optim.search`).

:func:`fit` is the front of the one optimisation core (:mod:`bondid.optim`): it builds a
:class:`~bondid.optim.FitProblem` and runs the direct schedule on it.

Kinematic joint placements are not fitted (they enter ``M`` non-linearly through Pinocchio's
numbers, which are constants here); a name that asks for one raises
:class:`bondid.exceptions.ConfigError`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..model.document import UrdfDocument
from ..optim.ipopt import SOFT_STATUSES, SUCCESS_STATUSES
from ..optim.result import FitResult
from ..optim.search import LOG_KINDS, PRESOLVE_ITER, WALL_SHARE

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..optim.search import SearchResult

__all__ = [
    "LOG_KINDS", "PRESOLVE_ITER", "SOFT_STATUSES", "SUCCESS_STATUSES", "WALL_SHARE", "fit",
]  # fmt: skip


def fit(
    doc: UrdfDocument,
    datasets: list[FrfData],
    names: list[str],
    *,
    options: CostOptions | None = None,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    start: np.ndarray | None = None,
    max_iter: int = 200,
    tol: float = 1e-10,
    progress: Callable[[int, float], None] | None = None,
    use_hull: bool = True,
    constraint_hessian: str = "convexified",
    ipopt_options: dict[str, Any] | None = None,
    presolve_iter: int = PRESOLVE_ITER,
    prior_width: float = 0.0,
    fallback_bands: int = 0,
    fallback_starts: int = 0,
) -> FitResult:
    """Fit the named parameters of ``doc`` to measured FRFs (see the module docstring).

    Args:
        doc: the model; not modified.
        datasets: measured FRFs, each at its own operating point (one linearisation each).
        names: free parameters (URDF form, e.g. ``x_stage.mass``, ``x_guide_rx.stiffness``);
            :func:`bondid.model.select_parameters` expands groups and globs.
        options: cost options (default: complex-log L2, all channels and frequencies).
        lower, upper, start, use_hull: see :class:`bondid.optim.FitProblem` (bounds ``(n,)``
            SI, default :func:`default_bounds`; start ``(n,)``, default the model's values,
            clipped and projected into the feasible set with a note).
        max_iter, tol, progress, constraint_hessian, ipopt_options: see
            :func:`bondid.optim.ipopt.solve` (``progress(iteration, cost)``).
        presolve_iter: for a log cost, the IPOPT iterations of the presolve on the normalised
            complex error from which a second fit runs when the direct one did not succeed
            without phase walls (:data:`PRESOLVE_ITER`, :data:`WALL_SHARE`); 0 = none.
        prior_width: relative width τ of a weak prior toward ``doc``'s values, scaled by
            the data's noise (:mod:`bondid.optim.prior`; log costs with the l2 norm, so not the
            normalised-complex presolve); 0 = none. The reported costs are the data's alone.
        fallback_bands: when the direct fit ends above the predicted noise level, the band
            continuation with this many bands and the staged schedule from the same start
            (:meth:`bondid.optim.schedules.Strategy.starts`; ``python -m bondid.fit``'s
            default is 8); 0 = none.
        fallback_starts: random starts tried after those, in the box the prior trusts.

    Returns:
        :class:`FitResult`. IPOPT's iteration/time limits and similar stops that leave a usable
        iterate (:data:`SOFT_STATUSES`) are returned with ``success=False``; a failed solve
        that reached a feasible point is returned with ``status="failed"`` and that point.

    Raises:
        ParameterError: an unknown name or a link that does not move.
        ConfigError: a repeated name, a kinematic placement, bad bounds or start.
        SolverError: IPOPT failed without reaching a feasible point (``status`` keeps IPOPT's).
    """
    from ..optim.prior import prior_rows, with_prior_ipopt
    from ..optim.problem import FitProblem
    from ..optim.schedules import Strategy

    problem = FitProblem(
        doc, datasets, names, options=options, lower=lower, upper=upper, start=start,
        use_hull=use_hull, extra_rows=prior_rows(doc, prior_width),
    )  # fmt: skip
    strategy = Strategy(
        presolve_iter=presolve_iter, max_iter=max_iter, prior_width=prior_width,
        fallback=fallback_bands,
    )  # fmt: skip
    return search_to_noise(
        problem,
        strategy,
        n_random=fallback_starts,
        tol=tol,
        progress=progress,
        ipopt_options=with_prior_ipopt(prior_width, ipopt_options),
        constraint_hessian=constraint_hessian,
    ).result


def search_to_noise(
    problem: Any, strategy: Any, *, n_random: int = 0, seed: int = 0, start_label: str = "",
    **search_kw: Any,
) -> SearchResult:  # fmt: skip
    """The fit's search: :func:`bondid.optim.multistart.keep_best` over the strategy's starts
    (:meth:`bondid.optim.schedules.Strategy.starts`: the model's values, the fallback
    schedules, ``n_random`` random starts), stopped at the noise level, when a restart cannot
    improve or when the strategy's budget is spent. The kept search, its result's notes
    saying what ran, its iterations and time those of the whole loop (``start_label``: the
    first start's label, e.g. ``"start 2"``).

    Raises:
        SolverError: every start failed (keeps the first failure's status).
    """
    from ..cost.noise_level import noise_level_cost
    from ..optim.multistart import Budget, keep_best, search_runner
    from ..optim.noise import NoisePolicy

    starts = strategy.starts(problem, n_random=n_random, seed=seed)
    if start_label:
        starts[0] = dataclasses.replace(starts[0], label=start_label)
    outcome = keep_best(
        starts, search_runner(problem, strategy.steps, **search_kw),
        noise=NoisePolicy(noise_level_cost(problem.frf)), budget=Budget(strategy.budget()),
        max_iter=strategy.max_iter,
    )  # fmt: skip
    search = outcome.result
    sol = search.solution
    if len(outcome.attempts) == 1 and sol is not None and sol.failed and sol.kept == "start":
        raise sol.error()
    result = search.result
    note = outcome.note()
    result = dataclasses.replace(
        result, iterations=outcome.iterations,
        wall_s=sum(a.wall_s for a in outcome.attempts),
        notes=[*result.notes, note] if note else list(result.notes),
    )  # fmt: skip
    return dataclasses.replace(search, result=result)
