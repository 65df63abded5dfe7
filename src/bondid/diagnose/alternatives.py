"""Alternatives to a candidate's refit that is :func:`stuck` — ended above the noise level, or
at it on the training data but well above it on the held-out data (for :mod:`.runner`):
a rotational joint compliance at a pivot refined continuously (:func:`at_refined_pivot`,
:mod:`.pivot`), a candidate with variants at each other variant (:func:`other_variants`).
Each alternative gets the full refit of both origins (:func:`.runner._fit`); the lowest
objective is kept unless it is bought with a worse held-out figure (:mod:`.keep`). An
alternative whose model or refit fails (a numerical error) is skipped, and the failure is said
in the job's notes (``candidates[].notes`` of ``diagnosis.json``).

Then, still stuck, the two ways the fit itself gets out of a wrong basin
(:func:`wider_search`): the refit from the candidate's own starting-point scans and start
options instead of the screening's start (:func:`with_own_scans`: the screening's start can
put the new mode out of the band, where no local solve moves it back), and the fit's band
continuation from the second origin, the nominal model with the best new parameters so far
(:func:`continuation_from_nominal`: the start ``bondid.fit`` runs it from, where the
parameter refit has not bent the nominal parameters around the missing effect). A job runs it
itself with ``Job.wider``; the diagnosis's search runs it in a second round of each step,
for the refits that could decide the step (:mod:`.widen`)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ..exceptions import BondidError
from .augmented import Augmented
from .effects import Candidate
from .job import Job, direct, with_option
from .keep import held_of, replaces
from .pivot import (
    FULL_EVAL_ITER,
    FULL_MAX_EVALS,
    MAX_EVALS,
    pivot_box,
    refine_pivot,
    with_pivot,
)
from .refit import State
from .rescue import above_noise
from .runner import _alt_start, _fit, _setup

#: the numerical failures of an alternative that skip it (anything else fails the job)
_SKIPPED = (BondidError, np.linalg.LinAlgError, ValueError)


def _failure(what: str, err: BaseException) -> str:
    """One line on a skipped alternative: what, the error's type and message."""
    return f"{what}: {type(err).__name__}: {err}"


def _failures_note(failed: list[str], of: int, what: str) -> str:
    """``"k of n <what> failed (first: ...)"``, or "" when none failed."""
    if not failed:
        return ""
    return f"{len(failed)} of {of} {what} failed (first: {failed[0]})"


#: bands and IPOPT iterations per band of :func:`continuation_from_nominal` (the fit's own
#: fallback continuation, :func:`bondid.optim.fallback.run_to_noise`, uses 8 × 60; 4 × 30
#: left the true actuator lag of benchmark case bonder/al/nocoh at 1.93× the noise level)
NOMINAL_BANDS = 8
NOMINAL_BAND_ITER = 60


def stuck(job: Job, aug: Augmented, state: State, res: Any) -> bool:
    """Does a candidate's refit need the alternatives: its training figure above the noise
    level (:func:`.rescue.above_noise`), or its held-out figure above
    :data:`.rescue.RESCUE_RATIO` times the held-out noise level (:attr:`.runner.Job.
    heldout_noise_db`; :func:`.rescue.above_heldout_level`)? A wrong variant (e.g. a pivot) can
    fit the training bands at the noise level with bent nominal parameters and miss the
    held-out ones (measured: a rotational compliance at the candidate's pivot, training
    1.19× the noise level, held-out 2.1×; at the refined pivot 1.13× and 1.5×). Which
    alternative is kept: :mod:`.keep`."""
    from .evaluate import heldout_rms
    from .rescue import above_heldout_level

    if above_noise(aug.refit, state):
        return True
    level = job.heldout_noise_db
    if not (math.isfinite(level) and level > 0):  # no level: the held-out figure is not needed
        return False
    return above_heldout_level(heldout_rms(aug.refit, res.result, job.heldout, job.options), level)


