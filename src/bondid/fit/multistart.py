"""Multistart: several fits from Latin-hypercube starts within the bounds, in parallel.

Start 0 is always the model's own (URDF) values; starts 1..N-1 fill the box
``[lower, upper]`` with a seeded Latin hypercube (:class:`scipy.stats.qmc.LatinHypercube`),
so the same seed gives the same starts. A parameter whose box spans more than a decade with
``lower > 0`` (typically an absolute stiffness or damping range) is sampled uniformly in its
logarithm. Each start runs one search (:mod:`bondid.optim.search`, the schedule chosen by a
:class:`~bondid.optim.schedules.Strategy`). The runs go to separate processes
(:class:`concurrent.futures.ProcessPoolExecutor`, 2 workers by default, one per core of the
reference machine), each building its problem once; starts run in this process share one
problem (:meth:`FitProblem.restrict`, no new linearisation). The best final cost of a run
that did not fail wins and the spread of the final costs is reported.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..exceptions import ComputationError, ConfigError, SolverError
from ..model.document import UrdfDocument
from ..model.parameters import get_parameters
from ..optim.schedules import Strategy

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..optim.problem import FitProblem
    from ..optim.result import FitResult

#: Called as each run finishes: (runs done, runs total, the finished run).
RunProgress = Callable[[int, int, "RunOutcome"], None]


def lhs_starts(
    x0: np.ndarray, lower: np.ndarray, upper: np.ndarray, n: int, seed: int = 0
) -> np.ndarray:
    """Start points for a multistart.

    Args:
        x0: the model's values, shape ``(p,)`` (becomes start 0).
        lower, upper: the box, shape ``(p,)`` each, ``lower <= upper``.
        n: number of starts (>= 1).
        seed: seed of the Latin hypercube.

    Returns:
        ``(n, p)``: row 0 is ``x0``, rows 1.. a Latin hypercube within ``[lower, upper]``
        (log-uniform for boxes with ``lower > 0`` spanning more than a factor 10).

    Raises:
        ConfigError: ``n < 1``.

    A parameter with an infinite bound keeps its value ``x0`` in every start.
    """
    from scipy.stats import qmc

    x0 = np.asarray(x0, dtype=float)
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    if n < 1:
        raise ConfigError(f"multistart: {n} starts; give at least 1")
    out = np.empty((n, x0.size))
    out[0] = x0
    if n == 1 or x0.size == 0:
        out[1:] = x0
        return out
    u = qmc.LatinHypercube(d=x0.size, seed=seed).random(n - 1)  # (n-1, p) in [0, 1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        logscale = (lo > 0) & np.isfinite(hi) & (hi / np.where(lo > 0, lo, 1.0) > 10.0)
        lin = lo + u * (hi - lo)
        ratio = np.where(logscale, hi / np.where(logscale, lo, 1.0), 1.0)
        lg = np.where(logscale, lo, 1.0) * np.exp(u * np.log(ratio))
    sample = np.clip(np.where(logscale, lg, lin), lo, hi)
    finite = np.isfinite(lo) & np.isfinite(hi)
    out[1:] = np.where(finite, sample, x0)
    return out


@dataclass
class RunOutcome:
    """One multistart run: its start, and its result or the reason it failed."""

    index: int
    start: np.ndarray
    result: FitResult | None
    error: str | None = None
    status: str | None = None
    stages: list[Any] = field(default_factory=list)  # StepResult per step (staged, continuation)
    wall_s: float = 0.0

    @property
    def cost(self) -> float:
        return math.inf if self.result is None else float(self.result.cost_final)


@dataclass
class MultistartResult:
    """All runs of a multistart and the best one."""

    runs: list[RunOutcome]
    best_index: int
    wall_s: float

    @property
    def best(self) -> FitResult:
        res = self.runs[self.best_index].result
        assert res is not None
        return res

    @property
    def best_run(self) -> RunOutcome:
        return self.runs[self.best_index]

    def spread(self) -> dict[str, Any]:
        """Spread of the final costs: ``{n_runs, n_failed, min, median, max, costs, best_start,
        statuses, errors}`` (``costs[i]`` is None for a failed run)."""
        finite = [r.cost for r in self.runs if r.result is not None]
        return {
            "n_runs": len(self.runs),
            "n_failed": sum(r.result is None for r in self.runs),
            "min": min(finite) if finite else None,
            "median": float(np.median(finite)) if finite else None,
            "max": max(finite) if finite else None,
            "costs": [None if r.result is None else r.cost for r in self.runs],
            "best_start": self.best_index,
            "statuses": [r.result.status if r.result is not None else r.status for r in self.runs],
            "errors": [r.error for r in self.runs],
            "wall_s": self.wall_s,
        }


@dataclass
class _Job:
    """One start: the problem's inputs, the start ``(p,)`` and the strategy."""

    index: int
    problem_args: tuple[UrdfDocument, list[FrfData], list[str], CostOptions, np.ndarray, np.ndarray]
    start: np.ndarray
    strategy: Strategy
    #: random starts the job's loop may try after its own schedules (the fit's last tier)
    n_random: int = 0


