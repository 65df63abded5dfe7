"""Where a candidate's refit may start, each start with a cheap figure (:func:`candidate_starts`).

A candidate adds parameters the model has never had (a stiffness, a delay), and a local fit
from one guess of them lands wherever that guess leads. Where the answer may lie is known
from the physics and the data, so the starts come from there:

* **the scale scan** — the candidate's parameters scaled together over its range (a mode
  swept through the band, a delay from microseconds to milliseconds), the lowest local
  minima of the training cost kept (:data:`N_SCAN`);
* **the mode placed at a measured one** — for a candidate with a mode (springs, a sensor
  on its mount), the scale that puts its mode at each measured mode the model lacks, then
  at the measured modes it matches worst (:data:`N_PLACED`): a missing mode is where a
  missing spring shows;
* **the modes matched** — for a candidate with several springs (a flexible base, soft
  mounts), each spring set on its own so that the model's modes match the measured ones
  (:mod:`.matching`): their modes are seldom in the ratios the scan keeps;
* **the nominal origin** — the best of those with the nominal parameters back at the
  nominal model's values: the parameter refit that every candidate starts from may have
  bent nominal parameters to mimic what the candidate does, and from there the candidate
  first makes the fit worse; from the nominal values they can unbend.

Each scanned start's new parameters are first fitted alone for a few iterations (the
nominal ones held); a placed start stays placed and the nominal parameters relax around it
instead (:func:`relaxed`). Then every start gets its **figure**: the
training objective after one Levenberg–Marquardt step over every parameter on the
linearised residual (:func:`predicted_cost`), i.e. the score-test idea taken where the new
parameters are no longer "absent" (a compliance at infinite stiffness has no gradient),
plus the first-order gain of letting the nominal parameters follow. The figure ranks the
starts of a candidate and, through its best start, the candidates of a step; it is a
training figure, so nothing here looks at the held-out data that decide the verdict.

A refit runs each start with the **held schedule**: the nominal parameters alone with the
new ones held at the start, then everything. A missing spring's basin is narrow: from the
right spring and the bent nominal parameters, a joint solve goes elsewhere, while the
nominal parameters first relaxing around the held spring lead into it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import BondidError
from ..optim.search import Step
from .effects import Candidate
from .refit import Refit, State
from .scan_grid import hint_scales, scan_grid

#: local minima of the scale scan kept as starts
N_SCAN = 2
#: measured modes a candidate's springs are placed at (missing ones first)
N_PLACED = 3
#: IPOPT iterations of the new-only solve that settles each start
NEW_ITER = 10
#: Levenberg–Marquardt damping of the figure (relative to diag(JᵀJ))
LM_DAMPING = 1e-3
#: IPOPT iterations of a refit start's first step (the nominal parameters, new ones held)
HELD_ITER = 20
#: IPOPT iterations of a placed start's relaxation before its figure (:func:`relaxed`): enough
#: to undo the parameter refit's bend around the missing mode, which is what misleads the
#: figure; the figure needs no converged point, and every structural candidate's placed
#: starts pay for these iterations in the screening
RELAX_ITER = 10
#: two starts whose new parameters differ by less than this factor are one
SAME_START = 1.05

#: the numerical failures that lose one start, not the candidate
FAILURES = (BondidError, np.linalg.LinAlgError, ValueError, FloatingPointError)


@dataclass(frozen=True)
class StartSpec:
    """A start as a worker hands it on (plain values only).

    Attributes:
        label: where it comes from (``"scan ×0.31"``, ``"mode at 412 Hz"``, ``"… from the
            nominal model"``).
        x: the refit problem's named values ``(n,)`` (nominal parameters, then the new
            ones' leaders), SI.
        theta: the FRF modifier's parameters ``(n_θ,)`` (empty without one).
        figure: the predicted training objective (:func:`predicted_cost`).
        variant: which of the candidate's options (0: the candidate, k: its k-th variant).
        edge: a scan start at an end of the scan's grid, where the scan was cut off rather
            than at a minimum (:func:`_scales`): tried after every other start.
    """

    label: str
    x: np.ndarray
    theta: np.ndarray
    figure: float
    variant: int = 0
    edge: bool = False


@dataclass(frozen=True)
class Places:
    """What the starts are placed from: the frequencies [Hz] of the measured modes the
    model lacks (``missing``) and of the others the model matches worst, worst first
    (``worst``), the nominal model's values of the nominal parameters (``nominal``,
    ``(n_nominal,)``; None: no nominal origin), and the modes identified in each whole data
    set (``measured``, :class:`~bondid.modal.record.IdentifiedMode` per set; empty: none)."""

    missing: tuple[float, ...] = ()
    worst: tuple[float, ...] = ()
    nominal: np.ndarray | None = None
    measured: tuple[tuple[Any, ...], ...] = ()


def predicted_cost(refit: Refit, state: State, damping: float = LM_DAMPING) -> float:
    """Training objective after one Levenberg–Marquardt step over every variable from
    ``state`` on the linearised residual; never above the objective at ``state`` (inf where
    the model fails)."""
    try:
        p = refit.at(state)
        r, J = p.residual_and_jacobian(p.z0)
    except FAILURES:
        return math.inf
    if not np.all(np.isfinite(r)) or not np.all(np.isfinite(J)):
        return math.inf
    c0 = float(r @ r)
    JtJ = J.T @ J
    d = np.maximum(np.diag(JtJ), 1e-12 * max(float(np.max(np.diag(JtJ), initial=0.0)), 1e-300))
    try:
        step = -np.linalg.solve(JtJ + damping * np.diag(d), J.T @ r)
    except np.linalg.LinAlgError:
        return c0
    res = r + J @ step
    return min(c0, float(res @ res))


def held_schedule(refit: Refit, presolve: int = 0) -> list[Step]:
    """The schedule of a refit start: the nominal parameters alone with the new ones held
    (:data:`HELD_ITER` iterations), then everything (module docstring)."""
    nominal = tuple(refit.problem.names[: refit.n_nominal])
    first = [Step("nominal parameters, new ones held", nominal, max_iter=HELD_ITER)]
    if not refit.own or len(nominal) == len(refit.problem.names):
        first = []  # nothing is held (no candidate, or a modifier with nothing else new)
    return [*first, Step("all", presolve=presolve)]


def relaxed(refit: Refit, state: State) -> State:
    """``state`` after :data:`RELAX_ITER` iterations of the held schedule's first step (the
    nominal parameters relaxed around the candidate's new ones, those held).

    A placed start stays where it was placed: where the parameter refit has bent the model
    around the missing mode, a solve of the new parameters alone runs the spring out of the
    band. Its figure is taken once the model has relaxed around the placed spring: from the
    bent model one linearised step predicts little (the new resonance sits where the bent
    model puts the wrong residues and anti-resonances), so an unrelaxed placed start, often
    the only one in the right basin, would be ranked below starts that reach nothing and,
    through its candidate's figure, below candidates that explain nothing.
    """
    held = held_schedule(refit)[:-1]
    if not held or held[0].names is None:
        return state
    return refit.solve_only(state, held[0].names, RELAX_ITER)[0]


def _scales(refit: Refit, cand: Candidate, places: Places) -> list[tuple[str, float, bool, bool]]:
    """(label, scale of the ``scan = 1`` parameters, placed at a measured mode, at an edge)
    of the scan's minima and the placed modes, scan first.

    The lowest cost at an end of the grid is no minimum: the cost still falls there, and
    the grid spans the range where the candidate can show in the data. At the end where
    the effect vanishes (a spring too stiff for any mode in the band, a delay too short for
    any phase the data resolve) the start is the parameter refit itself, from which the new
    parameters have next to no gradient to follow; at the other, the effect is as strong
    as the candidate allows. Either way a minimum inside the range or a mode placed at a
    measured one says more about where the answer lies, so an edge start is marked and
    tried after those (:func:`rank`), whatever its figure.
    """
    out: list[tuple[str, float, bool, bool]] = []
    if not cand.scan_grid:
        return [("start values", 1.0, False, False)]
    exps = np.array([p.scan for p in cand.parameters], float)
    grid, _ = scan_grid(cand, places.missing)
    g = np.asarray(grid, float)
    states = refit.profile(refit.state0, exps, g)
    costs = refit.costs(refit.state0, states)
    left, right = np.r_[np.inf, costs[:-1]], np.r_[costs[1:], np.inf]
    minima = np.flatnonzero((costs <= left) & (costs <= right) & np.isfinite(costs))
    for i in sorted(minima, key=lambda i: costs[i]):
        if len(out) == N_SCAN:
            break
        if all(abs(math.log(g[i] / s)) >= math.log(1.5) for _, s, _, _ in out):
            edge = int(i) in (0, len(g) - 1)
            out.append((f"scan ×{g[i]:.3g}", float(g[i]), False, edge))
    if cand.ref_hz and any(p.scan > 0 for p in cand.parameters):
        lo, hi = min(cand.scan_grid), max(cand.scan_grid)
        placed = 0
        freqs = [*places.missing, *places.worst]
        for f, s in zip(freqs, hint_scales(cand, freqs), strict=True):
            if placed == N_PLACED or not lo <= s <= hi:
                continue
            placed += 1
            out.append((f"mode at {f:.4g} Hz", float(s), True, False))
    return out or [("start values", 1.0, False, False)]


def rank(s: StartSpec) -> tuple[bool, bool, float]:
    """The order starts are tried in: edge starts last (:func:`_scales`), then by figure (a
    start without a figure after those with one)."""
    return (s.edge, not math.isfinite(s.figure), s.figure)


def candidate_starts(
    refit: Refit, cand: Candidate, places: Places, variant: int = 0, full: Sequence[Any] = ()
) -> list[StartSpec]:
    """The starts of ``cand`` on ``refit`` (its model augmented with ``cand``), best figure
    first, the nominal origin of the best second (module docstring). A start whose model
    fails is left out; an empty list means every one failed."""
    exps = np.array([p.scan for p in cand.parameters], float)
    # starts are told apart by their positive parameters (a signed one, e.g. a pivot's
    # shift, may sit at 0 or change sign: no ratio to compare)
    positive = np.array([not p.signed for p in cand.parameters], bool)
    v0 = refit.new_values(refit.state0)
    out: list[StartSpec] = []
    seen: list[np.ndarray] = []
    for label, s, placed, edge in _scales(refit, cand, places):
        state = refit.with_new(refit.state0, v0 * s**exps)
        try:
            if not placed:
                state = refit.solve_new(state, NEW_ITER)[0]
            new = refit.new_values(state)[positive]
            if any(np.all(np.abs(np.log(np.maximum(new, 1e-300) / np.maximum(o, 1e-300)))
                          < math.log(SAME_START)) for o in seen):  # fmt: skip
                continue
            # a placed start's figure is taken where the nominal parameters have relaxed
            # around it (:func:`relaxed`); the refit starts from the placed point itself, as
            # its held schedule does that relaxation first
            figure = predicted_cost(refit, relaxed(refit, state) if placed else state)
        except FAILURES:
            continue
        seen.append(new)
        out.append(StartSpec(label, state.x.copy(), state.theta.copy(), figure, variant, edge))
    matched = _matched(refit, cand, places, full, variant)
    out += matched
    out = [s for s in out if math.isfinite(s.figure)]
    out.sort(key=rank)
    if places.nominal is not None and out:
        # second in line whatever its figure: one LM step from the nominal model, far from
        # the data, predicts nothing useful, and the start is there for the case where the
        # base's own basin is the wrong one
        best = out[0]
        x = best.x.copy()
        x[: refit.n_nominal] = places.nominal
        label = f"{best.label} from the nominal model"
        out.insert(1, StartSpec(label, x, best.theta.copy(), math.nan, variant, best.edge))
    return out


def _matched(
    refit: Refit, cand: Candidate, places: Places, full: Sequence[Any], variant: int
) -> list[StartSpec]:
    """The modes-matched start of a candidate with several springs (:mod:`.matching`), from
    the scale that puts its first mode at the first missing mode (else its start)."""
    from .matching import matched_start

    if not places.measured or len(places.measured) != len(full):
        return []
    scales = hint_scales(cand, places.missing[:1]) or [1.0]
    lo, hi = (min(cand.scan_grid), max(cand.scan_grid)) if cand.scan_grid else (1.0, 1.0)
    try:
        new = matched_start(refit, cand, float(np.clip(scales[0], lo, hi)), places.measured,
                            full)  # fmt: skip
    except FAILURES:
        return []
    if new is None:
        return []
    return [spec_of(refit, "modes matched", refit.with_new(refit.state0, new), variant)]


def spec_of(
    refit: Refit,
    label: str,
    state: State,
    variant: int,
    relax: bool = False,
    edge: bool = False,
) -> StartSpec:
    """The start of ``state`` with its figure; ``relax``: the figure taken once the nominal
    parameters have relaxed around it (:func:`relaxed`), the refit still starting at
    ``state``; ``edge``: see :class:`StartSpec`."""
    figure = predicted_cost(refit, relaxed(refit, state) if relax else state)
    return StartSpec(label, state.x.copy(), state.theta.copy(), figure, variant, edge)


def best_figure(starts: Sequence[StartSpec]) -> float:
    """The lowest finite figure of ``starts`` (inf when none)."""
    return min((s.figure for s in starts if math.isfinite(s.figure)), default=math.inf)
