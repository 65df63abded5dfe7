"""The one way out of a bad basin: run searches from several starts, keep the best, stop as
soon as one is at the noise level (:func:`keep_best`).

A local fit of a lightly damped structure's FRF can end in another basin of the log cost:
a mode paired with the wrong measured one, a stiffness run to its bound, nominal parameters
bent to mimic something the model lacks. Nothing local gets it out; another start does. The
starts come from whoever knows where the answer may lie (:class:`Start`, ranked by the
caller): the model's own values, the same values under another schedule (the band
continuation, the staged schedule of :mod:`.schedules`), random points in the box the
prior trusts (:func:`random_starts`), and in a diagnosis a candidate's scans, its mode
placed at a measured one, its variants and the nominal origin.

The loop is the same for every client and has three ways to stop, each a property of the
problem rather than a count tuned on examples:

1. **at the noise level** — the kept search's data cost is within :data:`.noise.AT_LEVEL`
   of what an exact model would score (:class:`.noise.NoisePolicy`): no start can do
   better by a margin the data could show;
2. **a restart cannot improve** — :data:`PATIENCE` starts in a row removed less than
   :data:`MATERIAL` of the kept search's excess over the noise level (a lower one is still
   kept): the starts ranked next are not expected to do better than those already tried,
   and the kept basin is what the model reaches;
3. **the budget is spent** — one budget of IPOPT iterations (and optionally seconds) for
   the whole loop (:class:`Budget`); a start gets at most what is left.

A search stopped at its iteration limit while it is the best so far is continued from its
end point (once, within the budget) before another start is tried: more iterations, not
another basin, is what it lacks.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..exceptions import BondidError
from .noise import NoisePolicy

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .problem import FitProblem
    from .search import SearchResult, Step

#: starts in a row that end no lower than the kept search before the loop stops
PATIENCE = 2
#: a search replaces the kept one when its objective is lower by more than this fraction
IMPROVEMENT = 1e-3
#: ... and counts as an improvement (the patience starts again) only when it also removes at
#: least this share of the kept search's excess over the noise level: a restart that lowers
#: a fit far above the level by a fraction of a per cent found the same basin again, not a
#: better one, and the next starts are no more likely to
MATERIAL = 0.01
#: IPOPT's status of a solve stopped at its iteration limit (continued once, see the module)
ITERATION_LIMIT = "Maximum_Iterations_Exceeded"
#: a resumed search may run this many times the per-step iteration limit (within the budget)
RESUME_FACTOR = 3

#: a schedule, given or built for the problem at the start point when the start runs
Schedule = Sequence["Step"] | Callable[["FitProblem"], Sequence["Step"]]


@dataclass(frozen=True)
class Start:
    """One way into the search.

    Attributes:
        label: what the start is (``"model values"``, ``"band continuation"``,
            ``"random 2"``, ``"mode placed at 412 Hz"``).
        x: the named values ``(n,)`` to start from (SI, the problem's names); None: the
            problem's own start.
        theta: the FRF modifier's parameters ``(n_θ,)``; None: the problem's.
        steps: the schedule run from it (a list of steps, or a function of the problem at
            the start that builds one); None: the loop's default schedule.
        figure: a cheap prediction of the objective this start leads to (for the caller's
            ranking and the report; NaN when none).
        payload: what else the runner needs to run it (e.g. which variant of a diagnosis
            candidate); None for a plain start.
    """

    label: str
    x: np.ndarray | None = None
    theta: np.ndarray | None = None
    steps: Schedule | None = None
    figure: float = math.nan
    payload: Any = None


@dataclass
class Budget:
    """IPOPT iterations (and wall seconds) one loop may spend over all its searches."""

    iterations: int
    seconds: float = math.inf
    spent: int = 0
    t0: float = field(default_factory=time.perf_counter)

    @property
    def remaining(self) -> int:
        return max(0, self.iterations - self.spent)

    @property
    def exhausted(self) -> bool:
        return self.remaining <= 0 or time.perf_counter() - self.t0 >= self.seconds

    def spend(self, n: int) -> None:
        self.spent += max(0, int(n))


@dataclass
class Attempt:
    """One search of the loop: its start, result and figures.

    Attributes:
        start: the start it ran from.
        search: the search (None when it failed before any point).
        objective: the objective (data and prior) at its end point; inf when it failed.
        data_cost: the data cost there (the noise test's figure); inf when it failed.
        iterations: IPOPT iterations it used.
        wall_s: its time [s].
        error: why it failed ("" when it did not).
        resumed: it continues an earlier attempt stopped at its iteration limit.
        x_end, theta_end: its end point (named values and modifier θ; None when it failed).
        detail: what else the runner kept of it (e.g. a diagnosis refit's model).
        solver_status: the solver's own status of a failed search (None otherwise).
    """

    start: Start
    search: SearchResult | None
    objective: float
    data_cost: float
    iterations: int
    wall_s: float
    error: str = ""
    resumed: bool = False
    x_end: np.ndarray | None = None
    theta_end: np.ndarray | None = None
    detail: Any = None
    solver_status: str | None = None

    @property
    def status(self) -> str:
        if self.search is None:
            return "failed"
        return str(self.search.result.status)


@dataclass
class Outcome:
    """What :func:`keep_best` found: the kept attempt, every attempt in order, why it stopped.

    ``stopped`` is one of ``"at the noise level"``, ``"a restart could not improve"``,
    ``"budget spent"``, ``"no start left"``.
    """

    best: Attempt
    attempts: list[Attempt]
    stopped: str
    noise: NoisePolicy

    @property
    def result(self) -> SearchResult:
        assert self.best.search is not None
        return self.best.search

    @property
    def iterations(self) -> int:
        return sum(a.iterations for a in self.attempts)

    @property
    def at_level(self) -> bool:
        return self.noise.at_level(self.best.data_cost)

    def note(self) -> str:
        """One line for a fit's notes: what ran, what was kept and why the loop stopped
        (empty when one start sufficed)."""
        if len(self.attempts) <= 1:
            return ""
        parts = []
        for a in self.attempts:
            fig = self.noise.describe(a.data_cost) if not a.error else f"failed ({a.error})"
            parts.append(f"{a.start.label}{' (resumed)' if a.resumed else ''}: {fig}")
        return f"starts: {'; '.join(parts)}; kept {self.best.start.label}; stopped: {self.stopped}"


def theta_of(problem: FitProblem, search: SearchResult) -> np.ndarray | None:
    """The FRF modifier's parameters ``(n_θ,)`` at the search's end point (None without a
    modifier)."""
    mod = problem.frf.modifier
    if mod is None:
        return None
    return np.array([search.result.modifiers[n] for n in mod.names], float)


def _objective(problem: FitProblem, search: SearchResult) -> tuple[float, float]:
    """(objective, data cost) of ``problem`` at the search's end point."""
    at = problem.restrict(start=search.result.fitted, theta=theta_of(problem, search))
    obj, data = at.cost(at.z0), at.data_cost(at.z0)
    return (obj if math.isfinite(obj) else math.inf, data if math.isfinite(data) else math.inf)


def run_start(
    problem: FitProblem, start: Start, default: Schedule, max_iter: int, **search_kw: Any
) -> Attempt:
    """One search of the loop: ``start``'s schedule (or ``default``) from its point with at
    most ``max_iter`` IPOPT iterations per step; a numerical failure becomes a failed
    :class:`Attempt` (bad input still raises)."""
    from ..exceptions import ComputationError, SolverError
    from .search import run_search

    t0 = time.perf_counter()
    try:
        at = problem
        if start.x is not None or start.theta is not None:
            at = problem.restrict(start=start.x, theta=start.theta)
        steps = start.steps if start.steps is not None else default
        schedule = list(steps(at) if callable(steps) else steps)
        search = run_search(at, schedule, max_iter=max_iter, **search_kw)
        if (
            search.result.status == "failed"
            and search.solution is not None
            and (search.solution.kept == "start")
        ):
            st = search.solution.status
            raise SolverError(f"the solver failed ({st})", status=st)
        obj, data = _objective(problem, search)
        return Attempt(
            start, search, obj, data, search.result.iterations, time.perf_counter() - t0,
            x_end=search.result.fitted.copy(), theta_end=theta_of(problem, search),
        )  # fmt: skip
    except (ComputationError, np.linalg.LinAlgError, FloatingPointError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return Attempt(start, None, math.inf, math.inf, 0, time.perf_counter() - t0, msg,
                       solver_status=getattr(exc, "status", None))  # fmt: skip


def _better(new: Attempt, kept: Attempt | None) -> bool:
    if kept is None or kept.search is None:
        return new.search is not None or kept is None
    return new.objective < kept.objective * (1.0 - IMPROVEMENT)


def _material(new: Attempt, kept: Attempt | None, noise: NoisePolicy) -> bool:
    """Does ``new`` (better than ``kept``) remove :data:`MATERIAL` of ``kept``'s data cost
    over the noise level's? (True when there is no kept search or the level is unknown.)"""
    if kept is None or kept.search is None or not noise.known:
        return True
    assert noise.cost is not None
    excess = kept.data_cost - noise.cost
    return not excess > 0 or kept.data_cost - new.data_cost >= MATERIAL * excess


#: runs one start with at most the given IPOPT iterations per step
Runner = Callable[[Start, int], Attempt]


def search_runner(problem: FitProblem, default: Schedule, **search_kw: Any) -> Runner:
    """The runner of plain starts on ``problem`` (:func:`run_start`; ``default``: the
    schedule of a start that names none; ``search_kw`` for
    :func:`bondid.optim.search.run_search`)."""
    return lambda start, max_iter: run_start(problem, start, default, max_iter, **search_kw)


def keep_best(
    starts: Iterable[Start],
    run: Runner,
    *,
    noise: NoisePolicy,
    budget: Budget,
    max_iter: int,
    patience: int = PATIENCE,
    on_attempt: Callable[[Attempt], None] | None = None,
    stop: Callable[[], bool] | None = None,
) -> Outcome:
    """Run ``starts`` in order and keep the best (module docstring).

    Args:
        starts: ranked, best first; consumed lazily (a start that is never reached is never
            built).
        run: runs one start (:func:`search_runner` for a plain fit problem).
        noise: the data's noise level (the first way to stop).
        budget: IPOPT iterations (and seconds) for the whole loop.
        max_iter: IPOPT's iteration limit per step (capped by what the budget has left).
        patience: starts in a row without improvement before the loop stops.
        on_attempt: called after each attempt (progress).
        stop: asked before each start; True ends the loop (``stopped = "cancelled"``): the
            caller no longer needs the answer.

    Returns:
        :class:`Outcome`.

    Raises:
        SolverError: every start failed (the first failure's message).
    """
    from ..exceptions import SolverError
    from .search import Step

    attempts: list[Attempt] = []
    best: Attempt | None = None
    misses = 0
    stopped = "no start left"
    it = iter(starts)
    queued: list[Start] = []
    while True:
        if stop is not None and stop():
            stopped = "cancelled"
            break
        if best is not None and noise.at_level(best.data_cost):
            stopped = "at the noise level"
            break
        if best is not None and misses >= patience:
            stopped = "a restart could not improve"
            break
        if budget.exhausted:
            stopped = "budget spent"
            break
        resumed = bool(queued)
        start = queued.pop(0) if queued else next(it, None)
        if start is None:
            break
        # a resumed search gets what it lacks, more iterations (up to the budget's rest)
        limit = RESUME_FACTOR * max_iter if resumed else max_iter
        a = run(start, max(1, min(limit, budget.remaining)))
        a.resumed = resumed
        budget.spend(a.iterations)
        attempts.append(a)
        if on_attempt is not None:
            on_attempt(a)
        if _better(a, best):
            material = _material(a, best, noise)
            best = a
            misses = 0 if material or resumed else misses + 1
            if a.status == ITERATION_LIMIT and not resumed and a.x_end is not None:
                # still descending where it stopped: continue it before trying elsewhere
                queued.append(Start(f"{start.label}, resumed", a.x_end, a.theta_end,
                                    [Step("all, resumed")], payload=start.payload))  # fmt: skip
        elif not resumed:
            misses += 1
    if best is None or best.search is None:
        if stopped == "cancelled":
            raise SolverError("cancelled before any start ended")
        failed = next((a for a in attempts if a.error), None)
        first = failed.error if failed is not None else "no start"
        status = failed.solver_status if failed is not None else None
        raise SolverError(f"every start of the fit failed: {first}", status=status)
    return Outcome(best, attempts, stopped, noise)


def random_starts(
    problem: FitProblem, n: int, *, width: float, seed: int = 0, label: str = "random"
) -> list[Start]:
    """``n`` starts drawn around the problem's start in the box its prior trusts: each
    positive parameter times ``exp(N(0, width))``, each signed one (a CoM coordinate, a
    product of inertia) plus ``N(0, width)`` times the half-width of its bounds over 2 (so a
    draw stays well inside them); clipped to the bounds. ``width`` is the prior's relative
    width: starts no farther than the model's values are trusted, so they do not end in
    basins no one would believe. Inertial parameters are then projected into the
    physically consistent set when the start runs (:class:`FitProblem`'s start rule)."""
    if n <= 0:
        return []
    if not width > 0:
        raise BondidError(f"random starts need a positive width, got {width}")
    rng = np.random.default_rng(seed)
    x0 = np.asarray(problem.initial, float)
    lo, hi = np.asarray(problem.lower, float), np.asarray(problem.upper, float)
    out = []
    for k in range(n):
        g = rng.standard_normal(x0.size)
        positive = (x0 > 0) & (lo >= 0)
        half = np.where(np.isfinite(hi - lo), 0.5 * (hi - lo), np.abs(x0))
        x = np.where(positive, x0 * np.exp(width * g), x0 + 0.5 * width * g * half)
        x = np.clip(x, lo, hi)
        out.append(Start(f"{label} {k + 1}", x))
    return out
