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

Each candidate (the variant kept) whose one-step figure leaves the step unexplained
(:func:`needs_profile`) also gets its joint profile (:mod:`.joint_profile`): its scale swept
with every parameter following for a few damped Gauss–Newton iterations; the search refits
the best few by that figure too, from the profile's start (:func:`profile_picks`,
:meth:`Screening.refit_start`). A candidate with springs that gets the profile also gets
one round of the restart alternation (:func:`.modal_start.placed_alternation`), a full solve
of the nominal parameters with the springs held and then of everything, from its first
start at the measured modes: a single spring (a joint compliance) placed so that its mode
sits at a missing or worst-matched measured mode, several springs (a flexible base, soft
mounts; since stop 33) each matched to the measured modes; the search refits the best
:attr:`.search.Context.n_placed` by that figure too (:func:`placed_picks`). Several springs
need it as much: a flexible base added to the parameter refit first fits worse than the
base, whose stage masses have absorbed the base's motion, and neither the one-step figure
nor the profile's short fits move them back (measured, bonder, withheld 5-lump base,
coherence data: one-step 2.43 dB and profile 1.59 dB against the base's 1.52, 17th of 17,
while the candidate's full refit reaches 1.03 dB). Where the
parameter refit has bent an existing mode onto the missing one, neither the one-step figure
nor the profile's short fits undo it (measured, gantry, withheld bridge→carriage tz
compliance, coherence data: the one-step figures tied within 1 %, the truth's profile 5th),
while the alternation from the missing mode ended at 0.93× the training noise level, five
wrong compliances at 2.1–3.0×, the base at 2.8×.

Near the noise level the profile is skipped: on the
reference case (base at 1.02× the held-out noise level) it had raised the screening's
worker time from 80 s to 193 s and refitted 2 more candidates, for the same verdict. "Near
the noise level" is judged on the training figure and, since stop 20, on the base's held-out
score too (:attr:`.runner.Job.profile_always`): a base whose training cost is near the
noise while its held-out score is not has absorbed the missing effect in the training bands,
and every one-step figure is then near the noise (measured, gantry, withheld bridge→carriage
tz compliance, harsh floor: base 1.16 dB training, 2.15 dB held-out against a held-out
noise level of 0.88 dB; the one-step figures 1.07–1.14 skipped every profile and the truth
was not refitted, while its profile, 1.04, was the lowest of all).

Which candidates are refitted fully (:func:`select`): the ``n_refit`` lowest figures, and, when
even the best figure leaves the training cost well above the noise level (more than
:data:`UNEXPLAINED_RATIO` times the cost an exact model would score on this data,
:func:`bondid.cost.noise_level.noise_level_cost`), also the candidates tied with the last of
those (figures within :data:`TIE_FRACTION` of its excess over the noise level), up to
``n_max``. Such a step has not been explained by any candidate's cheap figure: the figures of
the candidates that changed nothing then differ by far less than the one-step prediction's own
error, and the order among them says nothing (measured: a withheld translational compliance
whose mode the parameter refit had absorbed ranked 14th of 17 within 0.02 dB of the best, a
rotational candidate at the same interface 1st). The ties are therefore taken in turn from
two other orders: the ties at the site of a kept candidate (another axis of a kept interface)
first, and the ties by their figure from the second origin alone, where a missing effect the
parameter refit absorbed still shows (measured, bonder, withheld x→y translational compliance,
coherence data: the 17 first-origin figures within 4 % of the base's own with the truth 7th,
and 1 % behind the 4th kept; from the nominal model it removed 4.9 % of the base's figure
there, the next candidate 3.3 %). When the best figure is near the noise level the ranking
is trusted and ``n_refit`` are kept.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..exceptions import BondidError
from .augmented import build
from .effects import Candidate
from .job import Job, with_option
from .joint_profile import damped_step, joint_profile
from .modal_start import applies, placed_alternation
from .refit import Refit, State
from .runner import _alt_start
from .scan_grid import scan_grid

