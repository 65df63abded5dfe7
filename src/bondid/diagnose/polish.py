"""The polish of an accepted effect's refit (:func:`polish`): the full solve it did not get.

A candidate's refit is capped at :attr:`.search.Context.refit_iter` IPOPT iterations from
each origin (30 by default): enough to rank the candidates of a step, not always to converge
the one the step accepts. Before it is reported (``db_rms_after``, ``augmented.urdf``) and
before the next step starts from it, the accepted model — the nominal parameters and every
accepted effect's parameters free, on the training data, the same bounds and prior — gets
the solve the parameter refit gets (``Settings.ipopt_iter`` iterations), then the rescue of
every refit (:func:`.runner.finish`). The polished refit replaces the accepted one only
under the rule of every choice between two refits (:func:`.keep.replaces`: a lower training
objective, not bought with a worse held-out figure). The verdict itself is unchanged: it was
taken on the refits as ranked.

Measured on the kept final models of stop 28 (``bondid.fit`` from ``augmented.urdf``, all
data, no iteration cap): bonder_b/jct/nocoh 0.737 → 0.436 dB (truth model 0.436),
bonder/jcr/nocoh 1.417 → 1.087 (truth 0.881), bonder_b/jcr/harsh 1.105 → 1.003 (truth 0.915).
"""

from __future__ import annotations

from dataclasses import replace

from .job import Job, JobResult
from .keep import known, replaces
from .runner import run_job


def polish_job(winner: JobResult, base: Job, max_iter: int) -> Job:
    """The job that polishes ``winner`` (its model and accepted effects, no new candidate),
    with the data, space and options of ``base`` (any job of the step) and ``max_iter``
    IPOPT iterations of the direct solve."""
    return replace(
        base, urdf=winner.urdf, candidate=None, accepted=winner.chain, all_iter=max_iter,
        alt_urdf=None, start_new=(), wider=False, modal=False, profile_always=False,
    )  # fmt: skip


def polished(winner: JobResult, job: Job, result: JobResult) -> JobResult:
    """``winner`` with the figures, values and model of the polish ``result`` (of ``job``:
    :func:`polish_job`) when they replace it (module docstring), else ``winner``; either
    way with a ``polish`` note in ``extra``."""
    if result.error or list(result.names) != list(winner.names):
        note = f"not kept: {result.error or 'the polished refit has other parameters'}"
        return replace(winner, extra={**winner.extra, "polish": note})
    keep = replaces(
        job, winner.objective, known(winner.heldout_rms), result.objective,
        known(result.heldout_rms),
    )  # fmt: skip
    note = (
        f"{job.all_iter} iterations: training objective {winner.objective:.4g} -> "
        f"{result.objective:.4g}, held-out {winner.heldout_db_rms:.3f} -> "
        f"{result.heldout_db_rms:.3f} dB, all data {winner.db_rms:.3f} -> {result.db_rms:.3f} dB"
        + (", kept" if keep else ", not kept")
    )
    extra = {**winner.extra, "polish": note}
    if "rescue" in result.extra:
        extra["polish rescue"] = result.extra["rescue"]
    if not keep:
        return replace(winner, extra=extra, wall_s=winner.wall_s + result.wall_s)
    return replace(
        winner, values=result.values, std=result.std, train_rms=result.train_rms,
        heldout_rms=result.heldout_rms, heldout_db_rms=result.heldout_db_rms,
        db_rms=result.db_rms, full_H=result.full_H, urdf=result.urdf, status=result.status,
        db_rms_unweighted=result.db_rms_unweighted, chain=result.chain,
        objective=result.objective, noise_ratio=result.noise_ratio, extra=extra,
        wall_s=winner.wall_s + result.wall_s,
    )  # fmt: skip


def polish(winner: JobResult, base: Job, max_iter: int, pool: object | None = None) -> JobResult:
    """The accepted ``winner`` polished (module docstring); ``base``: a job of its step (data,
    space, options); ``pool``: a worker pool with ``submit`` (None: run here)."""
    job = polish_job(winner, base, max_iter)
    run = run_job if pool is None else lambda j: pool.submit(run_job, j).result()  # type: ignore[attr-defined]
    result = run(job)
    return polished(winner, job, result)
