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
:mod:`bondid.fit.parameterisation`): ``m = e^{2α}``, ``c = t`` and the second moment about the
CoM ``Σ_c = V Vᵀ`` — so mass bounds are bounds on α, CoM bounds are bounds on ``t``, the
CoM-in-hull constraint ``A c ≤ b`` is linear, and a fixed mass, CoM or full inertia tensor is a
fixed variable. Fixed inertia components of a body whose other components are free are
equality constraints (symbolic in CasADi); bounds on free inertia components are inequality
constraints on the same expressions. Joint stiffness and damping are scaled by their starting
magnitude and bounded (≥ 0 by default). See :mod:`bondid.fit.parameterisation` and
:mod:`bondid.fit.nlp`.

The objective ``‖r‖²`` (:class:`bondid.cost.FrfProblem`, exact Jacobian in numpy) is given to
IPOPT with its gradient ``2Jᵀr`` and a Gauss–Newton Hessian ``2JᵀJ`` of the Lagrangian (plus the
constraints' symbolic Hessians, convexified): the least-squares structure converges in tens of
iterations where a quasi-Newton Hessian needs hundreds. It is a LOCAL method: from ±30 % on
every parameter the complex-log cost of lightly damped modes has other basins (measured on the
bonder); use the band continuation (:mod:`bondid.fit.continuation`), multistart or
staged fitting for global search. A log-cost fit runs twice, from
the start and from a start presolved on the normalised complex error (:data:`PRESOLVE_ITER`),
and keeps the better: the log cost has walls where a cross term changes sign. The second fit
is skipped when the direct one succeeded with the phase matched nearly everywhere
(:data:`WALL_SHARE`).

Kinematic joint placements are not fitted (they enter ``M`` non-linearly through Pinocchio's
numbers, which are constants here); a name that asks for one raises
:class:`bondid.exceptions.ConfigError`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .. import interrupt
from ..consistency.log_cholesky import pi_from_theta
from ..consistency.pseudo_inertia import second_moment_com
from ..cost.problem import CostOptions, FrfProblem
from ..data.measurement import FrfData
from ..exceptions import ConfigError, ParameterError, SolverError
from ..linear.parameter_map import ParameterMap
from ..model.document import UrdfDocument
from ..model.parameters import COM_AXES, get_parameters, set_link_inertial, set_parameter
from .bounds import default_bounds, infos_by_name, link_hulls
from .nlp import Evaluator, FitNlp, NlpOutcome
from .parameterisation import _IJ, Layout
from .prior import PRIOR_IPOPT, make_prior, shape_bounds
from .result import FitResult, parameter_statistics

#: IPOPT iterations of the presolve on the normalised complex error (eq. 6.3 of the seed) that
#: starts the second of the two fits a log-cost fit runs. The log error is infinite where the
#: model has a zero the data lack, so where a cross term's static gain must change sign on the
#: way to the optimum (a CoM coordinate a fraction of a millimetre off) the log cost has a wall
#: a local method cannot cross; the normalised error is bounded (−1) and smooth there. Neither
#: start is always better, hence both: on the bundled data (all 50 parameters from the nominal
#: model, default bounds) the direct fit stops with Infeasible_Problem_Detected at cost 7.60 and
#: the presolved one converges to 7.430 (the truth's cost: 7.428); on noise-free data from a
#: ±10–30 % start the direct fit reaches the truth and the presolved one a local minimum.
PRESOLVE_ITER = 60
#: the presolved second fit runs only when the direct one did not succeed or left more than
#: this share of the (coherence) weight beyond 90° of phase error — the signature of a wall;
#: a fit that matches the phase nearly everywhere does not sit behind one (the second fit
#: then costs time for nothing: on tools/bench_fit.py it took the fit from ~16 s to 79 s)
WALL_SHARE = 0.01
#: residual kinds whose cost is a log error (these get the presolve)
LOG_KINDS = frozenset({"complex_log", "log_magnitude"})

#: IPOPT statuses counted as success.
SUCCESS_STATUSES = frozenset({"Solve_Succeeded", "Solved_To_Acceptable_Level"})
#: IPOPT statuses returned with ``success=False`` (the iterate is usable); others raise.
SOFT_STATUSES = frozenset(
    {
        "Maximum_Iterations_Exceeded",
        "Maximum_CpuTime_Exceeded",
        "Maximum_WallTime_Exceeded",
        "Search_Direction_Becomes_Too_Small",
        "User_Requested_Stop",
        "Feasible_Point_Found",
    }
)
_ACTIVE_TOL = 1e-6  # slack (scaled units) below which a bound or inequality counts as active
_SINGULAR = 1e-6  # min/max principal second moment below which a body is on the boundary


@dataclass
class FitSetup:
    """Everything :func:`fit` builds before calling IPOPT (also used by tests and tools)."""

    names: list[str]
    problem: FrfProblem
    layout: Layout
    evaluator: Evaluator
    nlp: FitNlp
    z0: np.ndarray
    lbz: np.ndarray
    ubz: np.ndarray
    initial: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    var_labels: list[tuple[str, int]]
    g_labels: list[str]
    notes: list[str]


def prepare(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    names: Sequence[str],
    *,
    options: CostOptions | None = None,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    start: np.ndarray | None = None,
    use_hull: bool = True,
    constraint_hessian: str = "convexified",
    prior_width: float = 0.0,
) -> FitSetup:
    """Build the problem, the decision vector, the bounds and the CasADi NLP (no solve).

    Arguments as for :func:`fit`. Raises the same input errors.
    """
    names = list(names)
    if not names:
        raise ConfigError("no parameters to fit; give at least one name")
    infos = infos_by_name(doc, names)
    n = len(names)
    notes: list[str] = []
    if lower is None or upper is None:
        f_max = max((float(np.max(d.freq_hz)) for d in datasets), default=None)
        dlo, dhi = default_bounds(doc, names, f_max_hz=f_max)
        lower = dlo if lower is None else lower
        upper = dhi if upper is None else upper
    lo = np.asarray(lower, dtype=float).reshape(-1)
    hi = np.asarray(upper, dtype=float).reshape(-1)
    if lo.shape != (n,) or hi.shape != (n,):
        raise ConfigError(f"bounds have shapes {lo.shape}, {hi.shape}; expected ({n},) each")
    bad = [names[i] for i in np.flatnonzero(~(lo <= hi))]
    if bad:
        raise ConfigError(f"lower bound > upper bound (or NaN) for {', '.join(bad)}")
    for i, info in enumerate(infos):
        if info.kind == "mass" and hi[i] <= 0:
            raise ConfigError(f"{info.name}: upper bound {hi[i]:g} kg leaves no positive mass")
    p0 = get_parameters(doc, names) if start is None else np.asarray(start, dtype=float)
    if p0.shape != (n,) or not np.all(np.isfinite(p0)):
        raise ConfigError(f"start must be {n} finite values, got shape {np.shape(p0)}")
    clipped = np.clip(p0, lo, hi)
    if np.any(clipped != p0):
        outside = [names[i] for i in np.flatnonzero(clipped != p0)]
        notes.append(f"start outside the bounds, clipped: {', '.join(outside)}")
    p0 = clipped
    problem = FrfProblem(doc, datasets, options)
    affine = problem.affines[0]
    for info in infos:
        if info.is_inertial and info.owner not in affine.bodies:
            raise ParameterError(f"{info.name}: link {info.owner!r} does not move; cannot fit it")
    links = sorted({i.owner for i in infos if i.is_inertial})
    hulls = link_hulls(doc, links) if use_hull else dict.fromkeys(links)
    for link, h in hulls.items():
        if use_hull and h is None:
            notes.append(f"{link}: no collision or visual geometry, so no CoM-in-hull constraint")
    layout = Layout(doc, affine, infos, hulls)
    z0 = layout.start(doc, p0, lo, hi)
    notes.extend(layout.notes)
    lbz, ubz, var_labels = layout.variable_bounds(lo, hi)
    if prior_width > 0:
        var_labels += shape_bounds(doc, layout, lbz, ubz)
    prior = make_prior(doc, layout, problem, prior_width, notes)
    evaluator = Evaluator(problem, layout, prior=prior)
    g_labels: list[str] = []

    def constraints(zs: Any) -> tuple[Any, np.ndarray, np.ndarray]:
        g, lbg, ubg, labels, _ = layout.constraints(zs, lo, hi)
        g_labels.extend(labels)
        return g, lbg, ubg

    nlp = FitNlp(evaluator, layout.size, constraints, constraint_hessian)
    return FitSetup(
        names,
        problem,
        layout,
        evaluator,
        nlp,
        z0,
        lbz,
        ubz,
        p0,
        lo,
        hi,
        var_labels,
        g_labels,
        notes,
    )


def _active(setup: FitSetup, out: NlpOutcome) -> list[str]:
    z = out.z
    active: list[str] = []
    for name, i in setup.var_labels:
        lo, hi = setup.lbz[i], setup.ubz[i]
        if lo == hi:
            continue
        if np.isfinite(lo) and z[i] - lo <= _ACTIVE_TOL * max(1.0, abs(lo)):
            active.append(f"{name} lower bound")
        if np.isfinite(hi) and hi - z[i] <= _ACTIVE_TOL * max(1.0, abs(hi)):
            active.append(f"{name} upper bound")
    for k, label in enumerate(setup.g_labels):
        lo, hi, g = setup.nlp.lbg[k], setup.nlp.ubg[k], out.g[k]
        if lo == hi:
            continue  # equality (a fixed parameter): always active, not reported
        if label.endswith("com in hull"):
            name = label
        elif np.isfinite(lo) and g - lo <= _ACTIVE_TOL * max(1.0, abs(lo)):
            name = f"{label} lower bound"
        elif np.isfinite(hi) and hi - g <= _ACTIVE_TOL * max(1.0, abs(hi)):
            name = f"{label} upper bound"
        else:
            continue
        if label.endswith("com in hull") and hi - g > _ACTIVE_TOL:
            continue
        if name not in active:
            active.append(name)
    for blk in setup.layout.blocks:
        sigma = np.linalg.eigvalsh(second_moment_com(pi_from_theta(blk.theta(z))))
        if sigma[0] <= _SINGULAR * sigma[-1]:
            active.append(f"{blk.link} pseudo-inertia")
    return active


def _fitted_document(doc: UrdfDocument, setup: FitSetup, z: np.ndarray, p: np.ndarray):
    out = doc.copy()
    for link, vals in setup.layout.body_values(z).items():
        blk = next(b for b in setup.layout.blocks if b.link == link)
        vals = {**vals, **blk.fixed}  # fixed parameters keep their exact URDF values
        c = np.array([vals[f"com.{a}"] for a in COM_AXES])
        I_c = np.zeros((3, 3))
        for comp, (r, s) in _IJ.items():
            I_c[r, s] = I_c[s, r] = vals[f"inertia.{comp}"]
        set_link_inertial(out, link, vals["mass"], c, I_c)
    for jv in setup.layout.joints:
        set_parameter(out, jv.name, max(float(p[jv.name_index]), 0.0))
    for gv in setup.layout.gains:
        set_parameter(out, gv.name, float(p[gv.name_index]))
    return out


def _ipopt(setup: FitSetup, **solve_kw: Any) -> NlpOutcome:
    """Run IPOPT on a prepared problem; hard failures become :class:`SolverError`."""
    try:
        out = setup.nlp.solve(setup.z0, setup.lbz, setup.ubz, **solve_kw)
    except RuntimeError as exc:
        interrupt.check()  # CasADi turned a Ctrl-C into an error: it is an interrupt
        raise SolverError(f"IPOPT failed: {str(exc).splitlines()[0]}", status="exception") from exc
    if out.status not in SUCCESS_STATUSES | SOFT_STATUSES:
        err = SolverError(
            f"IPOPT stopped with {out.status} after {out.iterations} iterations "
            f"(cost {out.cost:.6g}); check the bounds and the start",
            status=out.status,
        )
        err.outcome = out  # type: ignore[attr-defined]  # its best iterate (see fit)
        err.setup = setup  # type: ignore[attr-defined]
        raise err
    return out


def _best_iterate(error: SolverError) -> tuple[FitSetup, NlpOutcome, int] | None:
    """The lowest-cost feasible iterate of a failed IPOPT run as an outcome (or None)."""
    out: NlpOutcome | None = getattr(error, "outcome", None)
    if out is None or out.best_z is None:
        return None
    return error.setup, replace(out, z=out.best_z, cost=out.best_cost), 0  # type: ignore[attr-defined]


def _solution(
    doc: UrdfDocument, setup: FitSetup, out: NlpOutcome
) -> tuple[np.ndarray, UrdfDocument, ParameterMap, np.ndarray]:
    """A fit's solution as named values (clipped to the bounds), the fitted document, its
    parameter map and the values the map reads (for :class:`bondid.cost.FrfProblem`)."""
    fitted = np.clip(setup.layout.named(out.z), setup.lower, setup.upper)
    fitted_doc = _fitted_document(doc, setup, out.z, fitted)
    affine = setup.problem.affines[0].with_values(*setup.layout.values(out.z))
    pmap = ParameterMap(fitted_doc, affine, setup.names)
    return fitted, fitted_doc, pmap, get_parameters(fitted_doc, setup.names)


def _wall_fraction(doc: UrdfDocument, setup: FitSetup, out: NlpOutcome) -> float:
    """Phase-wall share (:meth:`bondid.cost.FrfProblem.phase_wall_fraction`) at a fit's
    solution; 1.0 when IPOPT did not succeed (the presolve then always runs)."""
    if out.status not in SUCCESS_STATUSES:
        return 1.0
    _, _, pmap, x = _solution(doc, setup, out)
    return setup.problem.phase_wall_fraction(pmap, x)


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
) -> FitResult:
    """Fit the named parameters of ``doc`` to measured FRFs (see the module docstring).

    Args:
        doc: the model; not modified.
        datasets: measured FRFs, each at its own operating point (one linearisation each).
        names: free parameters (URDF form, e.g. ``x_stage.mass``, ``x_guide_rx.stiffness``);
            use :func:`bondid.model.select_parameters` to expand groups and globs.
        options: cost options (default: complex-log L2, all channels and frequencies).
        lower, upper: bounds ``(n,)`` in SI units (default :func:`default_bounds`; ±inf allowed).
        start: starting values ``(n,)`` (default: the model's values); clipped to the bounds,
            and each fitted body is projected into the feasible set (consistent, CoM inside its
            hull) with a note in ``FitResult.notes`` when it was not.
        max_iter, tol: IPOPT's iteration limit and convergence tolerance.
        progress: ``progress(iteration, cost)`` called at every IPOPT iteration.
        use_hull: constrain each fitted body's CoM to the convex hull of its collision geometry.
        constraint_hessian: ``"convexified"`` (default), ``"exact"`` or ``"none"`` (see
            :mod:`bondid.fit.nlp`).
        ipopt_options: extra IPOPT options (e.g. ``{"max_wall_time": 60}``).
        presolve_iter: for a log cost (``complex_log``, ``log_magnitude``), a second fit runs
            from a start presolved with this many IPOPT iterations on the normalised complex
            error, and the fit with the lower final cost is kept (see :data:`PRESOLVE_ITER`),
            unless the direct fit succeeded without phase walls (:data:`WALL_SHARE`);
            0 = the direct fit only.
        prior_width: relative width τ of a weak prior toward ``doc``'s values, scaled by
            the data's noise (:mod:`bondid.fit.prior`; log costs with the l2 norm); 0 = none.
            The presolve runs without it. The reported costs are the data's alone.

    Returns:
        :class:`FitResult`. IPOPT's iteration/time limits and similar stops that leave a usable
        iterate (:data:`SOFT_STATUSES`) are returned with ``success=False``.

    Raises:
        ParameterError: an unknown name or a link that does not move.
        ConfigError: a repeated name, a kinematic placement, bad bounds or start.
        SolverError: IPOPT failed (infeasible, restoration failed, invalid numbers ...);
            ``status`` keeps IPOPT's ``return_status``.
    """
    t0 = time.perf_counter()
    if prior_width > 0:
        ipopt_options = {**PRIOR_IPOPT, **(ipopt_options or {})}
    kw: dict[str, Any] = {"lower": lower, "upper": upper, "use_hull": use_hull}
    setup = prepare(
        doc, datasets, names, options=options, start=start,
        constraint_hessian=constraint_hessian, prior_width=prior_width, **kw,
    )  # fmt: skip
    cost_initial = setup.evaluator.cost(setup.z0)
    initial = setup.initial.copy()
    notes = list(setup.notes)
    solve_kw: dict[str, Any] = {"max_iter": max_iter, "tol": tol, "progress": progress,
                                "ipopt_options": ipopt_options}  # fmt: skip
    runs: list[tuple[FitSetup, NlpOutcome, int]] = []
    error: SolverError | None = None
    try:
        runs.append((setup, _ipopt(setup, **solve_kw), 0))
    except SolverError as exc:
        error = exc
    presolve = presolve_iter > 0 and setup.problem.options.kind in LOG_KINDS
    walls = _wall_fraction(doc, setup, runs[0][1]) if presolve and runs else 1.0
    if presolve and walls <= WALL_SHARE:
        notes.append(
            f"presolve skipped: the direct fit succeeded with {walls:.1%} of the weight beyond"
            f" 90° of phase error (the presolve runs above {WALL_SHARE:.0%})"
        )
    elif presolve:
        pre_options = replace(setup.problem.options, kind="normalised_complex", norm="l2")
        try:
            pre = fit(
                doc, datasets, names, options=pre_options, start=start, max_iter=presolve_iter,
                tol=tol, constraint_hessian=constraint_hessian, ipopt_options=ipopt_options,
                presolve_iter=0, **kw,
            )  # fmt: skip
            pre_setup = prepare(
                doc, datasets, names, options=options, start=pre.fitted,
                constraint_hessian=constraint_hessian, prior_width=prior_width, **kw,
            )  # fmt: skip
            runs.append((pre_setup, _ipopt(pre_setup, **solve_kw), pre.iterations))
        except SolverError as exc:
            notes.append(f"the presolved fit failed ({exc.status}); kept the direct one")
            error = error or exc
    failure = None
    if not runs:
        assert error is not None
        kept = _best_iterate(error)
        if kept is None:
            raise error
        runs.append(kept)
        failure = str(error)
        notes.append(f"IPOPT failed ({error.status}); kept its best feasible iterate")
    best = min(range(len(runs)), key=lambda k: runs[k][1].cost)
    setup, out, pre_iterations = runs[best]
    if len(runs) > 1:
        costs = ", ".join(f"{run[1].cost:.6g}" for run in runs)
        which = "presolved" if best == 1 else "direct"
        notes.append(
            f"two fits: direct and after {runs[-1][2]} presolve iterations on the normalised "
            f"complex error; final costs {costs}; kept the {which} one"
        )
    fitted, fitted_doc, pmap, x = _solution(doc, setup, out)
    r, J = setup.problem.residual_and_jacobian(pmap, x)
    std, corr = parameter_statistics(J, r)
    return FitResult(
        status="failed" if failure else out.status,
        success=failure is None and out.status in SUCCESS_STATUSES,
        solver_status=out.status,
        failure=failure,
        names=list(setup.names),
        initial=initial,
        fitted=fitted,
        lower=setup.lower.copy(),
        upper=setup.upper.copy(),
        std=std,
        correlation=corr,
        cost_initial=cost_initial,
        cost_final=float(r @ r),
        cost_name=setup.problem.options.name,
        iterations=out.iterations + pre_iterations,
        wall_s=time.perf_counter() - t0,
        cost_history=list(out.history),
        active_constraints=_active(setup, out),
        document=fitted_doc,
        notes=notes,
    )
