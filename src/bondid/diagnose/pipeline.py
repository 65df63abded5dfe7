"""The diagnosis pipeline: :func:`diagnose`.

1. Data: each point gets its information weight ``w = Ŝ/(Ŝ + N̂)``
   (:mod:`bondid.data.weights`, ``Settings.weighting``: the coherence combined with the noise
   estimated from the data, or the estimate alone when the file has no coherence), which then
   stands in the data's ``coherence`` for every later step (fit weights, held-out scores, gap
   figures); converted to receptance, limited to ``bands``; channels whose median weight is
   below :data:`MIN_CHANNEL_COHERENCE` (median SNR below 0 dB: under the noise floor) are left
   out unless the user names channels; decimated to ``n_points`` log-spaced frequencies per
   data set for the refits, and split into training and held-out frequencies (:mod:`.split`).
2. Parameter refit: :func:`bondid.fit.fit` (IPOPT, physically consistent, with the default
   bounds and the noise-scaled prior of ``bondid.fit``) of the nominal parameters on the
   training data, then the refit every candidate gets (:mod:`.runner` over the core,
   :mod:`.refit`) from there — the parameter-only baseline.
3. Where the gap lies: :func:`.gap.gap_report` of the nominal and the refitted model (total,
   per channel, per automatic band), measured modes (:func:`.modal_id.identify_modes`) paired
   with the refitted model's, anti-resonance shifts.
4. The search for missing effects (:mod:`.search`): every candidate of every chosen effect
   (:mod:`.effects`) is screened cheaply (:mod:`.screen`, seeded with the frequencies of the
   missing modes of step 3), the best few are refitted fully (:mod:`.runner`) in worker
   processes, scored on held-out data and ranked; the best is accepted by the rule of
   :mod:`.scoring`, and the search repeats from the model with it until nothing passes;
   with two or more accepted, each is tested again against the model with all the others
   and dropped when redundant (:mod:`.prune`); the first effect kept is the verdict.
5. The final model (the refit with every kept effect, else the parameter refit) refitted on
   all data (:mod:`.final_fit`): the model to take away; no verdict or figure of 4 changes.
   When the parameter refit is already at the held-out noise level, no effect can be
   accepted (:func:`.scoring.may_accept`) and the final fit is the parameter refit's: with
   worker processes it is then queued behind the first step's full refits, where a worker
   would otherwise wait for the slowest of them. Measured on the bundled reference case (its
   base at 1.02× the level), side by side, alternating: 52.5 / 60.1 / 58.8 s before, 46.4 /
   51.3 / 52.4 s after (0.85–0.89×), the same outputs. Queued whatever the base (as first
   tried), it cost a case with an effect (bonder/sd/coh) 3–4 %: the second process slows the
   refits beside it, and the fit is then thrown away.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..data.weights import MIN_CHANNEL_WEIGHT, check_weighting
from ..exceptions import ConfigError, DataError
from ..frf.aligned import model_frf
from ..model.document import UrdfDocument
from ..model.parameters import get_parameter, select_parameters
from . import scoring
from .effects import Candidate, get_effects
from .final_fit import FinalFit, PendingFinal, start_final
from .gap import missing_mode_hints
from .job import Job, JobResult
from .pool import WorkerPool
from .prune import Pruning, prune
from .refit import Nominal, nominal_space_for
from .runner import run_job
from .scoring import NoiseReference, heldout_noise
from .search import Context, Step, search
from .split import decimate, holdout_split, limit_bands
from .where import where

#: default free parameters of the parameter refit (zero-valued springs/dampers are dropped)
DEFAULT_FREE = ("all",)
#: channels below this median information weight are left out (:func:`used_channels`)
MIN_CHANNEL_COHERENCE = MIN_CHANNEL_WEIGHT


@dataclass
class Settings:
    """Choices of a diagnosis (CLI options map onto these)."""

    effects: list[str] | None = None
    free: list[str] | None = None
    bands: list[tuple[float, float]] | None = None
    channels: list[str] | None = None
    n_points: int = 500
    n_holdout_bands: int = 16
    workers: int = 2
    use_ipopt: bool = True
    ipopt_iter: int = 300
    refit_iter: int = 30
    n_starts: int = 3
    modes: bool = True
    weighting: str = "auto"
    #: candidates refitted fully after the screening, at the first and at later steps
    n_refit: int = 4
    n_refit_later: int = 2
    #: most candidates refitted when the screening's figures tie above the noise level
    #: (:func:`.screen.select`), at the first and at later steps
    n_refit_max: int = 6
    n_refit_max_later: int = 4
    #: most effects accepted one after the other
    max_effects: int = 3


@dataclass
class Diagnosis:
    """Everything :func:`diagnose` found (``report`` turns it into files)."""

    nominal: UrdfDocument
    datasets: list[FrfData]
    channels: list[str]
    names: list[str]
    baseline: JobResult
    results: list[JobResult]  # ranked, best first
    scores: list[float]
    baseline_score: float
    winner: JobResult | None
    nominal_H: list[np.ndarray]
    bands: list[tuple[float, float]]
    modes: list[dict[str, Any]]
    modes_by_dataset: list[list[dict[str, Any]]]
    antiresonances: list[dict[str, Any]]
    fit_info: dict[str, Any]
    split_info: dict[str, Any]
    wall_s: float
    notes: list[str] = field(default_factory=list)
    weighting: dict[str, Any] = field(default_factory=dict)
    #: the search's steps (:mod:`.search`); ``results``/``scores`` are the first's
    steps: list[Step] = field(default_factory=list)
    #: the final model (the refit with every kept effect, else the parameter refit) refitted
    #: on all data (:mod:`.final_fit`); None when not run
    final: FinalFit | None = None
    #: the backward elimination of the accepted effects (:mod:`.prune`); ``winner`` is its
    #: first kept effect's model. None: not run (every accepted effect kept)
    pruning: Pruning | None = None
    #: ``{absolute path: as the user wrote it}`` of the model's meshes
    #: (:func:`bondid.model.packages.with_absolute_meshes`): the written URDFs use the latter
    mesh_names: dict[str, str] = field(default_factory=dict)


def used_channels(datasets: Sequence[FrfData], requested: Sequence[str] | None) -> list[str]:
    """Channels to use: ``requested`` (checked), else every present channel whose median
    information weight — held in ``coherence`` once :func:`diagnose` has put the weights there
    — is at least :data:`MIN_CHANNEL_COHERENCE` (:func:`bondid.data.weights.
    informative_channels`, the rule of ``bondid.fit`` and ``bondid.sensitivity`` too)."""
    from ..data.weights import informative_channels

    present: list[str] = []
    for d in datasets:
        present += [c for c in d.channels if c not in present]
    if requested:
        bad = [c for c in requested if c not in present]
        if bad:
            raise DataError(
                f"--channels: {', '.join(bad)} not in the data; valid: {', '.join(present)}"
            )
        return list(requested)
    keep, _ = informative_channels(datasets, "coherence", MIN_CHANNEL_COHERENCE)
    if not keep:
        raise DataError(
            "every channel is below the noise floor (median information weight < 0.5, i.e. "
            "median SNR < 0 dB); name channels with --channels to use them anyway"
        )
    return keep


def default_names(doc: UrdfDocument, free: Sequence[str] | None) -> list[str]:
    """The refit's free parameters: ``free`` (names, globs, groups) or :data:`DEFAULT_FREE`
    without zero-valued springs and dampers."""
    if free:
        return select_parameters(doc, free)
    names = select_parameters(doc, DEFAULT_FREE)
    return [n for n in names if not n.endswith((".stiffness", ".damping")) or
            get_parameter(doc, n) > 0]  # fmt: skip


def _parameter_fit(
    doc: UrdfDocument, train: list[FrfData], space: Nominal, options: CostOptions, iters: int
) -> tuple[str, dict[str, Any]]:
    """Stage (i): :func:`bondid.fit.fit` with the bounds and prior of every refit; returns
    (URDF text of the fitted model, info)."""
    from ..exceptions import BondidError
    from ..fit import fit

    try:
        res = fit(
            doc, train, list(space.names), options=options, lower=space.lower,
            upper=space.upper, max_iter=iters, prior_width=space.prior_width,
        )  # fmt: skip
    except BondidError as exc:
        return doc.to_string(), {"status": "failed", "error": str(exc)}
    info = {
        "status": res.status,
        "iterations": res.iterations,
        "wall_s": res.wall_s,
        "cost_initial": res.cost_initial,
        "cost_final": res.cost_final,
        "parameters": [
            {"name": n, "initial": float(a), "fitted": float(b), "std": float(s)}
            for n, a, b, s in zip(res.names, res.initial, res.fitted, res.std, strict=True)
        ],
    }
    return res.document.to_string(), info


def _baseline_task(
    urdf: str, space: Nominal, train: list[FrfData], held: list[FrfData],
    full: list[FrfData], options: CostOptions, use_ipopt: bool, iters: int, refit_iter: int,
) -> tuple[JobResult, dict[str, Any]]:  # fmt: skip
    """The parameter-only baseline: :func:`_parameter_fit` from the nominal model, then the
    refit of :mod:`.runner` from there (the same problem: a short check); without IPOPT's
    parameter fit the refit runs from the nominal model with ``iters`` iterations."""
    nominal = UrdfDocument.from_string(urdf, source="nominal model")
    info: dict[str, Any] = {"status": "skipped"}
    start = urdf
    if use_ipopt:
        start, info = _parameter_fit(nominal, train, space, options, iters)
    n = refit_iter if use_ipopt else iters
    job = Job(start, space, train, held, full, None, options, all_iter=n)
    return run_job(job), info


@dataclass
class Prepared:
    """The data and choices of a diagnosis, ready for the refits (step 1 of the module
    docstring): data sets (weights in ``coherence``), channels, cost options, free names,
    candidates, the training / held-out split and what to report about it."""

    full: list[FrfData]
    channels: list[str]
    options: CostOptions
    names: list[str]
    candidates: list[Candidate]
    train: list[FrfData]
    held: list[FrfData]
    split_info: dict[str, Any]
    weighting: dict[str, Any]
    space: Nominal
    #: the held-out data's noise reference of the verdict rule (:func:`.scoring.heldout_noise`)
    noise: NoiseReference | None = None


def prepare_data(doc: UrdfDocument, datasets: Sequence[FrfData], s: Settings) -> Prepared:
    """Step 1 of the module docstring. Raises ConfigError/DataError on bad choices or data."""
    if not datasets:
        raise DataError("no measured data given")
    from ..data.weights import weighting_summary, with_weights_as_coherence

    check_weighting(s.weighting, "--weighting")
    w_info = weighting_summary(list(datasets), s.weighting)
    weighted = [with_weights_as_coherence(d, s.weighting) for d in datasets]
    full = [limit_bands(d, s.bands) for d in weighted]
    channels = used_channels(full, s.channels)
    # the data's coherence now holds the information weights: weigh by it as it is
    options = CostOptions(channels=channels, weighting="coherence")
    names = default_names(doc, s.free)
    if not names:
        raise ConfigError("no parameter to refit; check --free")
    candidates = [c for e in get_effects(s.effects) for c in e.candidates(doc)]
    dec = [decimate(d, s.n_points) for d in full]
    train, held = holdout_split(dec, s.n_holdout_bands)
    split_info = {
        "scheme": "checkerboard: data set k trains on log-frequency bands of parity k, "
        "holds out the others",
        "n_bands": s.n_holdout_bands,
        "n_points_per_dataset": [int(d.freq_hz.size) for d in dec],
        "n_train_points": [int(d.freq_hz.size) for d in train],
        "n_heldout_points": [int(d.freq_hz.size) for d in held],
    }
    space = nominal_space_for(doc, names, train)
    noise = heldout_noise(held, options, originals=list(datasets), weighting=s.weighting)
    return Prepared(full, channels, options, names, candidates, train, held, split_info,
                    w_info, space, noise)  # fmt: skip


def diagnose(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    settings: Settings | None = None,
    *,
    progress: Callable[[int, int, str], None] | None = None,
    during_final: Callable[[Diagnosis], object] | None = None,
) -> Diagnosis:
    """Diagnose the gap between ``doc`` and the measured ``datasets`` (see module docstring).

    Args:
        doc: the nominal model.
        datasets: measured FRFs (one per operating point), any quantity.
        settings: choices (default :class:`Settings`).
        progress: ``progress(done, total, label)`` after the baseline and each candidate.
        during_final: called with the diagnosis so far (``final`` still None) while a worker
            runs the final fit on all data, e.g. to draw the plots, which do not depend on
            it; an error it raises stops the diagnosis.

    Raises:
        ConfigError, DataError, ParameterError: bad choices or data.
    """
    from ..model.packages import with_absolute_meshes

    t0 = time.perf_counter()
    s = settings or Settings()
    # every model text the diagnosis hands to a worker names its meshes by absolute path, so
    # the hulls its candidates need are found there too; the outputs get the names back
    doc, mesh_names = with_absolute_meshes(doc)
    p = prepare_data(doc, datasets, s)
    pool = WorkerPool(max(1, s.workers))
    say = _announcer(progress)
    try:
        baseline, fit_info = _refit_baseline(pool, doc, p, s)
        say("parameter refit")
        modes, by_ds, anti, bands, measured = where(doc, p.full, baseline, p.channels, s.modes)
        ctx = Context(
            doc, p.names, p.train, p.held, p.full, p.options, p.candidates,
            missing_mode_hints(by_ds), s.refit_iter, s.n_starts, (s.n_refit, s.n_refit_later),
            s.max_effects, p.space, (s.n_refit_max, s.n_refit_max_later), p.noise,
            measured=measured,
        )  # fmt: skip
        level = p.noise.level_db if p.noise is not None else math.nan

        def final_of(source: JobResult) -> PendingFinal:
            data = Job(
                source.urdf, p.space, p.train, p.held, p.full, None, p.options,
                heldout_noise_db=level, restart_urdf=baseline.urdf,
            )  # fmt: skip
            return start_final(source, data, s.ipopt_iter, pool)

        ahead: list[PendingFinal] = []
        # a base at the noise level: no effect can be accepted (scoring, condition 1), so
        # the final fit is the parameter refit's; queued behind the first step's refits, it
        # runs on a worker that would otherwise wait for the slowest of them
        certain = not scoring.may_accept(scoring.base_score(baseline), p.noise)

        def submitted(index: int, what: str) -> None:
            if certain and pool.parallel and (index, what) == (0, "refits") and not ahead:
                ahead.append(final_of(baseline))

        steps = search(ctx, pool, baseline, say, submitted)
        pruning = prune(ctx, pool, steps, baseline, say)
        last = pruning.final or baseline
        if ahead and last is baseline:
            pending = ahead[0]
        else:
            for a in ahead:
                a.cancel()
            pending = final_of(last)
        first = steps[0]
        diag = Diagnosis(
            nominal=doc, datasets=p.full, channels=p.channels, names=p.names,
            baseline=baseline, results=first.results, scores=first.scores,
            baseline_score=first.base_score,
            winner=pruning.kept[0].model if pruning.kept else None,
            nominal_H=[model_frf(doc, d) for d in p.full], bands=bands, modes=modes,
            modes_by_dataset=by_ds, antiresonances=anti, fit_info=fit_info,
            split_info=p.split_info, wall_s=math.nan, weighting=p.weighting,
            steps=steps, final=None, pruning=pruning, mesh_names=mesh_names,
        )  # fmt: skip
        if during_final is not None:
            during_final(diag)
        diag.final = pending()
        say("final fit on all data")
    except BaseException:
        pool.kill()
        raise
    finally:
        pool.close()
    diag.wall_s = time.perf_counter() - t0
    return diag


def _announcer(progress: Callable[[int, int, str], None] | None) -> Callable[[str], None]:
    """``say(label)``: counts the finished steps and reports ``progress(done, done + 1,
    label)`` (nothing without ``progress``)."""
    count = [0]

    def say(label: str) -> None:
        count[0] += 1
        if progress:
            progress(count[0], count[0] + 1, label)

    return say


def _refit_baseline(
    pool: WorkerPool, doc: UrdfDocument, p: Prepared, s: Settings
) -> tuple[JobResult, dict[str, Any]]:
    """Step 2 of the module docstring in a worker: the parameter refit and its info.

    Raises:
        ComputationError: the refit failed.
    """
    fut = pool.submit(
        _baseline_task, doc.to_string(), p.space, p.train, p.held, p.full, p.options,
        s.use_ipopt, s.ipopt_iter, s.refit_iter,
    )  # fmt: skip
    baseline, fit_info = fut.result()
    if baseline.error:
        from ..exceptions import ComputationError

        raise ComputationError(f"the parameter refit failed: {baseline.error}")
    return baseline, fit_info
