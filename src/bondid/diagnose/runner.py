"""One refit job: the parameter-only baseline or one candidate effect (runs in a worker).

A job augments the (parameter-refitted) model with its candidate, refits the candidate's new
parameters and the nominal ones on the training data, and evaluates the result on the held-out
data and on all data. Steps for a candidate:

1. starting point: a coarse 1-D scan of the candidate's scale (its modes sweep the band, or
   its delay/lag sweeps microseconds to milliseconds), then, for candidates with several
   scanned parameters, one coordinate scan of each;
2. bounded least squares of the new parameters alone (nominal ones fixed at the refit);
3. bounded least squares of new and nominal parameters together.

Everything a job needs travels in :class:`Job` (URDF text, data, plain values), so it pickles
to a worker process.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..exceptions import BondidError
from ..model.document import UrdfDocument
from ..model.parameters import set_parameter
from .effects import Candidate, get_effect
from .engine import Refit, Variable

DAMPING_FACTORS = (1.0, 4.0)
COORD_GRID = tuple(float(x) for x in np.geomspace(1 / 30, 30, 9))


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
    alt_start: list[float] | None = None
    max_nfev_all: int = 30


@dataclass
class JobResult:
    """Outputs of one job.

    Attributes:
        label: ``effect@location`` or ``"refit"`` for the baseline.
        names, values, std: refit variables (nominal first, then new), SI.
        n_new: number of new parameters.
        train_rms, heldout_rms: weighted complex-log RMS [dB] (coherence weights).
        n_train: number of training residuals.
        heldout_db_rms, db_rms: the spec's unweighted figure on held-out / all data [dB].
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


def _modifier(effect, candidate):  # type: ignore[no-untyped-def]
    def fn(values, freq_hz, outputs, inputs):  # type: ignore[no-untyped-def]
        return effect.modifier(candidate, values, freq_hz, outputs, inputs)

    return fn


def _unweighted_db_rms(refit: Refit, u: np.ndarray) -> float:
    from .gap import gap_report
    from .split import mask_incoherent

    sets = [mask_incoherent(b.data) for b in refit.problem.blocks]
    chans = refit.problem.options.channels
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


def _run(job: Job, t0: float) -> JobResult:
    doc = UrdfDocument.from_string(job.urdf, source="refit model")
    cand = job.candidate
    variables = list(job.nominal)
    modifier = None
    if cand is not None:
        effect = get_effect(cand.effect)
        doc = effect.augment(doc, cand)
        k_mod = 0
        for p in cand.parameters:
            mod = None
            if not p.members:
                mod, k_mod = k_mod, k_mod + 1
            variables.append(
                Variable(f"{p.name}", p.initial, p.lower, p.upper, p.members, mod, p.unit)
            )
        if effect.is_modifier:
            modifier = _modifier(effect, cand)
    n_nom = len(job.nominal)
    n_new = len(variables) - n_nom
    refit = Refit(doc, job.train, variables, modifier=modifier, options=job.options)
    u = refit.u0.copy()
    status = ""
    if cand is None:
        u, out = refit.solve(u, max_nfev=job.max_nfev_all)
    else:
        new_idx = list(range(n_nom, len(variables)))
        exps = np.zeros(len(variables))
        exps[n_nom:] = [p.scan for p in cand.parameters]
        origins = [u]
        if job.alt_start is not None:
            vals = refit.values(u)
            vals[:n_nom] = job.alt_start
            alt = np.clip(refit._to_u(vals), refit.lower, refit.upper)
            origins.append(alt)
        starts = []
        for k_o, origin in enumerate(origins):
            found = [origin]
            if cand.scan_grid:
                damp = (exps == 0.5).astype(float)
                bases = (
                    [origin + damp * np.log(f) for f in DAMPING_FACTORS] if damp.any() else [origin]
                )
                found = []
                for b in bases:
                    found += refit.scan_starts(b, exps, cand.scan_grid, n_starts=job.n_starts)
                found.sort(key=refit.cost)
            n_keep = job.n_starts - (len(origins) - 1) if k_o == 0 else 1
            starts += found[: max(1, n_keep)]
        best = None
        for u_s in starts:
            scanned = [n_nom + i for i, p in enumerate(cand.parameters) if p.scan == 1.0]
            if len(scanned) > 1:
                for k in scanned:
                    e = np.zeros(len(variables))
                    e[k] = 1.0
                    u_s = refit.scan(u_s, e, COORD_GRID)
            u_s, _ = refit.solve(u_s, free=new_idx, max_nfev=job.max_nfev_new)
            u_s, o_s = refit.solve(u_s, max_nfev=job.max_nfev_all)
            if best is None or o_s.cost < best[1].cost:
                best = (u_s, o_s)
        assert best is not None
        u, out = best
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
        heldout_db_rms=_unweighted_db_rms(held, u),
        db_rms=_unweighted_db_rms(full, u),
        full_H=full.frf_for_data(u),
        urdf=doc.to_string(),
        wall_s=time.perf_counter() - t0,
        status=status,
    )
