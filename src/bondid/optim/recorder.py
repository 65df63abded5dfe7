"""What one IPOPT solve passed through: its cost history and its lowest-cost feasible iterate.

:func:`bondid.optim.ipopt.solve` hands IPOPT's per-iteration ``(f, z, g)`` to a
:class:`Recorder`; a solve that failed keeps the recorded best point, and so does one whose
final iterate costs more than a feasible iterate it passed through (an interior-point path can
leave a good start uphill: see :data:`bondid.optim.ipopt.WARM_START`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: constraint violation up to which an iterate counts as feasible
FEASIBLE_TOL = 1e-6
#: the final iterate is replaced by the best one only when that is lower by more than this
#: share of the final cost (not for rounding-level differences at a converged point)
BETTER_BY = 1e-9


class Recorder:
    """Called as ``recorder(f, z, g)`` at every IPOPT iteration.

    Args:
        lbg, ubg: the constraints' bounds ``(ng,)``.
        progress: called as ``progress(iteration, f)`` (None: nothing).

    Attributes:
        history: ``f`` at every iteration.
        best_z, best_cost, best_g: the lowest-cost iterate ``(n,)`` whose constraint values
            ``(ng,)`` are within :data:`FEASIBLE_TOL` of their bounds (None / inf before one).
    """

    def __init__(self, lbg: np.ndarray, ubg: np.ndarray, progress: Callable | None = None):
        self.lbg, self.ubg, self.progress = lbg, ubg, progress
        self.history: list[float] = []
        self.best_z: np.ndarray | None = None
        self.best_g: np.ndarray | None = None
        self.best_cost = float("inf")

    def __call__(self, cost: float, z: np.ndarray, g: np.ndarray) -> None:
        self.history.append(cost)
        tol = FEASIBLE_TOL
        feasible = bool(np.all(g >= self.lbg - tol) and np.all(g <= self.ubg + tol))
        if feasible and np.isfinite(cost) and cost < self.best_cost:
            self.best_z, self.best_g, self.best_cost = z.copy(), g.copy(), cost
        if self.progress is not None:
            self.progress(len(self.history) - 1, cost)

    def better_than(self, cost: float) -> tuple[np.ndarray, float, np.ndarray] | None:
        """``(z, cost, g)`` of the best feasible iterate when it cost less than ``cost`` (by
        more than :data:`BETTER_BY`), else None."""
        if self.best_z is None or self.best_g is None:
            return None
        if not self.best_cost < cost * (1.0 - BETTER_BY):
            return None
        return self.best_z, self.best_cost, self.best_g
