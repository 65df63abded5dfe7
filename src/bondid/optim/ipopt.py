"""The one place where IPOPT runs: :func:`solve` a :class:`~.problem.FitProblem`.

IPOPT is given the problem's CasADi functions (:class:`~.nlp.Nlp`: the objective ``‖r(z)‖²``,
its gradient and a Gauss–Newton Hessian of the Lagrangian, the residual computed in numpy).

:func:`solve` never raises for an IPOPT status: every outcome is a :class:`Solution`. A solve
that failed (infeasible, restoration failed, CasADi error ...) keeps the lowest-cost iterate
that met the constraints (or the start when there was none), with ``failure`` set; one that
stopped normally keeps that iterate too when its last one costs more.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import interrupt
from ..exceptions import SolverError
from .recorder import Recorder
from .stall import DEFAULT_RULE, STALLED, StallMonitor, StallRule

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .problem import FitProblem

#: IPOPT statuses counted as success, and the stall test's (:mod:`.stall`)
SUCCESS_STATUSES = frozenset({"Solve_Succeeded", "Solved_To_Acceptable_Level", STALLED})
#: IPOPT statuses that leave a usable final iterate (``success=False``, no ``failure``).
SOFT_STATUSES = frozenset(
    {
        "Maximum_Iterations_Exceeded",
        "Maximum_CpuTime_Exceeded",
        "Maximum_WallTime_Exceeded",
        "Search_Direction_Becomes_Too_Small",
        "User_Requested_Stop",
        "Feasible_Point_Found",
    }
)
#: IPOPT's status when its search direction became too small to move the iterate
TINY_STEP = "Search_Direction_Becomes_Too_Small"
#: IPOPT options of a solve warm-started at a fit (IPOPT's default initial barrier, 0.1, is of
#: the order of our objectives there and pushes the iterates off the start). Measured on the
#: all-data refit of a blind-benchmark case's final model (the gantry design, a rotational
#: joint compliance, no coherence; 50 parameters, from cost 1.087 at a feasible start): 0.1
#: went uphill to 1.365 in 300 iterations, 1e-4 (and 1e-6) converged to 0.936 in 109 (122).
#: Cold fits of the refit benchmark (harsh and acc regimes,
#: the three designs, 6 cases) ended at the same db_rms with either; the diagnosis's search
#: keeps the default until its benchmark is run with it.
WARM_START: dict[str, float] = {"mu_init": 1e-4}


@dataclass
class Solution:
    """One IPOPT solve of a :class:`~.problem.FitProblem` (arrays in its decision vector ``z``).

    Attributes:
        z: the point kept ``(size,)``: IPOPT's last iterate; the lowest-cost feasible iterate
            (``kept == "best"``) when the solve failed or when that iterate costs less than
            the last one (:class:`~.recorder.Recorder`); the start (``"start"``) when a failed
            solve passed through no feasible iterate.
        cost: ``‖r(z)‖²`` at ``z``.
        status: IPOPT's ``return_status`` (``"exception"`` when CasADi raised).
        success: IPOPT converged (:data:`SUCCESS_STATUSES`).
        failure: why the solve failed (None when IPOPT stopped normally or at a limit,
            :data:`SOFT_STATUSES`).
        kept: ``"final"``, ``"best"`` or ``"start"`` (see ``z``).
        iterations, wall_s: IPOPT iterations and wall time (s).
        history: the objective at every IPOPT iteration.
        g: constraint values ``(ng,)`` at ``z``.
        lam_x, lam_g: IPOPT's multipliers ``(n,)``, ``(ng,)`` at its last iterate.
        stop_reason: why a solve stopped converged by the stall test (status
            :data:`.stall.STALLED`), else None.
    """

    z: np.ndarray
    cost: float
    status: str
    success: bool
    iterations: int
    wall_s: float = 0.0
    history: list[float] = field(default_factory=list)
    failure: str | None = None
    kept: str = "final"
    g: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lam_x: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lam_g: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stop_reason: str | None = None

    @property
    def failed(self) -> bool:
        """The solve failed (``failure`` is set); ``z`` is the best point it reached."""
        return self.failure is not None

    def error(self) -> SolverError:
        """The failure as a :class:`SolverError` keeping IPOPT's status."""
        return SolverError(self.failure or f"IPOPT stopped with {self.status}", status=self.status)