def _problem(job: _Job, base: FitProblem | None = None) -> FitProblem:
    """The job's problem: ``base`` (the problem built for job 0, so used as is by job 0)
    restarted at the job's start, or built from the job's inputs."""
    if base is not None:
        return base if job.index == 0 else base.restrict(start=job.start)
    from ..optim.problem import FitProblem

    doc, datasets, names, options, lo, hi = job.problem_args
    return FitProblem(
        doc, datasets, names, options=options, lower=lo, upper=hi, start=job.start,
        extra_rows=job.strategy.extra_rows(doc),
    )  # fmt: skip


def _run_job(
    job: _Job,
    progress: Callable[[int, float], None] | None = None,
    base: FitProblem | None = None,
) -> RunOutcome:
    """Run one start (in a worker process or in-process).

    A failed computation (singular matrix, a solver that raised) becomes a failed run; bad
    input (:class:`ConfigError`, :class:`ParameterError`, ...) propagates.
    """
    from .solver import search_to_noise

    t0 = time.perf_counter()
    try:
        problem = _problem(job, base)
        st = search_to_noise(
            problem, job.strategy, n_random=job.n_random, seed=job.index,
            start_label=f"start {job.index}", progress=progress,
            ipopt_options=job.strategy.ipopt_options(),
        )  # fmt: skip
        return RunOutcome(
            job.index, job.start, st.result, stages=st.stages, wall_s=time.perf_counter() - t0
        )
    except ComputationError as exc:
        return RunOutcome(
            job.index, job.start, None, str(exc), getattr(exc, "status", None),
            wall_s=time.perf_counter() - t0,
        )  # fmt: skip
    except (np.linalg.LinAlgError, FloatingPointError) as exc:
        return RunOutcome(job.index, job.start, None, str(exc), wall_s=time.perf_counter() - t0)


def _in_process(jobs: list[_Job], on_run: RunProgress | None, on_iteration: Any) -> list:
    """Run the jobs here, one after another, on one problem built once (for job 0, which
    runs on it; the others restart it)."""
    runs = []
    base = _problem(jobs[0]) if len(jobs) > 1 else None
    for k, job in enumerate(jobs):
        runs.append(_run_job(job, on_iteration, base))
        if on_run is not None:
            on_run(k + 1, len(jobs), runs[-1])
    return runs


def _in_pool(jobs: list[_Job], workers: int, on_run: RunProgress | None) -> list:
    """Run the jobs in worker processes (each builds its problem); their outcomes in the
    order of ``jobs``."""
    from ..interrupt import ignore_in_worker, signals_deferred, terminate_on_interrupt

    runs: list[RunOutcome | None] = [None] * len(jobs)
    pool = ProcessPoolExecutor(max_workers=min(workers, len(jobs)), initializer=ignore_in_worker)
    with terminate_on_interrupt(pool):
        with signals_deferred():  # the workers start here: all recorded before a Ctrl-C lands
            futures: dict[Future[RunOutcome], int] = {
                pool.submit(_run_job, j): k for k, j in enumerate(jobs)
            }
        for k, fut in enumerate(as_completed(futures)):
            out = fut.result()
            runs[futures[fut]] = out
            if on_run is not None:
                on_run(k + 1, len(jobs), out)
    return runs


