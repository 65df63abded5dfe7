"""One refit job: the parameter-only baseline or one candidate effect (runs in a worker).

A job augments the (parameter-refitted) model with its candidate, refits the candidate's new
parameters and the nominal ones on the training data, and evaluates the result on the held-out
data and on all data. Steps for a candidate:

1. starting point: a coarse 1-D scan of the candidate's scale (its modes sweep the band, or
   its delay/lag sweeps microseconds to milliseconds), then, for candidates with several
   scanned parameters, one coordinate scan of each; both scans also try the scales that put
   the candidate's mode at each measured mode the refitted model lacks (``Job.hints_hz``);
2. an IPOPT solve of the new parameters alone (nominal ones fixed at the refit);
3. an IPOPT solve of new and nominal parameters together;
4. a second origin, when the job carries the nominal model: the nominal model augmented with
   new parameters — the best of step 2, the candidate's initial values, or those that put its
   mode at a missing mode — each fitted new-only and then briefly with everything
   (:func:`short`); the best of those short solves continues, all parameters together
   (:func:`direct`: the core's direct schedule with its presolve on the normalised complex
   error). The parameter refit that starts every candidate may have bent nominal parameters
   to mimic the missing effect; from the nominal values they can unbend. The lower training
   objective of the two origins is kept, unless it is bought with a worse held-out figure
   (:mod:`.keep`, the rule of every choice between two refits of a job).

A rotational joint compliance whose refit ends above the noise level gets its pivot refined
(:mod:`.pivot`) and both origins refitted there; another candidate with variants gets every
other variant refitted fully (:mod:`.alternatives`); the lowest objective is kept. A
structural candidate still above it gets the restart alternation from starts at the measured
modes (:mod:`.modal_start`) when ``Job.modal``: one with several springs (soft mounts, a
flexible base) on its kept variant, then on each other variant while still above it; one with
a single spring (a joint compliance) on its kept variant only. Still above it, with
``Job.wider``, the wider search (:func:`.alternatives.wider_search`).

Every solve is the optimisation core's (:mod:`.refit`: a :class:`~bondid.optim.FitProblem`
with the candidate's parameters as more names, tied or as the FRF modifier's, the default
bounds and the noise-scaled prior of ``bondid.fit``); iteration limits are IPOPT's.

A candidate with variants (e.g. the pivots of a rotational DOF) first keeps the variant
whose step-4 start fits best (:func:`_screen_variants`). In a diagnosis the screening
(:mod:`.screen`) has already chosen the variant and a start for the new parameters
(``Job.start_new``): the job then skips the scans (step 1) and the other start options of
step 4, which cuts a full refit's IPOPT iterations by about half.

The parameter-only baseline is :func:`bondid.fit.fit` from the nominal model with the same
bounds and prior (the same problem as step 4 without a candidate), then a direct solve of
:attr:`Job.all_iter` iterations from its result (one origin: it already started from the
nominal model). It gets no second short start of its own, while a candidate's refit does; a
refit of either kind that ends well above the noise level gets the band continuation
(:func:`.rescue.rescue`).

What a job carries in and out, and its solve schedules: :mod:`.job` (:class:`Job`,
:class:`JobResult`, :func:`direct`, :func:`short`; importable from here too).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..exceptions import BondidError
from .augmented import Augmented, build, chain_of
from .effects import Candidate
from .job import Job, JobResult, direct, short, with_option
from .keep import held_of, replaces
from .refit import Refit, State

__all__ = ["Job", "JobResult", "direct", "finish", "run_job", "short"]
from .rescue import rescue
from .scan_grid import scan_grid

DAMPING_FACTORS = (1.0, 4.0)
COORD_GRID = tuple(float(x) for x in np.geomspace(1 / 30, 30, 25))


def run_job(job: Job) -> JobResult:
    """Run one job; never raises for a numerical failure of the candidate (``error`` set)."""
    t0 = time.perf_counter()
    cand = job.candidate
    label = "refit" if cand is None else cand.label
    try:
        return _run(job, t0)
    except (BondidError, np.linalg.LinAlgError, ValueError) as exc:
        return JobResult(
            label, None if cand is None else cand.effect, None if cand is None else cand.location,
            [], np.zeros(0), np.zeros(0), 0 if cand is None else len(cand.parameters),
            np.inf, np.inf, 0, np.inf, np.inf, [], "", time.perf_counter() - t0,
            error=f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}",
        )  # fmt: skip


def _setup(urdf: str, job: Job) -> Augmented:
    """The (augmented) model of ``job`` on its training data (see :mod:`.augmented`)."""
    return build(
        urdf, job.nominal, job.train, job.options, job.accepted, job.candidate, dict(job.ipopt)
    )


def _exps(cand: Candidate) -> np.ndarray:
    return np.array([p.scan for p in cand.parameters], float)


def _starts(job: Job, refit: Refit) -> list[State]:
    """Step 1 of the module docstring: start states of the candidate's new parameters."""
    cand = job.candidate
    assert cand is not None
    s0 = refit.state0
    if job.start_new:
        return [refit.with_new(s0, job.start_new)]
    if not cand.scan_grid:
        return [s0]
    exps = _exps(cand)
    grid, hints = scan_grid(cand, job.hints_hz)
    damp = (exps == 0.5).astype(float)
    v0 = refit.new_values(s0)
    bases = [refit.with_new(s0, v0 * f**damp) for f in DAMPING_FACTORS] if damp.any() else [s0]
    starts: list[State] = []
    for b in bases:
        starts += refit.scan_starts(b, exps, grid, n_starts=job.n_starts)
    starts.sort(key=refit.cost)
    starts = starts[: job.n_starts]
    scanned = [i for i, p in enumerate(cand.parameters) if p.scan == 1.0]
    if len(scanned) <= 1:
        return starts
    out = []
    for s in starts:
        for k in scanned:
            e = np.zeros(len(exps))
            e[k] = 1.0
            # relative steps, and the values that put this DOF's mode at a hint
            rel = refit.new_values(s0)[k] / refit.new_values(s)[k]
            s = refit.scan(s, e, sorted({*COORD_GRID, *(h * rel for h in hints)}))
        out.append(s)
    return out