def solve(
    problem: FitProblem,
    z0: np.ndarray | None = None,
    *,
    max_iter: int = 200,
    tol: float = 1e-10,
    progress: Callable[[int, float], None] | None = None,
    ipopt_options: dict[str, Any] | None = None,
    constraint_hessian: str = "convexified",
    stall: StallRule | None = DEFAULT_RULE,
) -> Solution:
    """Run IPOPT (quiet) on ``problem`` from ``z0`` (default ``problem.z0``).

    Args:
        problem: the fit problem (its evaluator, variable bounds and constraints).
        z0: start ``(problem.size,)`` in the decision vector.
        max_iter, tol: IPOPT's ``max_iter`` and ``tol``.
        progress: called as ``progress(iteration, cost)`` at every IPOPT iteration.
        ipopt_options: extra IPOPT options (override the defaults).
        constraint_hessian: see :class:`~.nlp.Nlp`.
        stall: the stall test (:mod:`.stall`): a solve whose cost, steps and projected
            gradient have gone flat stops converged with status :data:`.stall.STALLED` and
            its reason in ``stop_reason``; None = IPOPT's own tests only.

    Returns:
        A :class:`Solution`; never raises for IPOPT's outcome (a Ctrl-C still interrupts).
    """
    z_start = problem.z0 if z0 is None else np.asarray(z0, dtype=float)
    nlp = problem.nlp(constraint_hessian)
    problem.evaluator.reset()  # every solve starts with the same damping
    cons = nlp.constraints
    rec = Recorder(cons.lower, cons.upper, progress)
    monitor = None if stall is None else StallMonitor(stall, nlp.decrement)

    def on_iteration(
        f: float, z: np.ndarray, g: np.ndarray, lx: np.ndarray, lg: np.ndarray
    ) -> bool:
        rec(f, z, g)
        return monitor is not None and monitor(f, z, lx, lg)

    ipopt: dict[str, Any] = {"print_level": 0, "sb": "yes", "max_iter": int(max_iter),
                             "tol": float(tol), "mu_strategy": "monotone"}  # fmt: skip
    ipopt.update(ipopt_options or {})
    t0 = time.perf_counter()
    try:
        solver, callback = nlp.solver(on_iteration, ipopt)
        sol = solver(x0=z_start, lbx=problem.lbz, ubx=problem.ubz, lbg=cons.lower, ubg=cons.upper)
    except RuntimeError as exc:
        interrupt.check()  # CasADi turned a Ctrl-C into an error: it is an interrupt
        why = f"IPOPT failed: {str(exc).splitlines()[0]}"
        return _failed(problem, z_start, rec, "exception", why, time.perf_counter() - t0)
    interrupt.check()  # a Ctrl-C during the solve stopped IPOPT: stop the run too
    wall = time.perf_counter() - t0
    if callback.error is not None:  # the per-iteration hook stopped the solve (e.g. cancelled)
        status, _ = _stats(solver, len(rec.history))
        return _failed(problem, z_start, rec, status, str(callback.error), wall)
    status, iterations = _stats(solver, len(rec.history))
    reason = None if monitor is None else monitor.reason
    if status == "User_Requested_Stop" and reason is not None:
        status = STALLED
    elif status == TINY_STEP and monitor is not None:
        lam = (_column(sol["lam_x"]), _column(sol["lam_g"]))
        if monitor.settled(_column(sol["x"]), *lam):
            status, reason = STALLED, monitor.reason
    if status not in SUCCESS_STATUSES | SOFT_STATUSES:
        why = (
            f"IPOPT stopped with {status} after {iterations} iterations "
            f"(cost {float(sol['f']):.6g}); check the bounds and the start"
        )
        out = _failed(problem, z_start, rec, status, why, wall)
        out.iterations = iterations
        return out
    out = Solution(
        z=_column(sol["x"]), cost=float(sol["f"]), status=status,
        success=status in SUCCESS_STATUSES, iterations=iterations, wall_s=wall,
        history=rec.history, g=_column(sol["g"]), lam_x=_column(sol["lam_x"]),
        lam_g=_column(sol["lam_g"]), stop_reason=reason if status == STALLED else None,
    )  # fmt: skip
    best = rec.better_than(out.cost)
    if best is not None:
        # the path went uphill from a feasible iterate: keep that one (multipliers: the last)
        (out.z, out.cost, out.g), out.kept = best, "best"
    return out


def _stats(solver: Any, n_recorded: int) -> tuple[str, int]:
    """IPOPT's ``(return_status, iterations)`` after a solve."""
    stats = solver.stats()
    return str(stats.get("return_status", "unknown")), int(
        stats.get("iter_count", max(n_recorded - 1, 0))
    )


def _column(v: Any) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(-1)


def _failed(
    problem: FitProblem, z0: np.ndarray, rec: Recorder, status: str, why: str, wall: float
) -> Solution:
    """A failed solve: the best feasible iterate recorded, else the start."""
    if rec.best_z is not None:
        z, cost, kept = rec.best_z, rec.best_cost, "best"
    else:
        z, cost, kept = z0.copy(), problem.cost(z0), "start"
    return Solution(
        z=z, cost=cost, status=status, success=False, iterations=max(len(rec.history) - 1, 0),
        wall_s=wall, history=rec.history, failure=why, kept=kept,
    )  # fmt: skip
