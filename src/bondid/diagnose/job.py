"""What a refit job carries in (:class:`Job`) and out (:class:`JobResult`), and the solve
schedules its steps use (:func:`direct`, :func:`short`); the job itself: :mod:`.runner`.

Everything a job needs travels in :class:`Job` (URDF text, data, plain values), so it pickles
to a worker process.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..optim.search import PRESOLVE_KIND, Step
from .effects import Candidate
from .refit import Nominal


def direct(max_iter: int, presolve: int = 0) -> list[Step]:
    """One solve over everything (``presolve``: the core's presolve of a log cost)."""
    return [Step("all", max_iter=max_iter, presolve=presolve)]


def short(n: int) -> list[Step]:
    """``n`` iterations on the normalised complex error (kept if lower), then ``n`` on the
    log error: the short start of the second origin."""
    return [
        Step("presolve", kind=PRESOLVE_KIND, norm="l2", max_iter=n, keep_if_lower=True),
        Step("all", max_iter=n),
    ]


def with_option(job: Job, option: Candidate) -> Job:
    """``job`` refitting ``option`` (one of its candidate's variants; variants cleared). The
    screening's start for the new parameters (``Job.start_new``) goes with it only when
    ``option`` has the same new parameters (a flexible base's chain of another length has
    other node masses: it then gets its own scans)."""
    cand = job.candidate
    same = cand is not None and [p.name for p in option.parameters] == [
        p.name for p in cand.parameters
    ]
    return replace(
        job, candidate=replace(option, variants=()), start_new=job.start_new if same else ()
    )


@dataclass
class Job:
    """Inputs of one refit job (see the module docstring).

    IPOPT iteration limits: ``new_iter`` a solve of the new parameters alone, ``all_iter``
    the full refit from the first origin, ``alt_iter`` the one from the second origin (and
    the rescue's continuation), ``presolve_iter`` its normalised-complex presolve,
    ``screen_iter`` each short solve of the second origin's start options.
    """

    urdf: str
    nominal: Nominal
    train: list[FrfData]
    heldout: list[FrfData]
    full: list[FrfData]
    candidate: Candidate | None = None
    options: CostOptions = field(default_factory=CostOptions)
    new_iter: int = 10
    n_starts: int = 3
    all_iter: int = 30
    alt_urdf: str | None = None
    alt_iter: int = 150
    presolve_iter: int = 30
    hints_hz: tuple[float, ...] = ()
    screen_iter: int = 10
    accepted: tuple[Candidate, ...] = ()
    #: the candidate's new parameters (SI) from its screening: when given, the refit starts
    #: there (no scan) from both origins
    start_new: tuple[float, ...] = ()
    #: run the wider search (:func:`.alternatives.wider_search`) inside the job; the
    #: diagnosis's search runs it in a second round instead (:mod:`.widen`)
    wider: bool = True
    #: the held-out data's noise level [dB] (:class:`.scoring.NoiseReference`): a refit at
    #: the training noise level whose held-out figure is above :data:`.rescue.RESCUE_RATIO`
    #: times it is stuck too (:func:`.alternatives.stuck`; NaN: the training test alone)
    heldout_noise_db: float = float("nan")
    #: the base's held-out score is above the held-out noise level (:mod:`.search`): the
    #: screening runs the joint profile whatever the one-step figure (:func:`.screen.needs_profile`)
    profile_always: bool = False
    #: a stuck refit of a structural candidate may get the modal step (:mod:`.modal_start`);
    #: the diagnosis's search allows it only to the candidates its screening ranks best
    #: (:data:`.search.MODAL_TOP`, and the placed alternation's picks)
    modal: bool = True
    #: the modes identified in each of ``full`` (tuples of :class:`.modal_id.IdentifiedMode`),
    #: for the starts of :mod:`.modal_start`; empty: identified there when needed
    measured: tuple = ()
    #: IPOPT options of the job's solves over the refit's own (``(name, value)`` pairs)
    ipopt: tuple[tuple[str, float], ...] = ()
    #: the rescue runs every fallback whatever the noise ratio (:func:`.rescue.rescue`)
    fallbacks_always: bool = False
    #: the final fit's nominal restart starts the nominal parameters from this model text
    #: (the parameter refit's; :mod:`.final_restart`); None: no restart
    restart_urdf: str | None = None


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
    #: the candidate as refitted (the variant or pivot the job kept; start values unfitted)
    candidate: Candidate | None = None
    #: the training objective (data and prior) and the noise ratio (training db_rms over the
    #: predicted noise level, :func:`.rescue.noise_ratio_at`) at the result
    objective: float = float("inf")
    noise_ratio: float | None = None
