"""One refit job: the parameter-only baseline or one candidate effect (runs in a worker).

A job augments the (parameter-refitted) model with its candidate, refits the candidate's new
parameters and the nominal ones on the training data, and evaluates the result on the held-out
data and on all data. Steps for a candidate:

1. starting point: a coarse 1-D scan of the candidate's scale (its modes sweep the band, or
   its delay/lag sweeps microseconds to milliseconds), then, for candidates with several
   scanned parameters, one coordinate scan of each; both scans also try the scales that put
   the candidate's mode at each measured mode the refitted model lacks (``Job.hints_hz``);
2. bounded least squares of the new parameters alone (nominal ones fixed at the refit);
3. bounded least squares of new and nominal parameters together;
4. a second origin, when the job carries the nominal model: the nominal model augmented with
   new parameters — the best of step 2, the candidate's initial values, or those that put its
   mode at a missing mode — each fitted new-only and then briefly with everything; the best
   of those short solves continues, all parameters together with the normalised complex
   error first and the complex-log error after (see :meth:`.engine.Refit.solve`). The
   parameter refit that starts every candidate may have bent nominal parameters to mimic the
   missing effect (including the proportions of the inertia tensors, which the refit
   variables keep); from the nominal values they can unbend. The lower training cost of the
   two origins is kept.

A candidate with variants (e.g. the pivots of a rotational DOF) first keeps the variant
whose step-4 start fits best (:func:`_screen_variants`). In a diagnosis the screening
(:mod:`.screen`) has already chosen the variant and a start for the new parameters
(``Job.start_new``): the job then skips the scans (step 1) and the other start options of
step 4, which cuts a full refit's evaluations by about half.

The parameter-only baseline gets the same treatment (step 3 from the parameter refit, and
step 4 from the nominal model), so that candidates do not win by a better optimiser alone.

Everything a job needs travels in :class:`Job` (URDF text, data, plain values), so it pickles
to a worker process.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..exceptions import BondidError
from ..model.parameters import set_parameter
from .augmented import Augmented, build, with_values
from .effects import Candidate
from .engine import Refit
from .variables import Variable

DAMPING_FACTORS = (1.0, 4.0)
COORD_GRID = tuple(float(x) for x in np.geomspace(1 / 30, 30, 25))


@dataclass
class Job:
    """Inputs of one refit job (see the module docstring)."""

    urdf: str
    nominal: list[Variable]
    train: list[FrfData]
    heldout: list[FrfData]
    full: list[FrfData]
    candidate: Candidate | None = None
    options: CostOptions = field(default_factory=CostOptions)
    max_nfev_new: int = 10
    n_starts: int = 3
    max_nfev_all: int = 30
    alt_urdf: str | None = None
    alt_nominal: list[Variable] | None = None
    max_nfev_alt: int = 150
    pre_nfev: int = 30
    hints_hz: tuple[float, ...] = ()
    screen_nfev: int = 10
    accepted: tuple[Candidate, ...] = ()
    #: the candidate's new parameters (log units) from its screening: when given, the refit
    #: starts there (no scan) from both origins
    start_new: tuple[float, ...] = ()


@dataclass
class JobResult:
    """Outputs of one job.

    Attributes:
        label: ``effect@location`` or ``"refit"`` for the baseline.
        names, values, std: refit variables (nominal first, then new), SI.
        n_new: number of new parameters.
        train_rms, heldout_rms: weighted complex-log RMS [dB] (the data's coherence, which
            the diagnosis fills with the information weights).
        n_train: number of training residuals.
        heldout_db_rms, db_rms: the weighted ``db_rms`` ``sqrt(Σ w e² / Σ w)`` on held-out /
            all data [dB], over the used channels.
        db_rms_unweighted: the plain RMS over the points with weight ≥ 0.5 [dB].
        full_H: model FRF per full data set (for the gap report and plots).
        urdf: the refitted (augmented) model as URDF text.
        error: why the job failed ("" when it did not).
    """

    label: str
    effect: str | None
    location: str | None
    names: list[str]
    values: np.ndarray
    std: np.ndarray
    n_new: int
    train_rms: float
    heldout_rms: float
    n_train: int
    heldout_db_rms: float
    db_rms: float
    full_H: list[np.ndarray]
    urdf: str
    wall_s: float
    status: str = ""
    error: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    db_rms_unweighted: float = float("nan")
    #: the effects of this model, in the order added, starting at their fitted values (the
    #: accepted effects the job carried, then its candidate with the variant it kept)
    chain: tuple[Candidate, ...] = ()
    #: number of this job's own candidate parameters (the last ``n_own`` of ``values``)
    n_own: int = 0


def _db_rms(refit: Refit, u: np.ndarray, weighted: bool = True) -> float:
    """Weighted ``db_rms`` (weights = the data's coherence) over the used channels, or the
    unweighted one over the points of weight ≥ 0.5."""
    from .gap import gap_report
    from .split import mask_incoherent

    chans = refit.problem.options.channels
    if weighted:
        sets = [b.data for b in refit.problem.blocks]
        return float(
            gap_report(sets, refit.frf_for_data(u), channels=chans, weighting="coherence").db_rms
        )
    sets = [mask_incoherent(b.data) for b in refit.problem.blocks]
    return float(gap_report(sets, refit.frf_for_data(u), channels=chans).db_rms)


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


def _setup(urdf: str, nominal: list[Variable], job: Job) -> Augmented:
    """The (augmented) model of ``job`` on its training data (see :mod:`.augmented`)."""
    return build(urdf, nominal, job.train, job.options, job.accepted, job.candidate)


def _candidate_fit(job: Job, refit: Refit, n_nom: int) -> tuple[np.ndarray, Any, list]:
    """Steps 1–3 of the module docstring from the parameter refit; returns the best
    ``(u, outcome)`` and the new-parameter-only solutions of the starts (log units)."""
    cand = job.candidate
    assert cand is not None
    n_var = len(refit.variables)
    new_idx = list(range(n_nom, n_var))
    exps = np.zeros(n_var)
    exps[n_nom:] = [p.scan for p in cand.parameters]
    u = refit.u0.copy()
    starts = [u]
    hint_factors = [(f / cand.ref_hz) ** 2 for f in job.hints_hz] if cand.ref_hz else []
    if job.start_new:
        u[n_nom:] = np.clip(job.start_new, refit.lower[n_nom:], refit.upper[n_nom:])
        starts, hint_factors = [u], []
    elif cand.scan_grid:
        grid = tuple(sorted({*cand.scan_grid, *hint_factors}))
        damp = (exps == 0.5).astype(float)
        bases = [u + damp * np.log(f) for f in DAMPING_FACTORS] if damp.any() else [u]
        starts = []
        for b in bases:
            starts += refit.scan_starts(b, exps, grid, n_starts=job.n_starts)
        starts.sort(key=refit.cost)
        starts = starts[: job.n_starts]
    scanned = [n_nom + i for i, p in enumerate(cand.parameters) if p.scan == 1.0]
    best: tuple[np.ndarray, Any] | None = None
    new_only: list[tuple[float, np.ndarray]] = []
    for u_s in starts:
        if len(scanned) > 1 and not job.start_new:
            for k in scanned:
                e = np.zeros(n_var)
                e[k] = 1.0
                # relative steps, and the values that put this DOF's mode at a hint
                at_hints = [h * np.exp(u[k] - u_s[k]) for h in hint_factors]
                u_s = refit.scan(u_s, e, sorted({*COORD_GRID, *at_hints}))
        u_s, o_s = refit.solve(u_s, free=new_idx, max_nfev=job.max_nfev_new)
        new_only.append((o_s.cost, u_s[n_nom:]))
        u_s, o_s = refit.solve(u_s, max_nfev=job.max_nfev_all)
        if best is None or o_s.cost < best[1].cost:
            best = (u_s, o_s)
    assert best is not None
    new_only.sort(key=lambda t: t[0])
    return best[0], best[1], [v for _, v in new_only]


def _alt_start(
    job: Job, refit: Refit, n_nom: int, found: list[np.ndarray], only: int | None = None
) -> tuple[np.ndarray, float, int]:
    """Start of the second origin and its training cost. Options for the new parameters: the
    best found from the parameter refit, the candidate's initial values, and those that put
    its mode at each missing mode (``Job.hints_hz``); each is fitted alone (nominal values
    fixed), then briefly with everything (``screen_nfev`` evaluations of the normalised
    complex error, as many of the complex-log error). The best after that short solve is
    kept: which basin a start leads to shows only once the nominal parameters move too.
    The parameter-only baseline (no candidate) gets the same short solve from the nominal
    values, so that candidates do not win by a longer optimisation. ``only``: try that option
    alone. Returns the start, its cost and the index of its option."""
    cand = job.candidate
    new_idx = list(range(n_nom, len(refit.u0)))
    lo, hi = refit.lower[n_nom:], refit.upper[n_nom:]
    options = [np.clip(v, lo, hi) for v in found[:1]] + [refit.u0[n_nom:]]
    if cand is not None and cand.ref_hz:
        exps = np.array([p.scan for p in cand.parameters])
        for f in job.hints_hz:
            options.append(np.clip(refit.u0[n_nom:] + exps * 2.0 * np.log(f / cand.ref_hz), lo, hi))
    best: tuple[float, np.ndarray, int] | None = None
    for k, new in enumerate(options):
        if only is not None and k != only:
            continue
        u = refit.u0.copy()
        u[n_nom:] = new
        if new_idx:
            u, _ = refit.solve(u, free=new_idx, max_nfev=job.max_nfev_new)
        u, o = refit.solve(u, max_nfev=job.screen_nfev, pre_nfev=job.screen_nfev)
        if best is None or o.cost < best[0]:
            best = (o.cost, u, k)
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
    use_alt = job.alt_urdf is not None and job.alt_nominal is not None
    urdf = job.alt_urdf if use_alt else job.urdf
    nominal = job.alt_nominal if use_alt else job.nominal
    assert urdf is not None and nominal is not None
    pick: int | None = None
    for option in (cand, *cand.variants):
        sub = replace(job, candidate=replace(option, variants=()))
        aug = _setup(urdf, nominal, sub)
        _, cost, k = _alt_start(sub, aug.refit, aug.n_nominal + aug.n_accepted, [], only=pick)
        pick = k
        if best is None or cost < best[0]:
            best = (cost, option)
    assert best is not None
    return replace(job, candidate=replace(best[1], variants=())), best[0]


def _run(job: Job, t0: float) -> JobResult:
    extra: dict[str, Any] = {}
    if job.candidate is not None and job.candidate.variants:
        job, _ = _screen_variants(job)
        assert job.candidate is not None
        extra["variant"] = job.candidate.description
    cand = job.candidate
    aug = _setup(job.urdf, job.nominal, job)
    found: list[np.ndarray] = []
    if cand is None:
        u, out = aug.refit.solve(aug.refit.u0, max_nfev=job.max_nfev_all)
    else:
        u, out, found = _candidate_fit(job, aug.refit, aug.n_nominal + aug.n_accepted)
    if job.alt_urdf is not None and job.alt_nominal is not None:
        # second origin: the nominal model (with the best new parameters found above). The
        # parameter refit may have bent the nominal parameters (and the proportions of the
        # inertia tensors, which the refit variables keep) to mimic the missing effect.
        alt = _setup(job.alt_urdf, job.alt_nominal, job)
        only = 0 if job.start_new else None  # the screening's start (in found) alone
        u_a = _alt_start(job, alt.refit, alt.n_nominal + alt.n_accepted, found, only)[0]
        u_a, o_a = alt.refit.solve(u_a, max_nfev=job.max_nfev_alt, pre_nfev=job.pre_nfev)
        if o_a.cost < out.cost:
            aug, u, out = alt, u_a, o_a
    doc, variables, refit, modifier = aug.doc, aug.variables, aug.refit, aug.modifier
    n_new = len(variables) - aug.n_nominal
    status = out.status
    r = refit.residual(u)
    held = Refit(doc, job.heldout, variables, modifier=modifier, options=job.options)
    full = Refit(doc, job.full, variables, modifier=modifier, options=job.options)
    for name, value in refit.named_values(u).items():
        set_parameter(doc, name, value)
    return JobResult(
        label="refit" if cand is None else cand.label,
        effect=None if cand is None else cand.effect,
        location=None if cand is None else cand.location,
        names=[v.name for v in variables],
        values=refit.values(u),
        std=out.std,
        n_new=n_new,
        train_rms=float(np.sqrt(r @ r)),
        heldout_rms=float(np.sqrt(held.cost(u))),
        n_train=int(r.size),
        heldout_db_rms=_db_rms(held, u),
        db_rms=_db_rms(full, u),
        full_H=full.frf_for_data(u),
        urdf=doc.to_string(),
        wall_s=time.perf_counter() - t0,
        status=status,
        extra=extra,
        db_rms_unweighted=_db_rms(full, u, weighted=False),
        chain=_chain(job, refit.values(u)[aug.n_nominal :]),
        n_own=0 if cand is None else len(cand.parameters),
    )


def _chain(job: Job, new_values: np.ndarray) -> tuple[Candidate, ...]:
    """``job.accepted`` and its candidate with their fitted ``new_values`` (in order)."""
    out: list[Candidate] = []
    k = 0
    for c in [*job.accepted, *([job.candidate] if job.candidate is not None else [])]:
        n = len(c.parameters)
        out.append(with_values(c, new_values[k : k + n]))
        k += n
    return tuple(out)