#: start points kept from the scan of a candidate (its variants: one each)
N_STARTS = 2
#: Levenberg–Marquardt damping of the screening step (relative to diag(JᵀJ))
LM_DAMPING = 1e-3
#: a step whose best screening figure is above this multiple of the noise-level cost is
#: unexplained (the ratio :mod:`.rescue` uses for a refit above the noise level)
UNEXPLAINED_RATIO = 1.5
#: figures within this fraction of the last kept one's excess over the noise-level cost tie
#: with it (module docstring)
TIE_FRACTION = 0.02


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
        noise_cost: the training objective an exact model would score on this data
            (:func:`bondid.cost.noise_level.noise_level_cost`; NaN when unknown), the same for
            every candidate of a step.
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
    noise_cost: float = math.nan
    #: the figure from each origin (first: the step's base; second: the nominal model, NaN
    #: without one) of the variant kept
    by_origin: tuple[float, float] = (math.nan, math.nan)
    #: the joint profile's figure of the variant kept (:mod:`.joint_profile`: the lowest
    #: training objective of short fits of every parameter over the candidate's scale; inf
    #: when it failed) and its new parameters (SI) there
    profile_cost: float = math.inf
    profile_start: tuple = ()
    #: the placed alternation's figure of a candidate with springs (its training objective;
    #: inf when not run) and its new parameters (SI) there
    placed_cost: float = math.inf
    placed_start: tuple = ()

    def refit_start(self, by_profile: bool, by_placed: bool = False) -> tuple:
        """The full refit's start of the new parameters: the placed alternation's when the
        candidate was kept by it (``by_placed``) or its figure is the lowest; else the joint
        profile's when the candidate was kept by it (``by_profile``) or its profile figure is
        the lower one, and it has one; else :attr:`start`. Measured, bonder_b, withheld
        carriage→slide tz compliance, no coherence: the truth, refitted as a tie from its
        one-step start (2.26 dB), ended rigid at the base's figure; from its profile's
        (1.89 dB) it was named at 1.02 dB."""
        placed = self.placed_cost < min(self.cost, self.profile_cost)
        if (by_placed or placed) and self.placed_start:
            return self.placed_start
        lower = self.profile_cost < self.cost
        return self.profile_start if (by_profile or lower) and self.profile_start else self.start


def predicted_cost(refit: Refit, state: State, damping: float = LM_DAMPING) -> float:
    """Training objective after one Levenberg–Marquardt step over every variable of the core's
    decision vector from ``state`` on the linearised residual (module docstring, step 3);
    never above the objective at ``state``."""
    p = refit.at(state)
    r, J = p.residual_and_jacobian(p.z0)
    if not np.all(np.isfinite(r)):
        return float("inf")
    c0 = float(r @ r)
    step = damped_step(J, r, damping)
    if step is None:
        return c0
    res = r + J @ step
    return min(c0, float(res @ res))


def noise_cost(refit: Refit) -> float:
    """The noise-level cost of ``refit``'s training data (:attr:`.refit.Refit.noise_cost`,
    the weights' basis; NaN when the data carry no noise estimate)."""
    c = refit.noise_cost
    return float(c) if c is not None and math.isfinite(c) else math.nan


Figure = tuple[float, float, int | None, tuple, float, tuple[float, float], Refit]