def refine_job_pivot(
    job: Job, warm: tuple[Augmented, State] | None = None, full: bool = False
) -> tuple[Job, str, State | None]:
    """The job with its rotational compliance's pivot refined (:func:`.pivot.refine_pivot`).
    Without ``warm``, each pivot is judged like a variant (:func:`.runner._screen_variants`:
    the second origin's start from the screening's new parameters). With ``warm`` (a refit
    and its state), the candidate is rebuilt about each pivot (:meth:`~.effects.
    joint_compliance.JointCompliance.at_pivot`) and judged by a solve of its new parameters
    alone from that state, scaled to the pivot (:func:`pivot_ratio`): the nominal parameters
    stay where the refit put them and the spring keeps its mode's frequency. With ``full``
    too, by a short solve of every parameter from there (:data:`.pivot.FULL_EVAL_ITER`
    iterations, at most :data:`.pivot.FULL_MAX_EVALS` pivots): the nominal parameters that
    the first pivot bent move with the pivot. Returns the job, the note and, with ``warm``,
    the state at the best pivot."""
    from ..model.document import UrdfDocument
    from .effects import get_effect
    from .effects.joint_compliance import JointCompliance

    cand = job.candidate
    assert cand is not None
    urdf = job.alt_urdf if job.alt_urdf is not None else job.urdf
    effect = get_effect(cand.effect)
    assert isinstance(effect, JointCompliance)
    doc = UrdfDocument.from_string(urdf)
    failed: list[str] = []
    states: dict[tuple[float, ...], State] = {}

    def move(c: Candidate, pivot: np.ndarray) -> Candidate:
        # cold: the same parameters (the short start from the nominal model sees little of
        # the pivot, and a rebuilt start only drifts it; measured on gantry/jcr, stop 27)
        return effect.at_pivot(doc, c, pivot) if warm is not None else with_pivot(c, pivot)

    def cost(c: Candidate) -> float:
        sub = warm_solves(moved_job(job, c)) if full else moved_job(job, c)
        try:
            refit = _setup(urdf, sub).refit
            if warm is None:
                found = [np.asarray(sub.start_new, float)] if sub.start_new else []
                return _alt_start(sub, refit, found, only=0)[1]
            w_aug, w_state = warm
            new = w_aug.refit.new_values(w_state) * pivot_ratio(c, cand)
            if full:
                s, value, _ = refit.solve(refit.with_new(w_state, new), direct(FULL_EVAL_ITER))
            else:
                s, value = refit.solve_new(refit.with_new(w_state, new), job.new_iter)
            states[tuple(c.spec["pivot"])] = s
            return value
        except _SKIPPED as err:
            failed.append(_failure(f"pivot {np.round(c.spec['pivot'], 4).tolist()}", err))
            return float("inf")

    box = pivot_box(cand)
    extent = None if box is None else box[1] - box[0]
    best, c, n = refine_pivot(cand, cost, extent, move, box, FULL_MAX_EVALS if full else MAX_EVALS)
    kind = "start" if warm is None else ("all parameters" if full else "warm")
    note = f"{n} pivots tried, {kind} figure {c:.4g}"
    failures = _failures_note(failed, n, "pivots")
    note = f"{note} ({failures})" if failures else note
    return moved_job(job, best), note, states.get(tuple(best.spec["pivot"]))


def warm_solves(job: Job) -> Job:
    """``job`` with its solves started as warm starts (:data:`bondid.optim.ipopt.WARM_START`:
    a small initial barrier). From a refit's own state IPOPT's default barrier pushes the
    iterate off it first: gantry/jcr/acc's true candidate, pivots judged with every parameter
    free (stop 32), from one refit: 0.164 (held-out 0.49 dB) with it, 0.358 (2.45 dB) without."""
    from ..optim.ipopt import WARM_START

    return replace(job, ipopt=tuple({**dict(job.ipopt), **WARM_START}.items()))


def pivot_ratio(cand: Candidate, old: Candidate) -> np.ndarray:
    """Per new parameter, ``cand``'s start over ``old``'s ``(n_new,)``: the same candidate
    about another pivot (the effective inertia's ratio for a spring and its damper)."""
    pairs = zip(cand.parameters, old.parameters, strict=True)
    return np.array([p.initial / q.initial for p, q in pairs], float)


def moved_job(job: Job, cand: Candidate) -> Job:
    """``job`` with ``cand`` (its candidate about another pivot) and the start of its new
    parameters scaled as the candidate's own start is (:func:`pivot_ratio`): the same
    spring-alone frequency and damping ratio as the start at the job's pivot."""
    old = job.candidate
    assert old is not None
    start = job.start_new
    if start:
        start = tuple(float(v) for v in np.asarray(start, float) * pivot_ratio(cand, old))
    return replace(job, candidate=cand, start_new=start)


