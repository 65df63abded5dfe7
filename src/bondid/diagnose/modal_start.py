"""Starts from the measured modes for a candidate with several stiffnesses, and the restart
alternation that refits from them (:func:`modal_restarts`).

A candidate that adds several independent springs (soft mounts: six; a flexible base: three)
has one mode per spring, and its scan moves them all together from fixed ratios. Measured
on soft mounts withheld from two designs (gantry/sm/acc, bonder_b/sm/coh), its full refit
stopped at 2.9–3.2× the training noise level with two or four springs run stiff (their modes
out of band, where the cost no longer sees them), although the candidate fits the truth's
data at 0.78–0.79× the noise level. Two findings make the path back:

1. **The nominal parameters must move with the springs held.** From the truth's spring
   values and the parameter refit's nominal values, one solve of everything went to another
   basin (3.0–3.6×); the nominal parameters alone with the springs held, then everything,
   reached 0.77–0.80×. The basin is narrow: the truth's springs scaled by 0.4 or 2.5 did not
   reach it. So each start is refitted by the **restart alternation**: the nominal parameters
   back at the job's model (the parameter refit), the new ones held at the start, a solve of
   the nominal parameters alone, then of everything; the new values it ends at start the next
   round (:data:`ROUNDS`). Measured: from springs within ~40 % of the truth's and the damping
   ratios at their start values, round 1 ended at 4.2× with every spring within 6 % of the
   truth's, round 2 at 0.76× (the noise level).
2. **Starts from the measured modes.** Each spring is set so that the model's modes match the
   measured ones (:func:`identify_modes` of the data) in frequency and residue MAC: a
   coordinate search of each spring on the matching cost (:func:`matching_cost`), from each
   scale that puts the candidate's modes at a missing mode (``Job.hints_hz``) and from its
   start, twice: over the spring's whole scan range and within :data:`LOCAL_SPAN` of the
   scale (:data:`MATCH_POINTS` values each). The whole range alone can move a spring onto a
   far mode the nominal parameters' errors left unmatched: on bonder_b/sm/coh it put two
   mounts at the 379 and 476 Hz structural modes, and the alternation from those starts
   ended at 5.85× the noise level; with the local searches, at 0.76×. Which start is right
   the matching cost does not tell reliably (on bonder_b/sm/coh two of four starts led to the
   noise level, not the best-matching one), so every distinct start gets the alternation and
   the lowest training objective is kept, against the refit so far by :mod:`.keep`'s rule.
3. **On every variant.** The alternation reaches the noise level only from the right variant
   of the candidate (e.g. the elastic centre of soft mounts), which the refits before it do
   not always keep, so :func:`modal_step` runs it on each other variant while the refit is
   still stuck.
4. **One spring: starts placed at the measured modes.** A candidate with a single spring (a
   joint compliance) is stuck the same way: the parameter refit has bent the nominal
   parameters around the missing mode, so the new mode first makes the fit worse and every
   local refit runs the spring stiff (measured, bonder_b with a withheld carriage→slide tz
   compliance, accelerance data: every refit ended at 1.29× the training noise level with
   the stiffness at 8·10¹⁰ N/m). The matching search does not leave that end either (its one
   start stayed rigid: the bent model already pairs every measured mode). The alternation
   from the spring placed so that the candidate's mode sits at a measured mode reached 0.71×
   from each of the five in-band modes tried (243–684 Hz); four wrong candidates of the same
   case ended at 1.02–1.29× from the same starts. So a single spring's starts are
   :func:`placed_starts` (the missing modes first, then the measured modes the model matches
   worst, :data:`PLACED_STARTS` in all); the alternation stops at the first start that ends
   at the training noise level (:data:`.rescue.RESCUE_RATIO`). It runs on the kept variant
   only: on the other pivots of two rotational compliances of the same case it took 836 and
   865 s of worker time per candidate, for nothing kept.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..optim.search import Step
from .augmented import Augmented
from .effects import Candidate
from .mode_match import job_modes, matching_cost, measured_modes, mode_mismatch, model_modes_hz
from .refit import Refit, State

if TYPE_CHECKING:
    from ..data.measurement import FrfData
    from .job import Job
    from .modal_id import IdentifiedMode

#: points of the matching's coordinate search of each spring: log-spaced multipliers of its
#: start value over the candidate's scan grid (a spring is not moved beyond the range its
#: own scan covers: a mode pushed out of band matches nothing and costs nothing)
MATCH_POINTS = 21
#: the second search from each scale stays within this factor of it (stiffness; √10 ≈ 3.2×
#: in frequency; module docstring, point 2)
LOCAL_SPAN = 10.0
#: coordinate sweeps of the matching search (it stops earlier when a sweep moves nothing)
MATCH_SWEEPS = 2
#: rounds of the restart alternation and IPOPT iterations of each of its solves
ROUNDS = 2
ROUND_ITER = 100
#: starts whose springs all agree within this factor are the same start
SAME_START = 1.05
#: starts of a single spring placed at measured modes (module docstring, point 4), and the
#: factor in frequency within which two modes give one start
PLACED_STARTS = 3
SAME_MODE = 1.1


def springs(cand: Candidate) -> list[int]:
    """Indices of ``cand``'s stiffnesses (structural new parameters, i.e. with URDF members,
    scanned with exponent 1; a delay or a lag time is scanned so too, but is no spring)."""
    return [i for i, q in enumerate(cand.parameters) if q.scan == 1.0 and q.members]


def applies(cand: Candidate | None) -> bool:
    """Does ``cand`` add a spring (the case this module is for)?"""
    return cand is not None and len(springs(cand)) >= 1


def single(cand: Candidate | None) -> bool:
    """Does ``cand`` add exactly one spring (:func:`placed_starts`)?"""
    return cand is not None and len(springs(cand)) == 1


def placed_starts(
    refit: Refit, cand: Candidate, data: Sequence[FrfData], hints_hz: Sequence[float],
    measured: Sequence[Sequence[IdentifiedMode]],
) -> list[np.ndarray]:  # fmt: skip
    """Starts ``(n_new,)`` (SI) of a single-spring candidate (module docstring, point 4): the
    spring scaled by ``(f/ref_hz)²`` so that the candidate's mode sits at ``f``, for the
    missing modes ``hints_hz`` first, then the measured modes inside their data set's band
    that the model at ``refit``'s start matches worst (:func:`mode_mismatch`); modes within
    :data:`SAME_MODE` of one already taken, and scales outside the candidate's scan range,
    are skipped; at most :data:`PLACED_STARTS`. When none of those gives a start (e.g. under
    a harsh noise floor only a rigid-body mode was identified, and no mode is missing), the
    model's own modes inside the data's band at the start, lowest first: the refitted model
    puts them where the measured peaks are. Empty without a reference frequency."""
    from ..exceptions import BondidError

    if not cand.ref_hz or not cand.scan_grid or not single(cand):
        return []
    inside = [
        [m for m in meas if d.freq_hz[0] <= m.f_hz <= d.freq_hz[-1]]
        for meas, d in zip(measured, data, strict=True)
    ]
    try:
        ranked = sorted(mode_mismatch(refit, refit.state0, inside, data), key=lambda t: -t[0])
    except (BondidError, np.linalg.LinAlgError, ValueError):
        ranked = []
    lo, hi = min(cand.scan_grid), max(cand.scan_grid)
    ref = float(cand.ref_hz)
    i = springs(cand)[0]
    v0 = refit.new_values(refit.state0)
    taken: list[float] = []
    out: list[np.ndarray] = []

    def place(freqs: Sequence[float]) -> None:
        for f in freqs:
            g = (f / ref) ** 2
            if len(out) == PLACED_STARTS or not lo <= g <= hi:
                continue
            if any(abs(np.log(f / t)) < np.log(SAME_MODE) for t in taken):
                continue
            taken.append(f)
            v = v0.copy()
            v[i] = v0[i] * g
            out.append(v)

    place([*hints_hz, *(f for _, f in ranked)])
    if not out:
        place(model_modes_hz(refit, data))
    return out


def placed_alternation(job: Job, refit: Refit, cand: Candidate) -> tuple[float, tuple] | None:
    """The screening's figure of a candidate with springs (:mod:`.screen`): one round of the
    restart alternation on ``refit`` from its first :func:`modal_starts` (``job``'s missing
    modes and measured modes: a single spring's :func:`placed_starts`, several springs
    matched to the measured modes); (training objective, new parameters (SI) there), or None
    when there is no start."""
    starts = modal_starts(refit, cand, job.full, job.hints_hz, job_modes(job))
    if not starts:
        return None
    state, cost, _ = alternation(refit, starts[0], rounds=1)
    return cost, tuple(float(v) for v in refit.new_values(state))


def modal_starts(
    refit: Refit, cand: Candidate, data: Sequence[FrfData], hints_hz: Sequence[float] = (),
    measured: Sequence[Sequence[IdentifiedMode]] | None = None,
) -> list[np.ndarray]:  # fmt: skip
    """Distinct starts ``(n_new,)`` (SI) of ``cand``'s new parameters, springs matched to the
    measured modes of ``data`` (module docstring; ``measured``: those modes, when already
    identified by :func:`measured_modes`), the other new parameters at their start values;
    best matching first; a single spring's are its :func:`placed_starts`. Empty when no data
    set has an identified mode (several springs)."""
    if measured is None:
        measured = measured_modes(data)
    if single(cand):
        return placed_starts(refit, cand, data, hints_hz, measured)
    if not any(measured):
        return []
    v0 = refit.new_values(refit.state0)
    idx = springs(cand)
    lo, hi = (min(cand.scan_grid), max(cand.scan_grid)) if cand.scan_grid else (1e-4, 1e2)
    grid = np.geomspace(lo, hi, MATCH_POINTS)
    scales = {1.0}
    if cand.ref_hz and cand.scan_grid:
        scales |= {(h / cand.ref_hz) ** 2 for h in hints_hz if lo <= (h / cand.ref_hz) ** 2 <= hi}
    found: list[tuple[float, np.ndarray]] = []
    for g in sorted(scales):
        local = np.clip(g * np.geomspace(1 / LOCAL_SPAN, LOCAL_SPAN, MATCH_POINTS), lo, hi)
        for multipliers in (grid, np.unique(local)):
            c, v = _coordinate_match(refit, v0, idx, g, multipliers, measured, data)
            if np.isfinite(c):
                found.append((c, v))
    found.sort(key=lambda t: t[0])
    out: list[np.ndarray] = []
    for _, v in found:
        if all(np.max(np.abs(np.log(v[idx] / u[idx]))) > np.log(SAME_START) for u in out):
            out.append(v)
    return out


def _coordinate_match(
    refit: Refit, v0: np.ndarray, idx: Sequence[int], g: float, multipliers: np.ndarray,
    measured: Sequence[Sequence[IdentifiedMode]], data: Sequence[FrfData],
) -> tuple[float, np.ndarray]:  # fmt: skip
    """The coordinate search of :func:`modal_starts` from every spring at ``g`` times its
    start value, each spring tried at ``multipliers`` times it: (matching cost, new values)."""
    base = refit.state0
    v = v0.copy()
    v[idx] = v0[idx] * g
    c = matching_cost(refit, refit.with_new(base, v), measured, data)
    for _ in range(MATCH_SWEEPS):
        moved = False
        for i in idx:
            trials = []
            for m in multipliers:
                w = v.copy()
                w[i] = v0[i] * m
                trials.append((matching_cost(refit, refit.with_new(base, w), measured, data), w))
            cm, wm = min(trials, key=lambda t: t[0])
            if cm < c:
                c, v, moved = cm, wm, True
        if not moved:
            break
    return c, v


def held_schedule(refit: Refit, max_iter: int) -> list[Step]:
    """The nominal parameters alone (the new ones held), then everything."""
    names = tuple(refit.problem.names[: refit.n_nominal])
    return [
        Step("nominal parameters, new ones held", names, max_iter=max_iter),
        Step("all", max_iter=max_iter),
    ]


def alternation(
    refit: Refit, start: np.ndarray, rounds: int = ROUNDS, max_iter: int = ROUND_ITER
) -> tuple[State, float, Any]:
    """The restart alternation (module docstring) from the new values ``start`` (SI): each
    round restarts the nominal parameters at ``refit``'s model; returns the best state, its
    objective and its search."""
    best: tuple[State, float, Any] | None = None
    v = np.asarray(start, float)
    for _ in range(max(1, rounds)):
        s, c, res = refit.solve(refit.with_new(refit.state0, v), held_schedule(refit, max_iter))
        if best is None or c < best[1]:
            best = (s, c, res)
        v = refit.new_values(s)
    assert best is not None
    return best


def modal_restarts(
    job: Job, aug0: Augmented, cand: Candidate, aug: Augmented, state: State, res: Any,
    measured: Sequence[Sequence[IdentifiedMode]] | None = None,
) -> tuple[Augmented, State, Any, str]:  # fmt: skip
    """The restart alternation from every start of :func:`modal_starts` (on ``job``'s data
    and hints) on ``aug0`` (the job's model augmented with its candidate ``cand``: the first
    origin); the start of lowest training objective is compared with the refit so far
    (``aug``, ``state``, ``res``) by :func:`.keep.replaces`; the starts after one that ends at
    the training noise level (:func:`.rescue.above_noise`) are not tried. Returns the kept
    refit and a note (starts tried of found, the best one's noise ratio, kept or not;
    failures)."""
    from .alternatives import _SKIPPED, _failure, _lower
    from .rescue import above_noise

    refit = aug0.refit
    starts = modal_starts(refit, cand, job.full, job.hints_hz, measured)
    if not starts:
        return aug, state, res, "no measured mode to match"
    best: tuple[State, float, Any] | None = None
    failed: list[str] = []
    tried = 0
    for v in starts:
        tried += 1
        try:
            s, c, r = alternation(refit, v)
        except _SKIPPED as err:
            failed.append(_failure("a start", err))
            continue
        if best is None or c < best[1]:
            best = (s, c, r)
            if not above_noise(refit, s):  # judged only when the best moved
                break
    note = f"{tried} of {len(starts)} start(s) from the measured modes"
    if failed:
        note += f", {len(failed)} failed (first: {failed[0]})"
    if best is None:
        return aug, state, res, note
    aug, state, res, kept = _lower(
        job, aug, state, res, aug0, best[0], best[2], "restart alternation"
    )
    return aug, state, res, f"{note}; {kept}"


def modal_step(
    job: Job, aug: Augmented, state: State, res: Any, others: bool = True
) -> tuple[Job, Augmented, State, Any, str]:
    """:func:`modal_restarts` for the job's candidate, then (``others``) for each other of its
    variants (:func:`.alternatives.variant_options`, e.g. the elastic centres of soft mounts)
    while the refit is still :func:`.alternatives.stuck`: the restart alternation reaches the
    noise level only from the right variant (bonder_b/sm/coh: the diagnosis of stop 21 had
    kept the centre below the CoM, where it ended at 6.75× the noise level; from the bottom
    face's centre, the truth's, the step reaches 0.76×). The measured modes are identified
    once. Returns
    the job with the candidate kept, the refit and a note per variant tried
    ("<variant>: <note>", "; "-joined)."""
    from .alternatives import stuck, variant_options
    from .job import with_option
    from .runner import _setup

    cand = job.candidate
    assert cand is not None
    measured = job_modes(job)
    order = [cand, *(o for o in variant_options(job) if o.spec != cand.spec and others)]
    notes = []
    for k, option in enumerate(order):
        if k and not stuck(job, aug, state, res):
            break
        sub = with_option(job, option)
        aug0 = _setup(job.urdf, sub)
        aug, state, res, note = modal_restarts(job, aug0, option, aug, state, res, measured)
        if aug is aug0:
            job = sub
        notes.append(f"{option.description}: {note}" if len(order) > 1 else note)
    return job, aug, state, res, "; ".join(notes)
