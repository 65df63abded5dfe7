"""The pivot of an accepted rotational compliance, searched again on all data in the final
fit (:func:`refined_pivots`).

The search places a rotational compliance's pivot on its training data
(:func:`.alternatives.refine_job_pivot`); no later refit can move it (the pivot enters the
kinematics, not the parameters). When the final model's held-out score is above the held-out
noise level (the final fit's own trigger, :attr:`.job.Job.fallbacks_always`), this runs the
search of :func:`.pivot.refine_pivot` again from the final fit, inside :func:`.pivot.pivot_box`
and started at the best point of a :data:`.pivot.FINAL_GRID`-level grid over it (a second
effect accepted after the pivot was placed can leave it in another basin: bonder/jcr+al/coh,
:mod:`.pivot`'s docstring), each pivot judged by
a solve of every parameter (:data:`.pivot.FULL_EVAL_ITER` IPOPT iterations, on all data)
from the final fit's values with the pivot moved (:func:`bondid.model.move_pivot`) and the
spring and damper scaled so that the DOF keeps its frequency and damping ratio
(:func:`moved`). The best pivot is refitted with the final fit's own iterations and kept
when its objective is lower.

Measured on bonder/jcr/acc of the blind benchmark (stop 32, ``bondid.fit`` on all data from
the search's final model with only the pivot moved): at the search's pivot 1.718 dB; on a
10 mm grid across the axis the figure falls smoothly to 0.751 dB at the truth's pivot (20 mm
and 10 mm away), the truth model's own figure; from the truth's own parameters with the
search's pivot the fit ends at 1.720 dB (the pivot, not the basin). The final fit with this
search from that case's true candidate: 2.207 -> 0.820 dB (1.722 without it).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..exceptions import BondidError
from ..model.authoring import move_pivot
from ..model.document import UrdfDocument
from .augmented import with_values
from .effects import Candidate
from .job import Job, JobResult, direct
from .pivot import (
    FINAL_GRID,
    FULL_EVAL_ITER,
    FULL_MAX_EVALS,
    is_rotational_compliance,
    pivot_box,
    refine_pivot,
    with_pivot,
)


def rotational(chain: tuple[Candidate, ...]) -> list[int]:
    """Indices of the rotational joint compliances in ``chain``."""
    return [k for k, c in enumerate(chain) if is_rotational_compliance(c)]


def moved(
    urdf: str, chain: tuple[Candidate, ...], k: int, pivot: np.ndarray
) -> tuple[str, tuple[Candidate, ...]]:
    """``urdf`` and ``chain`` with the pivot of ``chain[k]`` (a rotational compliance built
    into ``urdf``) at ``pivot`` (m, the frame it was inserted in), its stiffness and damping
    scaled by the ratio of the DOF's effective inertias about the new and the old pivot (the
    same spring-alone frequency and damping ratio)."""
    from .effects.topology import effective_inertia

    cand = chain[k]
    joint = str(cand.spec["joint"])
    doc = UrdfDocument.from_string(urdf, source="final model")
    before = effective_inertia(doc, joint)
    move_pivot(doc, joint, pivot)
    ratio = effective_inertia(doc, joint) / before
    values = [p.initial * ratio for p in cand.parameters]
    new = with_values(with_pivot(cand, np.asarray(pivot, float)), values)
    return doc.to_string(), (*chain[:k], new, *chain[k + 1 :])


def refined_pivots(job: Job, result: JobResult) -> tuple[JobResult, str]:
    """The final job's ``result`` with the pivot of each rotational compliance of its chain
    searched again (module docstring): the refit at the best pivots when its objective is
    lower, else ``result``; and a one-line note ("" without a rotational compliance)."""
    from .runner import _setup, run_job

    picks = rotational(result.chain)
    if not picks or result.error:
        return result, ""
    urdf, chain = result.urdf, result.chain
    notes = []
    for k in picks:
        start = np.asarray(chain[k].spec["pivot"], float)
        failed: list[str] = []

        def cost(c: Candidate, k: int = k, urdf: str = urdf, chain=chain, failed=failed) -> float:
            try:
                u, ch = moved(urdf, chain, k, np.asarray(c.spec["pivot"], float))
                refit = _setup(u, replace(job, urdf=u, accepted=ch)).refit
                return float(refit.solve(refit.state0, direct(FULL_EVAL_ITER))[1])
            except (BondidError, np.linalg.LinAlgError, ValueError) as err:  # skipped, and said
                failed.append(f"{type(err).__name__}: {err}")
                return float("inf")

        box = pivot_box(chain[k])
        extent = None if box is None else box[1] - box[0]
        best, figure, n = refine_pivot(
            chain[k], cost, extent, with_pivot, box, FULL_MAX_EVALS, FINAL_GRID
        )
        pivot = np.asarray(best.spec["pivot"], float)
        notes.append(
            f"{chain[k].label}: {n} pivots tried, {np.round(start * 1e3, 1).tolist()} -> "
            f"{np.round(pivot * 1e3, 1).tolist()} mm (figure {figure:.4g}"
            + (f"; {len(failed)} failed, first: {failed[0]}" if failed else "")
            + ")"
        )
        if not np.allclose(pivot, start):
            urdf, chain = moved(urdf, chain, k, pivot)
    if urdf == result.urdf:
        return result, "; ".join([*notes, "the pivots kept"])
    again = run_job(replace(job, urdf=urdf, accepted=chain, fallbacks_always=False))
    keep = not again.error and again.objective < result.objective
    verdict = f"refitted there: objective {result.objective:.4g} -> {again.objective:.4g}, " + (
        "kept" if keep else "not kept"
    )
    return (again if keep else result), "; ".join([*notes, verdict])


def run_final(job: Job) -> JobResult:
    """The final job (:func:`.runner.run_job`), then, when its trigger is set, the nominal
    restart (:mod:`.final_restart`; its note in ``extra["nominal restart"]``) and the pivot
    search of the module docstring (``extra["pivot search"]``)."""
    from .final_restart import nominal_restart
    from .runner import run_job

    result = run_job(job)
    if not job.fallbacks_always:
        return result
    result, restart = nominal_restart(job, result)
    if restart:
        result.extra["nominal restart"] = restart
    out, note = refined_pivots(job, result)
    if note:
        out.extra["pivot search"] = note
    if out is not result:  # the final job's fallbacks ran before the search: keep their note
        notes = (result.extra.get("rescue", ""), out.extra.get("rescue", ""))
        out.extra["rescue"] = "; ".join(str(x) for x in notes if x)
    return out
