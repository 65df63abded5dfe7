"""Screening: a cheap figure per candidate before any full refit (:func:`screen`).

A full refit of a candidate (:mod:`.runner`) costs hundreds of IPOPT iterations; most
candidates of a diagnosis explain nothing. Each candidate is therefore screened first, from
the model the search step starts at (the parameter refit, or the model with the effects
accepted so far), with the nominal (and accepted) parameters held at their refitted values:

1. a 1-D scan of the candidate's scale (its grid, plus the scales that put its mode at each
   measured mode the model lacks), keeping the :data:`N_STARTS` best local minima;
2. from each, a short solve of the candidate's new parameters alone by the core
   (:meth:`.refit.Refit.solve_new`, :attr:`.runner.Job.new_iter` IPOPT iterations);
3. at the best of those, one Levenberg–Marquardt step over **all** parameters on the
   linearised residual, ``δ = −(JᵀJ + λ diag(JᵀJ))⁻¹ Jᵀr``: the training cost it predicts,
   ``‖r + Jδ‖²``, is the screening figure. It is the score-test idea evaluated where the
   new parameters are no longer "absent" (a compliance at infinite stiffness has no
   gradient): the new DOF's best placement, plus the first-order gain of letting every
   nominal parameter follow — which matters, because the parameter refit has already bent
   nominal parameters toward what the missing effect does.

At the first step of a search the same figure is also taken from a second origin, the
nominal model, after the short start of the full refit's second origin
(:func:`.runner._alt_start` from the new parameters the first origin found: new parameters
alone, then a few IPOPT iterations of all together),
and the lower of the two counts: the parameter refit may have bent nominal parameters so far
toward the missing effect that the true candidate, added to it, first makes the fit worse
(measured: a withheld z-guide compliance ranked 10th of 11 from the parameter refit alone).
A candidate with variants (e.g. the pivots of a rotational DOF) gets the lowest figure of its
variants (one start each).
The figure is a training cost, so screening never looks at the held-out data that decide the
verdict.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..exceptions import BondidError
from .augmented import build
from .effects import Candidate
from .refit import Refit, State
from .runner import Job, _alt_start

#: start points kept from the scan of a candidate (its variants: one each)
N_STARTS = 2
#: Levenberg–Marquardt damping of the screening step (relative to diag(JᵀJ))
LM_DAMPING = 1e-3


@dataclass
class Screening:
    """The screening of one candidate.

    Attributes:
        label, effect, location: the candidate.
        cost_new_only: training objective (weighted mean square and the prior, as
            :meth:`.refit.Refit.cost`) after the new parameters alone were fitted.
        cost: the screening figure: the training cost one joint step predicts (lower is
            better; ``inf`` when the candidate failed).
        wall_s: time spent.
        error: why it failed ("" if it did not).
        variant: the candidate or variant (variants cleared) with the lowest figure: the one
            a full refit then uses.
        start: its new parameters (SI) where the figure was taken: the full refit's start.
    """

    label: str
    effect: str
    location: str | None
    cost_new_only: float
    cost: float
    wall_s: float
    error: str = ""
    variant: Candidate | None = None
    start: tuple = ()


def predicted_cost(refit: Refit, state: State, damping: float = LM_DAMPING) -> float:
    """Training objective after one Levenberg–Marquardt step over every variable of the core's
    decision vector from ``state`` on the linearised residual (module docstring, step 3);
    never above the objective at ``state``."""
    p = refit.at(state)
    r, J = p.residual_and_jacobian(p.z0)
    if not np.all(np.isfinite(r)):
        return float("inf")
    c0 = float(r @ r)
    JtJ = J.T @ J
    g = J.T @ r
    d = np.maximum(np.diag(JtJ), 1e-12 * max(float(np.max(np.diag(JtJ))), 1e-300))
    try:
        step = -np.linalg.solve(JtJ + damping * np.diag(d), g)
    except np.linalg.LinAlgError:
        return c0
    res = r + J @ step
    return min(c0, float(res @ res))


def _figure(job: Job, n_starts: int, pick: int | None) -> tuple[float, float, int | None, tuple]:
    """(objective after the new-only solve, screening figure, start option of the second
    origin, the new parameters (SI) where the figure was taken) of ``job``'s candidate;
    ``pick``: the only start option the second origin tries."""
    cand = job.candidate
    assert cand is not None
    refit = build(job.urdf, job.nominal, job.train, job.options, job.accepted, cand).refit
    exps = np.array([p.scan for p in cand.parameters], float)
    starts = [refit.state0]
    if cand.scan_grid:
        hints = [(f / cand.ref_hz) ** 2 for f in job.hints_hz] if cand.ref_hz else []
        grid = tuple(sorted({*cand.scan_grid, *hints}))
        starts = refit.scan_starts(refit.state0, exps, grid, n_starts=n_starts)
    best: tuple[float, State] | None = None
    for s in starts:
        s, c = refit.solve_new(s, job.new_iter)
        if best is None or c < best[0]:
            best = (c, s)
    assert best is not None
    figure = predicted_cost(refit, best[1])
    new = tuple(float(v) for v in refit.new_values(best[1]))
    if job.alt_urdf is None:
        return best[0], figure, None, new
    alt = build(job.alt_urdf, job.nominal, job.train, job.options, job.accepted, cand).refit
    s_a, _, k = _alt_start(job, alt, [np.array(new)], pick)
    fig_a = predicted_cost(alt, s_a)
    if fig_a < figure:
        figure, new = fig_a, tuple(float(v) for v in alt.new_values(s_a))
    return best[0], figure, k, new


def screen(job: Job) -> Screening:
    """Screen ``job``'s candidate (module docstring); never raises for a numerical failure
    (``cost = inf`` and ``error`` set)."""
    t0 = time.perf_counter()
    cand = job.candidate
    assert cand is not None
    best = (math.inf, math.inf)
    chosen: Candidate | None = None
    start: tuple = ()
    error = ""
    pick: int | None = 0  # the second origin starts from the first origin's best only
    for k, option in enumerate((cand, *cand.variants)):
        sub = replace(job, candidate=replace(option, variants=()))
        try:
            c_new, c_fig, pick, new = _figure(sub, N_STARTS if k == 0 else 1, pick)
        except (BondidError, np.linalg.LinAlgError, ValueError) as exc:
            error = error or f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
            continue
        if c_fig < best[1]:
            best, chosen, start = (c_new, c_fig), sub.candidate, new
    if math.isfinite(best[1]):
        error = ""
    wall = time.perf_counter() - t0
    return Screening(
        cand.label, cand.effect, cand.location, best[0], best[1], wall, error, chosen, start
    )


def select(screenings: list[Screening], n_refit: int) -> list[int]:
    """Indices of the candidates to refit fully: the ``n_refit`` lowest screening figures
    (failed ones never), best first."""
    order = sorted(
        (i for i, s in enumerate(screenings) if math.isfinite(s.cost)),
        key=lambda i: screenings[i].cost,
    )
    return order[:n_refit]