def _candidate_fit(job: Job, refit: Refit) -> tuple[State, float, Any, list[np.ndarray]]:
    """Steps 1–3 of the module docstring from the parameter refit; returns the best state,
    its cost and search, and the new-only solutions of the starts (SI, best first)."""
    best: tuple[State, float, Any] | None = None
    new_only: list[tuple[float, np.ndarray]] = []
    for s in _starts(job, refit):
        s, c = refit.solve_new(s, job.new_iter)
        new_only.append((c, refit.new_values(s)))
        s, c, res = refit.solve(s, direct(job.all_iter))
        if best is None or c < best[1]:
            best = (s, c, res)
    assert best is not None
    new_only.sort(key=lambda t: t[0])
    return best[0], best[1], best[2], [v for _, v in new_only]


def _alt_start(
    job: Job, refit: Refit, found: list[np.ndarray], only: int | None = None
) -> tuple[State, float, int]:
    """Start of the second origin and its training cost. Options for the new parameters: the
    best found from the parameter refit, the candidate's initial values, and those that put
    its mode at each missing mode (``Job.hints_hz``); each is fitted alone (nominal values
    fixed), then briefly with everything (:func:`short`: ``screen_iter`` iterations of the
    normalised complex error, as many of the complex-log error). The best after that short
    solve is kept: which basin a start leads to shows only once the nominal parameters move
    too. The parameter-only baseline (no candidate) gets the same short solve from the
    nominal values. ``only``: try that option alone. Returns the start, its cost and the
    index of its option."""
    cand = job.candidate
    s0 = refit.state0
    v0 = refit.new_values(s0)
    options = [*found[:1], v0]
    if cand is not None and cand.ref_hz:
        exps = _exps(cand)
        options += [v0 * (f / cand.ref_hz) ** (2.0 * exps) for f in job.hints_hz]
    best: tuple[float, State, int] | None = None
    for k, new in enumerate(options):
        if only is not None and k != only:
            continue
        s = refit.with_new(s0, new)
        if refit.own:
            s, _ = refit.solve_new(s, job.new_iter)
        s, c, _ = refit.solve(s, short(job.screen_iter))
        if best is None or c < best[0]:
            best = (c, s, k)
    assert best is not None
    return best[1], best[0], best[2]


