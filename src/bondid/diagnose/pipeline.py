"""The diagnosis pipeline: :func:`diagnose`.

1. **Data** (:func:`prepare_data`): each point gets its information weight ``w = Ŝ/(Ŝ + N̂)``
   (:mod:`bondid.data.weights`), which then stands in the data's ``coherence`` for every later
   step (fit weights, held-out scores, gap figures); converted to receptance, limited to
   ``bands``; channels whose median weight is below 0.5 (median SNR below 0 dB) left out
   unless the user names them; reduced to ``n_points`` frequencies per data set for the
   refits and split into training and held-out frequencies (:mod:`.split`).
2. **Parameter refit**: the nominal parameters refitted on the training data (the fit of
   ``bondid.fit``: bounds, prior, the one loop of :mod:`bondid.optim.multistart`), the base
   every candidate is added to.
3. **Where the gap lies** (:mod:`.where`): the gap by channel and band, the measured modes
   paired with the refitted model's, anti-resonance shifts.
4. **The search** (:mod:`.search`): screen every candidate, refit the promising ones through
   the one loop, the statistical rule of :mod:`.scoring` decides, repeated from the model
   with the accepted effect; then the backward elimination of the accepted effects
   (:mod:`.prune`). The first kept effect is the verdict.
5. **The final model** (:mod:`.final_fit`): the refit with every kept effect (else the
   parameter refit) refitted on all data: the model to take away; no figure of 4 changes.
6. **The outcome** (:mod:`.outcome`): explained, partly explained or unexplained (given
   the held-out figures of 4 and the final model's level on all data), and what the
   remainder looks like (:mod:`.remainder`).
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
from ..exceptions import ComputationError, ConfigError, DataError
from ..frf.aligned import model_frf
from ..model.document import UrdfDocument
from ..model.parameters import get_parameter, select_parameters
from .effects import Candidate, get_effects
from .final_fit import FinalFit, start_final
from .gap import missing_mode_hints, worst_matched_modes
from .job import JobResult, Task
from .outcome import Outcome, outcome
from .pool import open_pool
from .prune import Pruning, prune
from .refit import Nominal, nominal_space_for
from .refit_job import run_refit
from .scoring import NoiseReference, heldout_noise
from .search import N_MAX, N_MIN, Context, Step, search
from .split import decimate, holdout_split, limit_bands
from .starts import Places
from .where import where

#: default free parameters of the parameter refit (zero-valued springs/dampers are dropped)
DEFAULT_FREE = ("all",)
#: channels below this median information weight are left out (:func:`used_channels`)
MIN_CHANNEL_COHERENCE = MIN_CHANNEL_WEIGHT


@dataclass
class Settings:
    """Choices of a diagnosis (the command line maps onto these).

    Attributes:
        effects: the candidate effects (None: all).
        free: the nominal parameters refitted (names, globs, groups; None: the default).
        bands, channels: frequencies [Hz] and channels used (None: all informative ones).
        n_points: frequencies per data set for the refits.
        n_holdout_bands: bands of the training/held-out checkerboard.
        workers: local worker processes (1: this process).
        scheduler: a Dask scheduler's address (``tcp://HOST:PORT``): its workers instead.
        modes: identify the measured modes (where the gap lies; placed starts).
        weighting: the information weights' rule.
        max_effects: effects accepted one after the other at most.
        n_min, n_max: refits of a step before the rule may end it, and at most
            (:mod:`.search`).
        damping: the damping model the model was declared with (:mod:`bondid.setup.damping`).
    """

    effects: list[str] | None = None
    free: list[str] | None = None
    bands: list[tuple[float, float]] | None = None
    channels: list[str] | None = None
    n_points: int = 500
    n_holdout_bands: int = 16
    workers: int = 2
    scheduler: str | None = None
    modes: bool = True
    weighting: str = "auto"
    max_effects: int = 3
    n_min: int = N_MIN
    n_max: int = N_MAX
    damping: str = "model"


@dataclass
class Diagnosis:
    """Everything :func:`diagnose` found (:mod:`.report` turns it into files)."""

    nominal: UrdfDocument
    datasets: list[FrfData]
    channels: list[str]
    names: list[str]
    baseline: JobResult
    results: list[JobResult]  # the first step's refits, ranked best first
    scores: list[float]
    baseline_score: float
    winner: JobResult | None
    nominal_H: list[np.ndarray]
    bands: list[tuple[float, float]]
    modes: list[dict[str, Any]]
    modes_by_dataset: list[list[dict[str, Any]]]
    antiresonances: list[dict[str, Any]]
    split_info: dict[str, Any]
    wall_s: float
    notes: list[str] = field(default_factory=list)
    weighting: dict[str, Any] = field(default_factory=dict)
    #: the search's steps (:mod:`.search`); ``results``/``scores`` are the first's
    steps: list[Step] = field(default_factory=list)
    #: the final model refitted on all data (:mod:`.final_fit`); None when not run
    final: FinalFit | None = None
    #: the backward elimination of the accepted effects (:mod:`.prune`); ``winner`` is its
    #: first kept effect's model
    pruning: Pruning | None = None
    #: ``{absolute path: as the user wrote it}`` of the model's meshes
    mesh_names: dict[str, str] = field(default_factory=dict)
    #: the held-out noise reference of the rule (None: the margins' rule)
    noise: NoiseReference | None = None
    #: where the starts were placed (missing and worst-matched measured modes)
    places: Places = field(default_factory=Places)
    #: explained, partly explained or unexplained (:mod:`.outcome`)
    outcome: Outcome | None = None
    #: what the final model still misses (:mod:`.remainder`); None when not described
    remainder: Any = None
    #: per data file (its ``source``), the channels used there (None: ``channels`` in all)
    channels_by_file: dict[str, tuple[str, ...]] | None = None
    #: the ``--lines`` reduction of the data files (``LineReduction.to_json_dict()``), when
    #: the command recorded one
    lines: dict[str, Any] | None = None


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


def default_names(
    doc: UrdfDocument, free: Sequence[str] | None, damping: str = "model"
) -> list[str]:
    """The refit's free parameters: ``free`` (names, globs, groups) or :data:`DEFAULT_FREE`
    without zero-valued springs and dampers, under the damping model ``damping``
    (:func:`bondid.setup.damping.damping_free`)."""
    from ..setup.damping import damping_free

    tokens, fixed = damping_free(doc, damping, list(free or DEFAULT_FREE), [])
    names = select_parameters(doc, tokens, fixed)
    if free:
        return names
    return [n for n in names if not n.endswith((".stiffness", ".damping")) or
            get_parameter(doc, n) > 0]  # fmt: skip


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
    # the data's coherence now holds the information weights: weigh by it as it is; the
    # channels are chosen file by file, as bondid.fit chooses them (a channel informative at
    # one operating point is used there only), unless --channels names them
    by_file = None
    if not s.channels:
        from ..data.weights import informative_by_file

        by_file, _, _ = informative_by_file(full, "coherence", MIN_CHANNEL_COHERENCE)
    options = CostOptions(channels=channels, weighting="coherence", channels_by_file=by_file)
    names = default_names(doc, s.free, s.damping)
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
    progress: Callable[[str], None] | None = None,
    during_final: Callable[[Diagnosis], object] | None = None,
) -> Diagnosis:
    """Diagnose the gap between ``doc`` and the measured ``datasets`` (module docstring).

    Args:
        doc: the nominal model.
        datasets: measured FRFs (one per operating point), any quantity.
        settings: choices (default :class:`Settings`).
        progress: ``progress(label)`` after each finished piece of work.
        during_final: called with the diagnosis so far (``final`` still None) while a worker
            runs the final fit on all data, e.g. to draw the plots, which do not depend on
            it; an error it raises stops the diagnosis.

    Raises:
        ConfigError, DataError, ParameterError: bad choices or data.
        ComputationError: the parameter refit failed.
    """
    from ..model.packages import with_absolute_meshes

    t0 = time.perf_counter()
    s = settings or Settings()
    say = progress or (lambda _label: None)
    # every model text the diagnosis hands to a worker names its meshes by absolute path, so
    # the hulls its candidates need are found there too; the outputs get the names back
    doc, mesh_names = with_absolute_meshes(doc)
    p = prepare_data(doc, datasets, s)
    pool = open_pool(s.workers, s.scheduler)
    try:
        base_task = Task(doc.to_string(), p.space, p.train, p.held, p.full, p.options,
                         fallbacks=True)  # fmt: skip
        baseline = pool.submit(run_refit, base_task).result()
        if baseline.error:
            raise ComputationError(f"the parameter refit failed: {baseline.error}")
        say("parameter refit")
        modes, by_ds, anti, bands, measured = where(doc, p.full, baseline, p.channels, s.modes)
        places = Places(missing_mode_hints(by_ds), worst_matched_modes(by_ds),
                        np.asarray(p.space.centre, float), measured)  # fmt: skip
        ctx = Context(
            doc, p.names, p.train, p.held, p.full, p.options, p.candidates, p.space, p.noise,
            places, s.max_effects, s.n_min, s.n_max,
        )  # fmt: skip
        steps = search(ctx, pool, baseline, say)
        pruning = prune(ctx, pool, steps, baseline, say)
        last = pruning.final or baseline
        pending = start_final(last, base_task, baseline, pool)
        first = steps[0]
        kept = pruning.kept
        final_score = kept[-1].score if kept else first.base_score
        answer = outcome(first.base_score, final_score, [k.test for k in kept], p.noise)
        diag = Diagnosis(
            nominal=doc, datasets=p.full, channels=p.channels, names=p.names,
            baseline=baseline, results=first.results, scores=first.scores,
            baseline_score=first.base_score,
            winner=pruning.kept[0].model if pruning.kept else None,
            nominal_H=[model_frf(doc, d) for d in p.full], bands=bands, modes=modes,
            modes_by_dataset=by_ds, antiresonances=anti, split_info=p.split_info,
            wall_s=math.nan, weighting=p.weighting, steps=steps, pruning=pruning,
            mesh_names=mesh_names, noise=p.noise, places=places, outcome=answer,
            channels_by_file=p.options.channels_by_file,
        )  # fmt: skip
        if during_final is not None:
            during_final(diag)
        diag.final = pending()
        # the final fit's level counts only when it refitted the model (on all data); the
        # search's model's own ratio is on its training bands, in-sample
        ratio = diag.final.model.noise_ratio if diag.final.kept else None
        diag.outcome = outcome(first.base_score, final_score, [k.test for k in kept], p.noise,
                               ratio)  # fmt: skip
        say("final fit on all data")
        diag.remainder = describe(doc, datasets, p, diag.final.model, measured, s)
        say("the remainder described")
    except BaseException:
        pool.kill()
        raise
    finally:
        pool.close()
    diag.wall_s = time.perf_counter() - t0
    return diag


def describe(
    doc: UrdfDocument, originals: Sequence[FrfData], p: Prepared, model: JobResult,
    measured: tuple, s: Settings,
) -> Any:  # fmt: skip
    """What ``model`` (the final model) still misses on all the data (:mod:`.remainder`),
    its points judged against the prediction of their noise; None when it cannot be said."""
    from ..cost.noise_level import point_noise_to_signal
    from ..exceptions import BondidError
    from .remainder import Settings as RemainderSettings
    from .remainder import describe_remainder
    from .where import modes_on_channels

    if model.error or not model.full_H:
        return None
    rotary = tuple(t.joint for t in doc.transmissions
                   if doc.joint(t.joint).type in ("revolute", "continuous"))  # fmt: skip
    try:
        nts = [point_noise_to_signal(d, "coherence", "prediction", (orig, s.weighting))
               for d, orig in zip(p.full, originals, strict=True)]  # fmt: skip
        final = UrdfDocument.from_string(model.urdf, source="final model")
        mod = [modes_on_channels(final, d, p.channels) for d in p.full] if measured else None
        return describe_remainder(
            p.full, model.full_H, p.channels, noise_to_signal=nts,
            measured_modes=list(measured) or None, model_modes=mod,
            settings=RemainderSettings(modes=bool(measured), rotary=rotary),
        )  # fmt: skip
    except (BondidError, np.linalg.LinAlgError, ValueError) as exc:
        return RemainderFailure(f"{type(exc).__name__}: {exc}")


@dataclass
class RemainderFailure:
    """Why the remainder could not be described (it is then reported, not raised)."""

    error: str

    def as_dict(self) -> dict[str, Any]:
        return {"error": self.error, "findings": [], "summary": []}

    def sentences(self) -> list[str]:
        return [f"the remainder could not be described: {self.error}"]