def at_refined_pivot(
    job: Job, aug: Augmented, state: State, res: Any, warm: bool = False, full: bool = False
) -> tuple[Job, Augmented, State, Any, str]:
    """A rotational compliance whose refit is stuck (:func:`stuck`): the pivot refined
    (:func:`refine_job_pivot`) and refitted there, kept by :func:`.keep.replaces`. Without
    ``warm``, both origins are refitted at the new pivot (:func:`.runner._fit`); with it (a
    refit whose spring already sits at a mode, e.g. after the modal step), the pivot is judged
    and refitted from ``state`` (everything solved from the warm figure's state); ``full``:
    each pivot judged by a short solve of every parameter (:func:`refine_job_pivot`), those
    solves and the refit at the best pivot started as warm starts (:func:`warm_solves`)."""
    moved, note, s_w = refine_job_pivot(job, (aug, state) if warm else None, full)
    assert moved.candidate is not None and job.candidate is not None
    if moved.candidate.spec["pivot"] == job.candidate.spec["pivot"]:
        return job, aug, state, res, f"{note}; the pivot kept"
    if s_w is None:
        aug2, state2, res2 = _fit(moved)
    else:
        solver = warm_solves(moved) if full else moved
        aug2 = _setup(moved.alt_urdf if moved.alt_urdf is not None else moved.urdf, solver)
        state2, _, res2 = aug2.refit.solve(s_w, direct(job.all_iter, job.presolve_iter))
    if _better(job, aug, state, res, aug2, state2, res2):
        return moved, aug2, state2, res2, f"{note}; refitted there, kept"
    return job, aug, state, res, f"{note}; refitted there, not kept"


def variant_options(job: Job) -> list[Candidate]:
    """The job's candidate's options as its effect lists them on the nominal model (the
    candidate of the same label and its variants, each without variants; a variant may have
    other new parameters: refit it with :func:`.job.with_option`). The job's own candidate
    may be one variant already (the screening's choice), so its own ``variants`` are not
    enough."""
    from ..model.document import UrdfDocument
    from .effects import get_effect

    cand = job.candidate
    assert cand is not None
    doc = UrdfDocument.from_string(job.alt_urdf if job.alt_urdf is not None else job.urdf)
    same = [c for c in get_effect(cand.effect).candidates(doc) if c.label == cand.label]
    if not same:
        return []
    return [replace(v, variants=()) for v in (same[0], *same[0].variants)]


def other_variants(
    job: Job, aug: Augmented, state: State, res: Any, notes: dict[str, Any] | None = None
) -> tuple[Job, Augmented, State, Any]:
    """A refit above the noise level of a candidate with variants (e.g. the elastic centres
    of soft mounts; the screening kept one on short starts): every other variant refitted
    fully (both origins, the same start); the lowest objective is kept. A variant whose
    refit fails is skipped and said in ``notes["variants"]`` (the job's ``extra``)."""
    cand = job.candidate
    assert cand is not None
    best = (job, aug, state, res)
    failed: list[str] = []
    tried = 0
    for v in variant_options(job):
        if v.spec == cand.spec:
            continue
        other = with_option(job, v)
        tried += 1
        try:
            a2, s2, r2 = _fit(other)
        except _SKIPPED as err:
            failed.append(_failure(f"variant {v.description!r}", err))
            continue
        if _better(job, *best[1:], a2, s2, r2):
            best = (other, a2, s2, r2)
    if failed and notes is not None:
        notes["variants"] = _failures_note(failed, tried, "other variants' refits")
    return best


def with_own_scans(
    job: Job, aug: Augmented, state: State, res: Any
) -> tuple[Augmented, State, Any, str]:
    """The refit of both origins again without the screening's start (``Job.start_new``
    dropped: the runner's own scans of the candidate's scale and every start option of the
    second origin); the lower objective is kept. Nothing to do without a screening start."""
    if not job.start_new:
        return aug, state, res, ""
    try:
        aug2, state2, res2 = _fit(replace(job, start_new=()))
    except _SKIPPED as exc:
        return aug, state, res, f"own scans failed ({type(exc).__name__})"
    return _lower(job, aug, state, res, aug2, state2, res2, "own scans")