def run_multistart(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    names: Sequence[str],
    *,
    lower: np.ndarray,
    upper: np.ndarray,
    options: CostOptions | None = None,
    n_starts: int = 1,
    seed: int = 0,
    workers: int = 2,
    strategy: Strategy | None = None,
    on_run: RunProgress | None = None,
    on_iteration: Callable[[int, float], None] | None = None,
    fallback_starts: int = 0,
) -> MultistartResult:
    """Search from ``n_starts`` starts (start 0 = the URDF values) and keep the best.

    Args:
        doc: the model (not modified).
        datasets: measured FRFs (one linearisation per operating point).
        names: free parameters, length ``p``.
        lower, upper: bounds, shape ``(p,)`` each (SI units of each parameter).
        options: cost options (default :class:`CostOptions`).
        n_starts: number of starts; 1 runs the single search in this process.
        seed: Latin-hypercube seed.
        workers: processes to use (1 = run the starts one after another here).
        strategy: the schedule of each search and its iteration limits (default: direct).
        on_run: called in this process as each run finishes.
        on_iteration: per-iteration progress ``(iteration, cost)``, only for runs done in
            this process (``workers == 1`` or a single start).
        fallback_starts: the fit's last tier, for a single start (``n_starts == 1``):
            ``fallback_starts - 1`` random starts the fit's loop may try after its
            schedules (:func:`.solver.search_to_noise`: only while it is above the noise
            level and a restart still improves); 0 or 1 = none.

    Returns:
        :class:`MultistartResult`; ``.best`` is the best :class:`FitResult` (a run whose
        solver failed counts only when every run failed).

    Raises:
        SolverError: every run failed without a result (keeps the status of start 0's failure).
        ConfigError: bad start count.
    """
    t0 = time.perf_counter()
    args = (doc, list(datasets), list(names), options or CostOptions(),
            np.asarray(lower, dtype=float), np.asarray(upper, dtype=float))  # fmt: skip
    jobs = _jobs(args, n_starts, seed, strategy)
    if n_starts == 1 and fallback_starts >= 2:
        jobs[0] = replace(jobs[0], n_random=fallback_starts - 1)
    done = _run(jobs, workers, on_run, on_iteration)
    return MultistartResult(done, _best_index(done), time.perf_counter() - t0)


def _jobs(args: tuple, n_starts: int, seed: int, strategy: Strategy | None) -> list[_Job]:
    """The jobs of :func:`run_multistart`, one per start (:func:`lhs_starts`); ``args``:
    :attr:`_Job.problem_args`."""
    doc, _, names, _, lo, hi = args
    starts = lhs_starts(np.clip(get_parameters(doc, names), lo, hi), lo, hi, n_starts, seed)
    return [_Job(i, args, starts[i], strategy or Strategy()) for i in range(n_starts)]


def _run(
    jobs: list[_Job], workers: int, on_run: RunProgress | None, on_iteration: Any = None
) -> list[RunOutcome]:
    """The jobs' outcomes, in their order: here for one job or one worker, else in a pool."""
    if len(jobs) == 1 or workers <= 1:
        return _in_process(jobs, on_run, on_iteration)
    return _in_pool(jobs, workers, on_run)


def _best_index(done: list[RunOutcome]) -> int:
    """Position in ``done`` (ordered by start) of the best run: not failed, then the lowest
    final cost; raises :class:`SolverError` when no run has a result."""
    ok = [r for r in done if r is not None and r.result is not None]
    if not ok:
        first = done[0]
        raise SolverError(
            f"all {len(done)} fit run(s) failed; start 0: {first.error}", status=first.status
        )
    best = min(ok, key=lambda r: (r.result is None or r.result.status == "failed", r.cost, r.index))
    return best.index