def _screen_variants(job: Job) -> tuple[Job, float]:
    """The job with its candidate replaced by the best of the candidate and its variants
    (:attr:`~.effects.base.Candidate.variants`), by the training cost of the second origin's
    start (:func:`_alt_start`, from the nominal model when the job has one, else from the
    parameter refit). The candidate itself tries every starting option; its variants (which
    differ in how the new DOF couples, not in its frequency) only the option it chose. From
    the parameter refit alone the variants hardly differ: it has already bent the nominal
    parameters toward whatever the missing DOF does. Returns the job and the best screening
    cost."""
    cand = job.candidate
    assert cand is not None
    best: tuple[float, Candidate] | None = None
    urdf = job.alt_urdf if job.alt_urdf is not None else job.urdf
    pick: int | None = None
    for option in (cand, *cand.variants):
        sub = with_option(job, option)
        aug = _setup(urdf, sub)
        _, cost, k = _alt_start(sub, aug.refit, [], only=pick)
        pick = k
        if best is None or cost < best[0]:
            best = (cost, option)
    assert best is not None
    return with_option(job, best[1]), best[0]


def _fit(job: Job) -> tuple[Augmented, State, Any]:
    """Both origins of the module docstring; the better (lower training objective, without a
    worse held-out figure: :func:`.keep.replaces`)."""
    cand = job.candidate
    aug = _setup(job.urdf, job)
    found: list[np.ndarray] = []
    if cand is None:
        s, c, res = aug.refit.solve(aug.refit.state0, direct(job.all_iter, job.presolve_iter))
    else:
        s, c, res, found = _candidate_fit(job, aug.refit)
    if job.alt_urdf is not None:
        # second origin: the nominal model (with the best new parameters found above). The
        # parameter refit may have bent the nominal parameters to mimic the missing effect.
        alt = _setup(job.alt_urdf, job)
        # with a screening start: only the first option, the new parameters the first origin
        # found from it (not the screening's own start moved to this origin)
        only = 0 if job.start_new else None
        s_a = _alt_start(job, alt.refit, found, only)[0]
        s_a, c_a, res_a = alt.refit.solve(s_a, direct(job.alt_iter, job.presolve_iter))
        if replaces(job, c, held_of(job, aug, res), c_a, held_of(job, alt, res_a)):
            aug, s, res = alt, s_a, res_a
    return aug, s, res


#: the note of a stuck refit whose job does not allow the modal step (``Job.modal``)
MODAL_SKIPPED = "not run: the screening did not rank the candidate among the best of its step"