def _figure(job: Job, n_starts: int, pick: int | None, noise: bool = True) -> Figure:
    """(objective after the new-only solve, screening figure, start option of the second
    origin, the new parameters (SI) where the figure was taken, the noise-level cost or NaN
    without ``noise``) of ``job``'s candidate; ``pick``: the only start option the second
    origin tries; last, the first origin's refit (the joint profile runs on it)."""
    cand = job.candidate
    assert cand is not None
    refit = build(job.urdf, job.nominal, job.train, job.options, job.accepted, cand).refit
    exps = np.array([p.scan for p in cand.parameters], float)
    starts = [refit.state0]
    grid, _ = scan_grid(cand, job.hints_hz)
    if grid:
        starts = refit.scan_starts(refit.state0, exps, grid, n_starts=n_starts)
    best: tuple[float, State] | None = None
    for s in starts:
        s, c = refit.solve_new(s, job.new_iter)
        if best is None or c < best[0]:
            best = (c, s)
    assert best is not None
    figure = predicted_cost(refit, best[1])
    new = tuple(float(v) for v in refit.new_values(best[1]))
    floor = noise_cost(refit) if noise else math.nan
    if job.alt_urdf is None:
        return best[0], figure, None, new, floor, (figure, math.nan), refit
    alt = build(job.alt_urdf, job.nominal, job.train, job.options, job.accepted, cand).refit
    s_a, _, k = _alt_start(job, alt, [np.array(new)], pick)
    fig_a = predicted_cost(alt, s_a)
    both = (figure, fig_a)
    if fig_a < figure:
        figure, new = fig_a, tuple(float(v) for v in alt.new_values(s_a))
    return best[0], figure, k, new, floor, both, refit


def screen(job: Job) -> Screening:
    """Screen ``job``'s candidate (module docstring); never raises for a numerical failure
    (``cost = inf`` and ``error`` set)."""
    t0 = time.perf_counter()
    cand = job.candidate
    assert cand is not None
    best = (math.inf, math.inf)
    chosen: Candidate | None = None
    chosen_refit: Refit | None = None
    start: tuple = ()
    error = ""
    pick: int | None = 0  # the second origin starts from the first origin's best only
    floor = math.nan
    both = (math.nan, math.nan)
    for k, option in enumerate((cand, *cand.variants)):
        sub = with_option(job, option)
        try:
            c_new, c_fig, pick, new, f, b, r = _figure(sub, N_STARTS if k == 0 else 1, pick, k == 0)
            floor = f if k == 0 else floor
        except (BondidError, np.linalg.LinAlgError, ValueError) as exc:
            error = error or f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
            continue
        if c_fig < best[1]:
            best, chosen, start, both, chosen_refit = (c_new, c_fig), sub.candidate, new, b, r
    profile: tuple[float, tuple[float, ...]] = (math.inf, ())
    placed: tuple[float, tuple[float, ...]] = (math.inf, ())
    if (
        chosen is not None
        and chosen_refit is not None
        and needs_profile(best[1], floor, job.profile_always)
    ):
        try:
            pr = joint_profile(chosen_refit, chosen, job.hints_hz)
            profile = (pr.cost, pr.new)
        except (BondidError, np.linalg.LinAlgError, ValueError) as exc:
            error = error or f"joint profile: {type(exc).__name__}"
        if applies(chosen):
            try:
                placed = placed_alternation(job, chosen_refit, chosen) or placed
            except (BondidError, np.linalg.LinAlgError, ValueError) as exc:
                error = error or f"placed alternation: {type(exc).__name__}"
    if math.isfinite(best[1]) or math.isfinite(profile[0]):
        error = ""
    wall = time.perf_counter() - t0
    return Screening(
        cand.label, cand.effect, cand.location, best[0], best[1], wall, error, chosen, start,
        floor, both, profile[0], profile[1], placed[0], placed[1],
    )  # fmt: skip


def needs_profile(figure: float, noise_cost: float, base_unexplained: bool = False) -> bool:
    """Does a candidate whose one-step figure is ``figure`` get the joint profile? Not when
    the figure already reaches :data:`UNEXPLAINED_RATIO` times the noise-level cost
    ``noise_cost`` (the step is explained there, as :func:`select` trusts the ranking),
    unless ``base_unexplained`` (the base's held-out score is above the held-out noise level,
    :attr:`.runner.Job.profile_always`: a training figure near the noise says nothing then);
    always without a noise level (NaN)."""
    if base_unexplained:
        return True
    return not (math.isfinite(noise_cost) and figure <= UNEXPLAINED_RATIO * noise_cost)


