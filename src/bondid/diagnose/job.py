"""What a diagnosis task carries to a worker (:class:`Task`) and back (:class:`JobResult`).

Everything a task needs travels in :class:`Task` (model text, data, plain values), so it
pickles to a worker process or a Dask worker. The same task serves the screening of a
candidate (:func:`.screen.screen`), its refit (:func:`.refit_job.run_refit`), the parameter
refit (no candidate) and the refits of the backward elimination and the final fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from .effects import Candidate
from .refit import Nominal
from .starts import Places, StartSpec

#: IPOPT iterations of a refit's last step (a start's whole-problem solve)
REFIT_ITER = 150
#: a refit's loop may spend this many starts' worth of iterations
REFIT_BUDGET_STARTS = 4


@dataclass
class Task:
    """Inputs of one screening or refit (module docstring).

    Attributes:
        urdf: the model the task starts from (the step's base: the parameter refit, or the
            model with the effects accepted so far), as URDF text.
        nominal: the nominal parameters (names, bounds, prior).
        train, heldout, full: the training, held-out and whole data sets (receptance; their
            ``coherence`` holds the information weights).
        options: the cost options (channels, weighting).
        accepted: the effects accepted before (parameters at their fitted values).
        candidate: the effect tried now, or None (a refit of the model as it is).
        places: where the candidate's starts are placed (:class:`.starts.Places`).
        starts: the screening's starts; empty: the refit finds its own.
        max_iter: IPOPT iterations of a start's last step.
        budget_starts: the loop's budget in starts' worth of iterations.
        fallbacks: also try the band continuation and the staged schedule (the parameter
            refit, which has no candidate starts; the final fit).
        probe: run the first of ``starts`` only (a search step's first round, see
            :mod:`.search`).
        warm: the refit starts where the model is (no held step: the elimination's and the
            final fit's warm refits).
        token: the cancellation token of the work this task belongs to (0: never
            cancelled; :mod:`.pool`).
    """

    urdf: str
    nominal: Nominal
    train: list[FrfData]
    heldout: list[FrfData]
    full: list[FrfData]
    options: CostOptions = field(default_factory=CostOptions)
    accepted: tuple[Candidate, ...] = ()
    candidate: Candidate | None = None
    places: Places = field(default_factory=Places)
    starts: tuple[StartSpec, ...] = ()
    max_iter: int = REFIT_ITER
    budget_starts: int = REFIT_BUDGET_STARTS
    fallbacks: bool = False
    probe: bool = False
    warm: bool = False
    token: int = 0


@dataclass(frozen=True)
class AttemptNote:
    """One start a refit tried: its label, the training db_rms over the noise level it
    ended at (NaN unknown), its IPOPT iterations and why it failed ("" if it did not)."""

    label: str
    ratio: float
    iterations: int
    error: str = ""

    def text(self) -> str:
        if self.error:
            return f"{self.label}: failed ({self.error})"
        r = f"{self.ratio:.2f}×" if math.isfinite(self.ratio) else "?"
        return f"{self.label}: {r} ({self.iterations} it.)"


@dataclass
class JobResult:
    """Outputs of one refit.

    Attributes:
        label: ``effect@location``, or ``"refit"`` for a model without a candidate.
        effect, location: the candidate's (None without one).
        names, values, std: refit variables (nominal first, then every new one), SI.
        n_new: number of new parameters (the accepted effects' and the candidate's).
        train_rms, heldout_rms: weighted complex-log RMS [dB] on training / held-out data.
        n_train: number of training residuals.
        heldout_db_rms, db_rms: the weighted ``db_rms`` on held-out / all data [dB], over
            the used channels; ``db_rms_unweighted`` over the points of weight ≥ 0.5.
        full_H: the model FRF per full data set, each ``(n_out, n_in, n_freq)``.
        urdf: the refitted (augmented) model as URDF text.
        wall_s: time spent [s].
        status: IPOPT's status of the kept search.
        error: why the refit failed ("" when it did not).
        chain: the model's effects in the order added, at their fitted values.
        n_own: the candidate's own parameters (the last ``n_own`` of ``values``).
        candidate: the candidate as refitted (the variant kept).
        objective: the training objective (data and prior) at the result.
        noise_ratio: the training db_rms over the predicted noise level (None unknown).
        attempts: the starts tried, in order; ``stopped``: why the loop stopped.
        variant: the variant kept, in words ("" for the candidate itself).
        end: where the kept attempt ended, as a start a later refit of the same candidate
            continues from (None for a failed refit).
        own_std: std (SI) of each of the candidate's own parameters with its other own
            structural ones held ``(n_own,)`` (:meth:`.refit.Refit.own_strength_std`; empty
            without a candidate): what the strength test divides by.
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
    db_rms_unweighted: float = math.nan
    chain: tuple[Candidate, ...] = ()
    n_own: int = 0
    candidate: Candidate | None = None
    objective: float = math.inf
    noise_ratio: float | None = None
    attempts: tuple[AttemptNote, ...] = ()
    stopped: str = ""
    variant: str = ""
    end: StartSpec | None = None
    own_std: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def failed(cls, task: Task, error: str, wall_s: float) -> JobResult:
        """The result of a task that failed numerically (``error`` says how)."""
        c = task.candidate
        return cls(
            "refit" if c is None else c.label, None if c is None else c.effect,
            None if c is None else c.location, [], np.zeros(0), np.zeros(0),
            0 if c is None else len(c.parameters), math.inf, math.inf, 0, math.inf,
            math.inf, [], "", wall_s, error=error,
        )  # fmt: skip

    def notes(self) -> str:
        """The starts tried and why the loop stopped, one line ("" for one start)."""
        if len(self.attempts) <= 1:
            return ""
        return "; ".join(a.text() for a in self.attempts) + f"; stopped: {self.stopped}"
