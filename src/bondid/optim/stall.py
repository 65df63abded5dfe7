"""When a solve has stopped making progress: the stall test of :func:`bondid.optim.ipopt.solve`.

IPOPT stops when its scaled NLP error is below ``tol``. On a problem whose minimum lies in a
flat valley (parameters the data barely determine, a damper collapsing towards its bound) the
cost can stay flat to the last digit for hundreds of iterations while that error, a
mixture of the dual infeasibility and the complementarity of the bounds, never reaches
``tol``: the solve then runs to its iteration limit and reads as a failure, although its
point is as good as any the method will reach. IPOPT's own acceptable-level test does not
help there: it too needs the NLP error below ``acceptable_tol`` (and its objective-change
test only adds a condition to that one).

:class:`StallMonitor` looks at the iterates as they come and stops a solve when, over the
last :attr:`StallRule.window` iterations, all three hold:

* the objective changed by less than ``f_rtol`` relative to its value,
* no step moved a decision variable by more than ``x_rtol`` (relative to ``1 + ‖z‖∞``; the
  decision vector is scaled to O(1)),
* the local model promises nothing: the decrease a Gauss–Newton step on the Lagrangian's
  gradient (the projected gradient: the bound and constraint multipliers remove what
  the active constraints forbid) would bring, ``¼ ∇Lᵀ (JᵀJ)⁺ ∇L``, is below ``decrement_rtol``
  times the objective (:func:`gauss_newton_decrement`).

It also stops a solve that has stopped making progress at all: over the last
:attr:`StallRule.progress_window` iterations the best cost fell by less than
``progress_rtol`` and every cost stayed within ``spread_rtol`` of it, although the steps still
move. An interior-point method reaches that state when its barrier subproblem cannot be
solved to the tolerance that would let it lower the barrier parameter: typically where
parameters the data barely determine press against a bound or a consistency constraint
(the Gauss–Newton decrement, which ignores those constraints, then still promises a
decrease the solver cannot take). More iterations only wander along that valley.

The solve is then converged with a reason (status :data:`STALLED`), not failed. So is one
IPOPT ended because its search direction became too small to move
(``Search_Direction_Becomes_Too_Small``) when its cost is flat over its last iterations and the
Gauss–Newton decrement is small there (:meth:`StallMonitor.settled`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: the status of a solve stopped by the stall test (converged, with its reason)
STALLED = "Converged_Stalled"

#: relative cut-off of the Gauss–Newton matrix's eigenvalues in the decrement (directions
#: the data do not determine carry no promise of decrease)
DECREMENT_RCOND = 1e-12


@dataclass(frozen=True)
class StallRule:
    """The stall test's tolerances (see the module docstring).

    Attributes:
        window: iterations the objective and the steps are judged over (>= 1).
        f_rtol: largest relative change of the objective over the window.
        x_rtol: largest step of any decision variable, relative to ``1 + ‖z‖∞``.
        decrement_rtol: largest Gauss–Newton decrement relative to the objective.
        progress_window: iterations over which a solve that makes no progress is judged
            (the second test of the module docstring; > ``window``).
        progress_rtol: largest fall of the best cost over that window, relative to it.
        spread_rtol: largest excess of any cost in that window over the best, relative.
    """

    window: int = 10
    f_rtol: float = 1e-9
    x_rtol: float = 1e-5
    decrement_rtol: float = 1e-6
    progress_window: int = 50
    progress_rtol: float = 1e-6
    spread_rtol: float = 1e-5


#: iterations over which a solve IPOPT ended with too small a search direction must be flat
MIN_SETTLED = 3

#: the test :func:`bondid.optim.ipopt.solve` runs by default
DEFAULT_RULE = StallRule()


def gauss_newton_decrement(J: np.ndarray, grad_lagrangian: np.ndarray) -> float:
    """``¼ dᵀ (JᵀJ)⁺ d`` for ``d`` = the Lagrangian's gradient ``(n,)`` and the residual
    Jacobian ``J`` ``(m, n)``: what a Gauss–Newton step of ``‖r‖²`` would lower it by (the
    objective's Hessian is ``2 JᵀJ``). Directions whose eigenvalue is below
    :data:`DECREMENT_RCOND` times the largest are left out."""
    A = J.T @ J
    w, V = np.linalg.eigh(0.5 * (A + A.T))
    top = float(w[-1]) if w.size else 0.0
    if not top > 0:
        return 0.0
    keep = w > DECREMENT_RCOND * top
    c = V[:, keep].T @ grad_lagrangian
    return 0.25 * float(np.sum(c**2 / w[keep]))


class StallMonitor:
    """Called after every IPOPT iteration with ``(f, z, lam_x, lam_g)``; returns True when
    the solve has stalled (:attr:`reason` then says how).

    Args:
        rule: the tolerances.
        decrement: ``(z, lam_x, lam_g) -> (Gauss–Newton decrement, f)`` at an iterate
            (evaluated only when the objective and the steps are already flat).
    """

    def __init__(
        self,
        rule: StallRule,
        decrement: Callable[[np.ndarray, np.ndarray, np.ndarray], float],
    ):
        self.rule = rule
        self._decrement = decrement
        self._f: list[float] = []
        self._best: list[float] = []  # the best finite cost up to each iteration
        self._steps: list[float] = []
        self._last: np.ndarray | None = None
        self.reason: str | None = None

    def __call__(self, f: float, z: np.ndarray, lam_x: np.ndarray, lam_g: np.ndarray) -> bool:
        rule = self.rule
        z = np.asarray(z, dtype=float)
        if self._last is not None:
            self._steps.append(float(np.max(np.abs(z - self._last), initial=0.0)))
        self._last = z.copy()
        self._f.append(float(f))
        prev = self._best[-1] if self._best else math.inf
        self._best.append(min(prev, float(f)) if np.isfinite(f) else prev)
        if len(self._f) <= rule.window or not np.isfinite(f):
            return False
        recent = self._f[-rule.window - 1 :]
        scale = max(abs(float(f)), np.finfo(float).tiny)
        change = (max(recent) - min(recent)) / scale
        step = self._largest_step(rule.window, z)
        if not (change <= rule.f_rtol and step <= rule.x_rtol):
            return self._no_progress(z)
        dec = self._decrement(z, np.asarray(lam_x, float), np.asarray(lam_g, float)) / scale
        if not dec <= rule.decrement_rtol:
            return self._no_progress(z)
        self.reason = (
            f"stalled: over the last {rule.window} iterations the cost changed by"
            f" {change:.1e} (relative), no step exceeded {step:.1e}, and a Gauss-Newton step"
            f" would lower it by {dec:.1e} at most"
        )
        return True

    def _largest_step(self, n: int, z: np.ndarray) -> float:
        """The largest of the last ``n`` steps, relative to ``1 + ‖z‖∞``."""
        return max(self._steps[-n:]) / (1.0 + float(np.max(np.abs(z), initial=0.0)))

    def _no_progress(self, z: np.ndarray) -> bool:
        """The second test (module docstring) at the iterate ``z``; sets :attr:`reason`
        when it holds."""
        rule = self.rule
        n = rule.progress_window
        if len(self._f) <= n:
            return False
        best, before = self._best[-1], self._best[-n - 1]
        scale = max(abs(best), np.finfo(float).tiny)
        fall = (before - best) / scale
        spread = (max(self._f[-n - 1 :]) - best) / scale
        if not (fall <= rule.progress_rtol and spread <= rule.spread_rtol):
            return False
        step = self._largest_step(n, z)
        self.reason = (
            f"stalled: over the last {n} iterations the best cost fell by {fall:.1e}"
            f" (relative) and no cost strayed more than {spread:.1e} from it, while steps of"
            f" up to {step:.1e} still moved the parameters: the solver makes no more progress"
        )
        return True

    def settled(self, z: np.ndarray, lam_x: np.ndarray, lam_g: np.ndarray) -> bool:
        """After IPOPT gave up on a search direction too small to move (its steps are then
        settled by its own test): is the cost flat over its last :data:`MIN_SETTLED`
        iterations with nothing promised by a Gauss–Newton step? Sets :attr:`reason` when
        it is."""
        rule = self.rule
        recent = self._f[-MIN_SETTLED - 1 :]
        if len(recent) <= MIN_SETTLED or not np.all(np.isfinite(recent)):
            return False
        scale = max(abs(recent[-1]), np.finfo(float).tiny)
        change = (max(recent) - min(recent)) / scale
        if not change <= rule.f_rtol:
            return False
        dec = self._decrement(np.asarray(z, float), np.asarray(lam_x, float),
                              np.asarray(lam_g, float)) / scale  # fmt: skip
        if not dec <= rule.decrement_rtol:
            return False
        self.reason = (
            f"stalled: IPOPT's search direction became too small to move, the cost changed by"
            f" {change:.1e} (relative) over the last {len(recent) - 1} iterations and a"
            f" Gauss-Newton step would lower it by {dec:.1e} at most"
        )
        return True


def still_falling(history: list[float], window: int = DEFAULT_RULE.window,
                  f_rtol: float = 1e-6) -> bool:  # fmt: skip
    """Was the cost still falling at the end of ``history`` (the objective per iteration):
    more than ``f_rtol`` (relative) over its last ``window`` iterations? (A short history
    counts as falling.)"""
    h = [v for v in history if np.isfinite(v)]
    if len(h) <= window:
        return True
    first, last = h[-window - 1], h[-1]
    return first - last > f_rtol * max(abs(last), np.finfo(float).tiny)