def site(s: Screening) -> str | None:
    """Where a candidate acts, without its axis: ``"x_stage->y_stage"`` for
    ``"x_stage->y_stage:tz"``, the location itself otherwise."""
    return s.location.split(":")[0] if s.location else None


def _interleaved(*orders: list[int]) -> list[int]:
    """The items of ``orders`` taken in turn (first of each, then second of each, ...),
    each once."""
    out: list[int] = []
    for k in range(max((len(o) for o in orders), default=0)):
        for o in orders:
            if k < len(o) and o[k] not in out:
                out.append(o[k])
    return out


def select(screenings: list[Screening], n_refit: int, n_max: int | None = None) -> list[int]:
    """Indices of the candidates to refit fully (failed ones never): the ``n_refit`` lowest
    figures, then, when the best figure leaves the step unexplained (above
    :data:`UNEXPLAINED_RATIO` times the noise-level cost), the candidates that tie with the
    last kept (within :data:`TIE_FRACTION` of its excess over the noise-level cost), up to
    ``n_max`` in all (default ``n_refit``: no ties).

    Among ties the figure's order says nothing, so two other orders take turns:

    - ties at the :func:`site` of a kept candidate first, the site of the best kept one
      first, then the others, each by figure (a compliant interface shows at the screening
      through whichever of its axes the start reaches: a rotation about an offset pivot
      moves the child much like a translation). Measured, bonder_b, withheld carriage→slide
      tz compliance, no coherence: the rz axis there ranked 1st of 17, and the truth, tied at
      the 13th figure, came after a tie at the 4th kept candidate's site and was not refitted;
    - by the figure from the second origin, the nominal model (``by_origin[1]``; when the
      step has one): the parameter refit may have absorbed the missing effect, and then it
      shows only from the nominal model (module docstring).
    """
    order = sorted(
        (i for i, s in enumerate(screenings) if math.isfinite(s.cost)),
        key=lambda i: screenings[i].cost,
    )
    keep = order[:n_refit]
    noise = [s.noise_cost for s in screenings if math.isfinite(s.noise_cost)]
    if not keep or not noise or n_max is None or n_max <= n_refit:
        return keep
    floor = float(np.median(noise))
    if not floor > 0 or screenings[order[0]].cost <= UNEXPLAINED_RATIO * floor:
        return keep
    last = screenings[keep[-1]].cost
    tol = TIE_FRACTION * (last - floor)
    ties = [i for i in order[n_refit:] if screenings[i].cost <= last + tol]
    rank: dict[str | None, int] = {}  # a kept site: the rank of its best kept candidate
    for k, i in enumerate(keep):
        rank.setdefault(site(screenings[i]), k)
    by_site = sorted(ties, key=lambda i: rank.get(site(screenings[i]), len(keep)))  # stable
    second = [i for i in ties if math.isfinite(screenings[i].by_origin[1])]
    by_second = sorted(second, key=lambda i: screenings[i].by_origin[1])
    return keep + _interleaved(by_second, by_site)[: n_max - n_refit]


def profile_picks(screenings: list[Screening], n: int) -> list[int]:
    """Indices of the ``n`` lowest joint-profile figures (finite ones only), best first: the
    candidates refitted fully whatever their one-step figure, from the profile's start
    (:mod:`.joint_profile`)."""
    return _lowest(screenings, n, "profile_cost")


def placed_picks(screenings: list[Screening], n: int) -> list[int]:
    """Indices of the ``n`` lowest placed-alternation figures (finite ones only), best first:
    refitted fully whatever their other figures, from the alternation's end (module
    docstring)."""
    return _lowest(screenings, n, "placed_cost")


def _lowest(screenings: list[Screening], n: int, attr: str) -> list[int]:
    ok = [i for i, s in enumerate(screenings) if math.isfinite(getattr(s, attr))]
    return sorted(ok, key=lambda i: getattr(screenings[i], attr))[: max(0, n)]
