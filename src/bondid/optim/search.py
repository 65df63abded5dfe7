"""Search strategies as schedules of :class:`Step` over one :class:`~.problem.FitProblem`,
driven by one loop, :func:`run_search`.

A step fits a subset of the names on a selection of the data (bands, residual kind), starting
where the previous steps left the parameters: it is a :meth:`FitProblem.restrict` of the problem
(no new linearisation) solved by :func:`~.ipopt.solve`. The last step of a schedule fits every
name and gives the search's result. The strategies (:mod:`.schedules`): direct, staged by
parameter kind, band continuation; the presolve is an option of a step (``presolve``) and the
multistart runs a search per start (:mod:`bondid.fit.multistart`).

A step that fails keeps its best feasible iterate; one that leaves nothing usable is recorded
as skipped and the next starts from the same point. The search never raises for a solver
outcome: a failed last step gives a result with status ``"failed"`` and the best point known.

Presolve (a log-cost step with ``presolve > 0``): the log error is infinite where the model has
a zero the data lack, so where a cross term's static gain must change sign on the way to the
optimum the log cost has a wall a local method cannot cross; the normalised complex error is
bounded and smooth there. The step runs the direct solve and, unless it succeeded with at most
:data:`WALL_SHARE` of the weight beyond 90° of phase error, a second solve from a start presolved
with ``presolve`` iterations on the normalised complex error, and keeps the lower final cost.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..exceptions import ConfigError
from .ipopt import Solution, solve
from .outcome import fit_result
from .problem import KEEP, FitProblem
from .result import FitResult

Band = tuple[float, float]
#: IPOPT iterations of the normalised-complex presolve of a log-cost fit (the default of
#: ``--presolve``). On the bundled data (all 50 parameters from the nominal model, default
#: bounds) the direct fit stops with Infeasible_Problem_Detected at cost 7.60 and the presolved
#: one converges to 7.430 (the truth's cost: 7.428); on noise-free data from a ±10–30 % start
#: the direct fit reaches the truth and the presolved one a local minimum: hence both.
PRESOLVE_ITER = 60
#: the presolved second solve runs only when the direct one did not succeed or left more than
#: this share of the (coherence) weight beyond 90° of phase error — the signature of a wall; a
#: fit that matches the phase nearly everywhere does not sit behind one (the second solve then
#: costs time for nothing: on tools/bench_fit.py it took the fit from ~16 s to 79 s)
WALL_SHARE = 0.01
#: residual kinds whose cost is a log error (these get the presolve)
LOG_KINDS = frozenset({"complex_log", "log_magnitude"})
#: residual of the presolve
PRESOLVE_KIND = "normalised_complex"
#: IPOPT's iteration limit of a search step by default
MAX_ITER = 200


@dataclass(frozen=True)
class Step:
    """One solve of a schedule.

    Attributes:
        name: shown in the results (``"stiffness"``, ``"up to 120 Hz"``, ``"all"``).
        names: the free subset (None = every name of the problem).
        bands: bands (Hz) to fit (None = all frequencies; default: the problem's).
        kind, norm: another residual kind / norm (None = the problem's).
        max_iter: IPOPT iteration limit (None = the search's).
        cap: a free parameter without a finite upper bound is capped at ``cap`` times its
            current value (a spring whose mode lies above the band would run off).
        keep_if_lower: keep the step's point only if it lowered the step's cost.
        presolve: see the module docstring (0 = none).
        skip: a reason to record the step as skipped without solving.
    """

    name: str
    names: tuple[str, ...] | None = None
    bands: Any = KEEP
    kind: str | None = None
    norm: str | None = None
    max_iter: int | None = None
    cap: float | None = None
    keep_if_lower: bool = False
    presolve: int = 0
    skip: str | None = None


@dataclass
class StepResult:
    """What one step did: its free names, bands, and costs (None fields when skipped)."""

    name: str
    bands: list[Band]
    names: list[str]
    status: str | None = None
    cost_initial: float | None = None
    cost_final: float | None = None
    iterations: int = 0
    wall_s: float = 0.0
    skipped: str | None = None

    def to_json_dict(self) -> dict:
        return {
            "name": self.name, "bands_hz": [list(b) for b in self.bands],
            "parameters": list(self.names), "skipped": self.skipped, "status": self.status,
            "cost_initial": self.cost_initial, "cost_final": self.cost_final,
            "iterations": None if self.skipped else int(self.iterations),
            "wall_s": None if self.skipped else float(self.wall_s),
        }  # fmt: skip


@dataclass
class SearchResult:
    """The outcome of a search: the final fit (``result``: ``initial``, ``cost_initial``,
    ``iterations`` and ``wall_s`` cover the whole search) and every step."""

    result: FitResult
    steps: list[StepResult] = field(default_factory=list)
    #: the last step's kept solve (its ``kept`` says whether a failed one reached a point)
    solution: Solution | None = None

    @property
    def stages(self) -> list[StepResult]:
        """The steps worth reporting: none for a one-step (direct) search."""
        return self.steps if len(self.steps) > 1 else []


@dataclass
class _Run:
    """Solve settings shared by the steps of one search."""

    max_iter: int
    solve_kw: dict[str, Any]
    on_step: Callable[[StepResult], None] | None


@dataclass
class _State:
    """Where the search is: the named values ``x`` ``(n,)`` and the modifier's θ."""

    x: np.ndarray
    theta: np.ndarray


@dataclass
class _Solved:
    """A step's kept solve: the problem its ``z`` belongs to, notes, presolve iterations."""

    problem: FitProblem
    solution: Solution
    notes: list[str] = field(default_factory=list)
    extra_iterations: int = 0

    @property
    def iterations(self) -> int:
        return self.solution.iterations + self.extra_iterations


def run_search(
    problem: FitProblem,
    steps: Sequence[Step],
    *,
    max_iter: int = MAX_ITER,
    tol: float = 1e-10,
    progress: Callable[[int, float], None] | None = None,
    on_step: Callable[[StepResult], None] | None = None,
    ipopt_options: dict[str, Any] | None = None,
    constraint_hessian: str = "convexified",
) -> SearchResult:
    """Run ``steps`` in order over ``problem`` from its start (see the module docstring).

    Args:
        problem: the fit problem (bounds, start, cost options).
        steps: the schedule; the last step must fit every name.
        max_iter, tol: IPOPT's limits (``max_iter`` for steps without their own).
        progress: ``progress(iteration, cost)`` at every IPOPT iteration of every step.
        on_step: called after each step.
        ipopt_options, constraint_hessian: see :func:`bondid.optim.ipopt.solve`.

    Returns:
        :class:`SearchResult`; its ``result.status`` is ``"failed"`` when the last step failed.
    """
    if not steps or steps[-1].names not in (None, tuple(problem.names)):
        raise ConfigError("a search schedule must end with a step over every free parameter")
    t0 = time.perf_counter()
    kw = {"tol": tol, "progress": progress, "ipopt_options": ipopt_options,
          "constraint_hessian": constraint_hessian}  # fmt: skip
    run = _Run(max_iter, kw, on_step)
    x = problem.initial.copy()
    state = _State(x, problem.theta(problem.z0))
    records: list[StepResult] = []
    iterations = 0
    final: _Solved | None = None
    for k, step in enumerate(steps):
        last = k == len(steps) - 1
        done = _step(problem, step, state, run, records, last)
        if done is not None:
            iterations += done.iterations
            idx = [problem.names.index(n) for n in done.problem.names]
            x[idx] = done.problem.values(done.solution.z)
            state.theta = done.problem.theta(done.solution.z)
            final = done if last else None
    if final is None:  # the last step was skipped: nothing solved over every name
        final = _Solved(problem, _unsolved(problem, records[-1].skipped or "skipped"))
    sub = final.problem
    notes = list(problem.notes) + [n for n in sub.notes if n not in problem.notes]
    result = fit_result(
        sub, final.solution, initial=problem.initial, cost_initial=problem.data_cost(problem.z0),
        iterations=iterations, wall_s=time.perf_counter() - t0, notes=notes + final.notes,
    )  # fmt: skip
    return SearchResult(result, records, final.solution)


def _unsolved(problem: FitProblem, why: str) -> Solution:
    return Solution(
        z=problem.z0.copy(), cost=problem.cost(problem.z0), status="not_run", success=False,
        iterations=0, failure=why, kept="start",
    )  # fmt: skip


def _step(
    problem: FitProblem,
    step: Step,
    state: _State,
    run: _Run,
    records: list[StepResult],
    last: bool,
) -> _Solved | None:
    """Run one step from ``x``; ``None`` when it was skipped (recorded in ``records``)."""
    names = list(problem.names if step.names is None else step.names)
    record = StepResult(step.name, _bands_of(problem, step), names)
    records.append(record)
    sub: FitProblem | None = None
    if step.skip is not None:
        record.skipped = step.skip
    else:
        try:
            sub = _restricted(problem, step, state, names)
        except ConfigError as exc:
            if "no data" not in str(exc) or last:
                raise
            record.skipped = f"no data: {exc}"
    if sub is None:
        _report(run, record)
        return None
    t0 = time.perf_counter()
    max_iter = run.max_iter if step.max_iter is None else step.max_iter
    cost0 = sub.cost(sub.z0)
    done = _solve_step(sub, step, max_iter, run.solve_kw)
    sol = done.solution
    record.status = "failed" if sol.failed else sol.status
    record.cost_initial, record.cost_final = cost0, sol.cost
    record.iterations = done.iterations
    record.wall_s = time.perf_counter() - t0
    reason = None if last else _rejected(step, sol, cost0)
    if reason is not None:
        record.skipped = reason
        record.status = record.cost_initial = record.cost_final = None
    _report(run, record)
    return None if reason is not None else done


def _report(run: _Run, record: StepResult) -> None:
    if run.on_step is not None:
        run.on_step(record)


def _rejected(step: Step, sol: Solution, cost0: float) -> str | None:
    """Why a (not last) step's point is not kept, or None."""
    if sol.failed and sol.kept == "start":
        return f"solver failed ({sol.status}); kept its start: {sol.failure}"
    if step.keep_if_lower and not sol.cost <= cost0:
        return (
            f"ended at a higher cost ({sol.status}, {cost0:.4g} → {sol.cost:.4g}); kept its start"
        )
    return None


def _bands_of(problem: FitProblem, step: Step) -> list[Band]:
    bands = problem.options.bands if step.bands is KEEP else step.bands
    if bands:
        return [(float(a), float(b)) for a, b in bands]
    return [problem.data_span_hz]


def _restricted(problem: FitProblem, step: Step, state: _State, names: list[str]) -> FitProblem:
    """The step's problem at the current point (the whole problem itself when nothing
    changes)."""
    x = state.x
    same = (
        names == problem.names and step.bands is KEEP and step.kind is None
        and step.norm is None and step.cap is None and np.array_equal(x, problem.initial)
        and np.array_equal(state.theta, problem.theta(problem.z0))
    )  # fmt: skip
    if same:
        return problem
    idx = [problem.names.index(n) for n in names]
    upper = None
    if step.cap is not None:
        hi, xs = problem.upper[idx], x[idx]
        upper = np.where(np.isfinite(hi) | (xs <= 0.0), hi, step.cap * xs)
    theta = state.theta if state.theta.size else None
    return problem.restrict(
        names, start=x, bands=step.bands, kind=step.kind, norm=step.norm, upper=upper,
        theta=theta,
    )  # fmt: skip


def _solve_step(sub: FitProblem, step: Step, max_iter: int, kw: dict[str, Any]) -> _Solved:
    """The step's solve, with the presolve when asked (see the module docstring)."""
    direct = solve(sub, max_iter=max_iter, **kw)
    if step.presolve <= 0 or sub.options.kind not in LOG_KINDS:
        return _Solved(sub, direct)
    walls = sub.phase_wall_fraction(direct.z) if direct.success else 1.0
    if walls <= WALL_SHARE:
        note = (
            f"presolve skipped: the direct fit succeeded with {walls:.1%} of the weight beyond"
            f" 90° of phase error (the presolve runs above {WALL_SHARE:.0%})"
        )
        return _Solved(sub, direct, [note])
    return _presolved(_Solved(sub, direct), step.presolve, max_iter, kw)


def _presolved(direct: _Solved, presolve: int, max_iter: int, kw: dict[str, Any]) -> _Solved:
    """Solve again from a start presolved on the normalised complex error; keep the better."""
    sub, first = direct.problem, direct.solution
    pre_problem = sub.restrict(kind=PRESOLVE_KIND, norm="l2")
    pre = solve(pre_problem, max_iter=presolve, **kw)
    if pre.failed and pre.kept == "start":
        direct.notes.append(f"the presolved fit failed ({pre.status}); kept the direct one")
        return direct
    theta = pre_problem.theta(pre.z)
    again = sub.restrict(start=pre_problem.values(pre.z), theta=theta if theta.size else None)
    second = solve(again, max_iter=max_iter, **kw)
    if second.failed:
        direct.notes.append(f"the presolved fit failed ({second.status}); kept the direct one")
        return direct
    keep_second = first.failed or second.cost < first.cost
    if first.failed:
        direct.notes.append(f"IPOPT failed ({first.status}) on the direct fit")
    direct.notes.append(
        f"two fits: direct and after {pre.iterations} presolve iterations on the normalised "
        f"complex error; final costs {first.cost:.6g}, {second.cost:.6g}; kept the "
        f"{'presolved' if keep_second else 'direct'} one"
    )
    if not keep_second:
        return direct
    return _Solved(again, second, direct.notes, pre.iterations)
