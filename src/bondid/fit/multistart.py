"""Multistart: several fits from Latin-hypercube starts within the bounds, in parallel.

Start 0 is always the model's own (URDF) values; starts 1..N-1 fill the box
``[lower, upper]`` with a seeded Latin hypercube (:class:`scipy.stats.qmc.LatinHypercube`),
so the same seed gives the same starts. A parameter whose box spans more than a decade with
``lower > 0`` (typically an absolute stiffness or damping range) is sampled uniformly in its
logarithm. The fits run in separate processes (:class:`concurrent.futures.ProcessPoolExecutor`,
2 workers by default, one per core of the reference machine); the best final cost wins and the
spread of the final costs is reported.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..exceptions import ComputationError, ConfigError, SolverError
from ..model.document import UrdfDocument
from ..model.parameters import get_parameters
from .solver import PRESOLVE_ITER

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .result import FitResult

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
    stages: list[Any] = field(default_factory=list)  # staged fit: StageResult per stage
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
    index: int
    doc: UrdfDocument
    datasets: list[FrfData]
    names: list[str]
    options: CostOptions
    lower: np.ndarray
    upper: np.ndarray
    start: np.ndarray
    max_iter: int
    staged: bool
    stage_bands: dict[str, list[tuple[float, float]]] | None
    presolve_iter: int = PRESOLVE_ITER
    continuation: int = 0
    prior_width: float = 0.0


def _run_job(job: _Job, progress: Callable[[int, float], None] | None = None) -> RunOutcome:
    """Run one start (in a worker process or in-process).

    A failed computation (solver failure, singular matrix) becomes a failed run; bad input
    (:class:`ConfigError`, :class:`ParameterError`, ...) propagates.
    """
    t0 = time.perf_counter()
    try:
        if job.staged or job.continuation:
            from .continuation import continuation_fit
            from .staged import staged_fit

            common: dict[str, Any] = {
                "options": job.options, "lower": job.lower, "upper": job.upper,
                "start": job.start, "max_iter": job.max_iter, "progress": progress,
                "presolve_iter": job.presolve_iter,
            }  # fmt: skip
            st = (
                staged_fit(job.doc, job.datasets, job.names, stage_bands=job.stage_bands, **common)
                if job.staged
                else continuation_fit(
                    job.doc, job.datasets, job.names, n_bands=job.continuation, **common
                )
            )
            return RunOutcome(
                job.index, job.start, st.result, stages=st.stages,
                wall_s=time.perf_counter() - t0,
            )  # fmt: skip
        from .solver import fit

        res = fit(
            job.doc, job.datasets, job.names, options=job.options, lower=job.lower,
            upper=job.upper, start=job.start, max_iter=job.max_iter, progress=progress,
            presolve_iter=job.presolve_iter, prior_width=job.prior_width,
        )  # fmt: skip
        return RunOutcome(job.index, job.start, res, wall_s=time.perf_counter() - t0)
    except ComputationError as exc:
        return RunOutcome(
            job.index, job.start, None, str(exc), getattr(exc, "status", None),
            wall_s=time.perf_counter() - t0,
        )  # fmt: skip
    except (np.linalg.LinAlgError, FloatingPointError) as exc:
        return RunOutcome(job.index, job.start, None, str(exc), wall_s=time.perf_counter() - t0)


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
    max_iter: int = 200,
    workers: int = 2,
    staged: bool = False,
    continuation: int = 0,
    stage_bands: dict[str, list[tuple[float, float]]] | None = None,
    on_run: RunProgress | None = None,
    on_iteration: Callable[[int, float], None] | None = None,
    presolve_iter: int = PRESOLVE_ITER,
    prior_width: float = 0.0,
) -> MultistartResult:
    """Fit from ``n_starts`` starts (start 0 = the URDF values) and keep the best.

    Args:
        doc: the model (not modified).
        datasets: measured FRFs (one linearisation per operating point).
        names: free parameters, length ``p``.
        lower, upper: bounds, shape ``(p,)`` each (SI units of each parameter).
        options: cost options (default :class:`CostOptions`).
        n_starts: number of starts; 1 runs the single fit in this process.
        seed: Latin-hypercube seed.
        max_iter: IPOPT iteration limit per fit.
        workers: processes to use (1 = run the starts one after another here).
        staged: run each start as a staged fit (:func:`bondid.fit.staged.staged_fit`).
        continuation: run each start as a band continuation with this many bands
            (:func:`bondid.fit.continuation.continuation_fit`); 0 = off.
        stage_bands: user bands per stage for the staged fit.
        on_run: called in this process as each run finishes.
        on_iteration: per-iteration progress ``(iteration, cost)``, only for runs done in
            this process (``workers == 1`` or a single start).
        presolve_iter: normalised-complex presolve iterations of each fit
            (:data:`bondid.fit.solver.PRESOLVE_ITER`).
        prior_width: width of the prior toward the model's values (:mod:`bondid.fit.prior`;
            0 = none) of each plain fit; staged and continuation runs have none.

    Returns:
        :class:`MultistartResult`; ``.best`` is the best :class:`FitResult`.

    Raises:
        SolverError: every run failed (keeps the status of start 0's failure).
        ConfigError: bad start count.
    """
    t0 = time.perf_counter()
    opts = options or CostOptions()
    names = list(names)
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    x0 = np.clip(get_parameters(doc, names), lo, hi)
    starts = lhs_starts(x0, lo, hi, n_starts, seed)
    common = (list(datasets), names, opts, lo, hi)
    jobs = [
        _Job(
            i,
            doc,
            *common,
            starts[i],
            max_iter,
            staged,
            stage_bands,
            presolve_iter,
            continuation,
            prior_width,
        )
        for i in range(n_starts)
    ]
    runs: list[RunOutcome | None] = [None] * n_starts
    if n_starts == 1 or workers <= 1:
        for k, job in enumerate(jobs):
            runs[job.index] = out = _run_job(job, on_iteration)
            if on_run is not None:
                on_run(k + 1, n_starts, out)
    else:
        from ..interrupt import ignore_in_worker, terminate_on_interrupt

        with (
            ProcessPoolExecutor(
                max_workers=min(workers, n_starts), initializer=ignore_in_worker
            ) as pool,
            terminate_on_interrupt(pool),
        ):
            futures: dict[Future[RunOutcome], int] = {
                pool.submit(_run_job, j): j.index for j in jobs
            }
            for k, fut in enumerate(as_completed(futures)):
                out = fut.result()
                runs[futures[fut]] = out
                if on_run is not None:
                    on_run(k + 1, n_starts, out)
    done = [r for r in runs if r is not None]
    ok = [r for r in done if r.result is not None]
    if not ok:
        first = done[0]
        raise SolverError(
            f"all {n_starts} fit run(s) failed; start 0: {first.error}", status=first.status
        )
    best = min(ok, key=lambda r: (r.cost, r.index))
    return MultistartResult(done, best.index, time.perf_counter() - t0)