def _run(job: Job, t0: float) -> JobResult:
    from .alternatives import stuck
    from .modal_start import applies, modal_step, single
    from .pivot import is_rotational_compliance

    extra: dict[str, Any] = {}
    if job.candidate is not None and job.candidate.variants:
        job, _ = _screen_variants(job)
        assert job.candidate is not None
        extra["variant"] = job.candidate.description
    aug, state, res = _fit(job)
    # whether the refit is stuck, judged again only after a step that moved it
    is_stuck = job.candidate is not None and stuck(job, aug, state, res)
    if is_stuck:
        from .alternatives import at_refined_pivot, other_variants

        assert job.candidate is not None
        if is_rotational_compliance(job.candidate):
            job, aug, state, res, extra["pivot"] = at_refined_pivot(job, aug, state, res)
        else:
            job, aug, state, res = other_variants(job, aug, state, res, extra)
        extra["variant"] = job.candidate.description  # type: ignore[union-attr]
        is_stuck = stuck(job, aug, state, res)
    if is_stuck and applies(job.candidate) and not job.modal:
        extra["modal starts"] = MODAL_SKIPPED
    elif is_stuck and applies(job.candidate):
        assert job.candidate is not None
        job, aug, state, res, extra["modal starts"] = modal_step(
            job, aug, state, res, others=not single(job.candidate)
        )
        extra["variant"] = job.candidate.description  # type: ignore[union-attr]
        is_stuck = stuck(job, aug, state, res)
        if is_stuck and is_rotational_compliance(job.candidate):
            # the spring now sits at a mode: the pivot judged from there (warm)
            from .alternatives import at_refined_pivot

            job, aug, state, res, extra["pivot after modal"] = at_refined_pivot(
                job, aug, state, res, warm=True
            )
            extra["variant"] = job.candidate.description  # type: ignore[union-attr]
            is_stuck = stuck(job, aug, state, res)
    if is_stuck and job.modal and is_rotational_compliance(job.candidate):
        # still stuck: each pivot judged with the nominal parameters free too (the ones the
        # first pivot bent move with it; gantry/jcr/acc's true candidate, stop 32: held-out
        # 2.48 -> 0.48 dB against a noise level of 0.53, the pivot 5 mm from the truth's)
        from .alternatives import at_refined_pivot

        job, aug, state, res, extra["pivot, all parameters"] = at_refined_pivot(
            job, aug, state, res, warm=True, full=True
        )
        extra["variant"] = job.candidate.description  # type: ignore[union-attr]
        is_stuck = stuck(job, aug, state, res)
    from_nominal = False
    if job.wider and is_stuck:
        from .alternatives import wider_search

        aug, state, res, extra["wider"] = wider_search(job, aug, state, res)
        from_nominal = job.alt_urdf is not None
    return finish(job, aug, state, res, extra, t0, continuation=not from_nominal)


def finish(
    job: Job, aug: Augmented, state: State, res: Any, extra: dict[str, Any], t0: float,
    continuation: bool = True,
) -> JobResult:  # fmt: skip
    """The rescue (:func:`.rescue.rescue`; ``continuation``: with its band continuation) from
    the job's best refit, then its figures on held-out and all data."""
    from .evaluate import figures
    from .rescue import noise_ratio_at

    cand = job.candidate
    refit = aug.refit
    state, res, note = rescue(
        refit, state, res, job.presolve_iter, job.alt_iter, continuation=continuation,
        always=job.fallbacks_always,
    )  # fmt: skip
    if note:
        extra["rescue"] = note
    fit, std_theta = refit.result(res)
    theta = refit.state_theta(fit)
    train = refit.at(state)
    r = train.residual(train.z0)[: train.n_residuals]
    held = figures(refit, fit, theta, job.heldout, job.options)
    full = figures(refit, fit, theta, job.full, job.options)
    new_vals = refit.new_values(state, own=False)
    return JobResult(
        label="refit" if cand is None else cand.label,
        effect=None if cand is None else cand.effect,
        location=None if cand is None else cand.location,
        names=aug.names,
        values=np.r_[fit.fitted[: aug.n_nominal], new_vals],
        std=np.r_[fit.std[: aug.n_nominal], refit.new_std(fit, std_theta)],
        n_new=len(refit.new),
        train_rms=float(np.sqrt(r @ r)),
        heldout_rms=float(np.sqrt(held.cost)),
        n_train=int(r.size),
        heldout_db_rms=held.db_rms,
        db_rms=full.db_rms,
        full_H=full.H,
        urdf=fit.document.to_string(),
        wall_s=time.perf_counter() - t0,
        status=fit.status,
        extra=extra,
        db_rms_unweighted=full.db_rms_unweighted,
        chain=chain_of(job.accepted, cand, new_vals),
        n_own=0 if cand is None else len(cand.parameters),
        candidate=cand, objective=refit.cost(state), noise_ratio=noise_ratio_at(refit, state),
    )  # fmt: skip