def continuation_from_nominal(
    job: Job, aug: Augmented, state: State, res: Any,
    n_bands: int = NOMINAL_BANDS, band_iter: int = NOMINAL_BAND_ITER,
) -> tuple[Augmented, State, Any, str]:  # fmt: skip
    """The fit's band continuation (:func:`bondid.optim.schedules.continuation`, ``n_bands``
    bands of ``band_iter`` iterations, then the full fit) from the second origin: the nominal
    model (``Job.alt_urdf``) with the candidate's new parameters at their best values so far,
    fitted alone first; the lower objective is kept. Nothing to do without a second origin."""
    if job.alt_urdf is None:
        return aug, state, res, ""
    try:
        alt_aug, s2, res2 = nominal_continuation(job, aug.refit.new_values(state), n_bands,
                                                 band_iter)  # fmt: skip
    except _SKIPPED as exc:
        return aug, state, res, f"{NOMINAL_LABEL} failed ({type(exc).__name__})"
    return _lower(job, aug, state, res, alt_aug, s2, res2, NOMINAL_LABEL)


NOMINAL_LABEL = "continuation from the nominal model"


def nominal_continuation(
    job: Job, new_values: np.ndarray,
    n_bands: int = NOMINAL_BANDS, band_iter: int = NOMINAL_BAND_ITER,
) -> tuple[Augmented, State, Any]:  # fmt: skip
    """The solve of :func:`continuation_from_nominal` from the nominal model with the
    candidate's own new parameters at ``new_values`` (SI); raises what the refit raises."""
    from ..optim.schedules import continuation

    assert job.alt_urdf is not None
    alt_aug = _setup(job.alt_urdf, job)
    alt = alt_aug.refit
    s = alt.with_new(alt.state0, new_values)
    if alt.own:
        s, _ = alt.solve_new(s, job.new_iter)
    steps = continuation(alt.at(s), n_bands, band_iter=band_iter, presolve_iter=job.presolve_iter)
    s2, _, res2 = alt.solve(s, steps, max_iter=job.alt_iter)
    return alt_aug, s2, res2


def wider_search(
    job: Job, aug: Augmented, state: State, res: Any
) -> tuple[Augmented, State, Any, str]:
    """:func:`with_own_scans` while :func:`stuck`, then :func:`continuation_from_nominal` while
    above the noise level on the training data (module docstring; at the training noise
    level it has nothing to find there, and what is kept is decided on the training
    objective: measured on 7 refits stuck on their held-out figure alone, in bonder/jcr/nocoh
    and gantry/jct/harsh, never kept); notes joined by "; "."""
    notes = []
    for step in (with_own_scans, continuation_from_nominal):
        if not stuck(job, aug, state, res) or (
            step is continuation_from_nominal and not above_noise(aug.refit, state)
        ):
            break
        aug, state, res, note = step(job, aug, state, res)
        if note:
            notes.append(note)
    return aug, state, res, "; ".join(notes)


def _better(
    job: Job, aug: Augmented, state: State, res: Any, aug2: Augmented, state2: State, res2: Any
) -> bool:
    """Does the second refit replace the first (:func:`.keep.replaces`)?"""
    return replaces(job, aug.refit.cost(state), held_of(job, aug, res),
                    aug2.refit.cost(state2), held_of(job, aug2, res2))  # fmt: skip


def _lower(
    job: Job, aug: Augmented, state: State, res: Any,
    aug2: Augmented, state2: State, res2: Any, label: str,
) -> tuple[Augmented, State, Any, str]:  # fmt: skip
    """The refit :func:`.keep.replaces` keeps, with a note of ``label``'s noise ratio."""
    from .rescue import noise_ratio_at

    kept = _better(job, aug, state, res, aug2, state2, res2)
    lower = aug2.refit.cost(state2) < aug.refit.cost(state)
    note = kept_note(label, noise_ratio_at(aug2.refit, state2), kept, lower)
    if kept:
        return aug2, state2, res2, note
    return aug, state, res, note


#: the reason :func:`kept_note` gives for a retry with the lower training objective that
#: :func:`.keep.replaces` refused
HELD_OUT_WORSE = "its held-out figure is worse"


def kept_note(label: str, ratio: float | None, kept: bool, lower: bool = False) -> str:
    """``"<label> to <ratio>x, kept"`` (or ``not kept``): what a retry reached (its training
    db_rms over the predicted noise level) and whether it was kept; ``lower``: its training
    objective was the lower one, so a refusal was for its held-out figure (said)."""
    r = ratio if ratio is not None else float("nan")
    said = "kept" if kept else f"not kept ({HELD_OUT_WORSE})" if lower else "not kept"
    return f"{label} to {r:.2f}x, {said}"
