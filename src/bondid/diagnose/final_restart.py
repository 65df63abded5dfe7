"""The nominal restart of the final fit (:func:`nominal_restart`): the final model's nominal
parameters back at the parameter refit's values, its effects' parameters held where the
final fit put them, then everything.

Each search step refits every parameter from the model it starts from, so a step can leave
a nominal parameter far from where the data put it before the effect was added: the new
parameters and the nominal ones trade against each other, and once a nominal spring has
moved its mode out of place no local solve on the same data brings it back (the cost no
longer sees that mode where it belongs). The effects' parameters, though, may be right. The
restart alternation of :mod:`.modal_start` (nominal parameters alone with the new ones held,
then everything) is the path back it found for a candidate's refit; here it runs once more on
the final model, from the parameter refit's nominal values, which were fitted without any
effect and kept every measured mode paired.

Measured on bonder_b/jct+sd/nocoh of the blind benchmark (a withheld sensor delay on ``ya``
and a ``slide_x→rocker`` tx compliance, both named, the delay 50.5 µs against the truth's
50, the stiffness 1.51e7 N/m against 1.56e7): the final fit ended at 1.311 dB on all data
against the truth model's 1.021 dB, with the carriage's yaw stiffness at its lower bound
(2.1e5 N·m/rad; parameter refit 5.0e5, truth 4.8e5), its mode at 274 Hz where the data have
528 Hz; the band continuation and the staged schedule from there ended at 3.3× and 4.1× the
noise level. (Figures of the restart: README, stop 53.)

It runs where the final fit's fallbacks run (the final model's held-out score above the
held-out noise level, :attr:`.job.Job.fallbacks_always`), on a final model with at least one
accepted effect (without one the final model is the parameter refit itself), and is kept
when its training objective on all data is lower than the final fit's.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ..exceptions import BondidError
from .job import Job, JobResult


def nominal_restart(job: Job, result: JobResult) -> tuple[JobResult, str]:
    """The final job's ``result`` (its model with the accepted effects, fitted on all data)
    refitted by the restart alternation from the nominal values of ``job.restart_urdf`` (the
    parameter refit) with the effects' parameters at ``result``'s values (module
    docstring). Returns the result kept (the restart's when its objective is lower) and a
    note; ``(result, "")`` when it does not apply."""
    from .modal_start import alternation
    from .rescue import noise_ratio_at
    from .runner import _setup, finish

    if not (job.fallbacks_always and job.restart_urdf and result.chain) or result.error:
        return result, ""
    t0 = time.perf_counter()
    # a start far from the final fit's point: IPOPT's own initial barrier, not the final
    # fit's warm start (with it, the case of the module docstring ended at 1.091 dB)
    sub = replace(job, accepted=result.chain, fallbacks_always=False, ipopt=())
    try:
        aug = _setup(job.restart_urdf, sub)
        refit = aug.refit
        state, cost, res = alternation(refit, refit.new_values(refit.state0))
    except (BondidError, np.linalg.LinAlgError, ValueError) as err:
        return result, f"nominal restart failed: {type(err).__name__}: {err}"
    ratio = noise_ratio_at(refit, state)
    said = f"{ratio:.2f}x the noise level" if ratio is not None else "done"
    if not cost < result.objective:
        return result, (
            f"nominal restart from the parameter refit: objective {cost:.4g} against"
            f" {result.objective:.4g} ({said}), not kept"
        )
    again = finish(sub, aug, state, res, {}, t0)
    if again.error or not again.objective < result.objective:
        return result, f"nominal restart: {again.error or 'no lower objective'}, not kept"
    rescued = again.extra.get("rescue")
    note = (
        f"nominal restart from the parameter refit: objective {result.objective:.4g} ->"
        f" {again.objective:.4g} ({said}), kept" + (f"; then {rescued}" if rescued else "")
    )
    return replace(again, extra=dict(result.extra)), note
