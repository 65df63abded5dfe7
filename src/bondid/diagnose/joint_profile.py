"""The screening's joint profile of a candidate (:func:`joint_profile`).

The one-step figure of :mod:`.screen` is taken where the candidate's new parameters alone fit
best with every nominal parameter held at the parameter refit. That misses a candidate whose
mode the parameter refit has absorbed by bending nominal parameters: placed at its true
frequency with the nominal parameters held, the new mode first makes the fit worse, so the
new-only solve leaves it "absent" (out of band), and the figure taken there is the base's own.
Measured on bonder/jct/coh (withheld x→y translational compliance, 900 Hz): the true candidate
ranked 7th of 17 by that figure, its start at a stiffness putting the mode out of band.

The joint profile sweeps the candidate's scale instead (its scan grid, every
:data:`PROFILE_STRIDE`-th point, plus its start) and, at each point, lets **every**
parameter follow for :data:`PROFILE_ITER` damped Gauss–Newton (Levenberg–Marquardt)
iterations with step acceptance on the real objective (:func:`short_joint_fit`, inside the
bounds, the physical-consistency constraints not enforced: a figure, not a fit). The lowest
objective reached is the candidate's profile figure and its new parameters there the full
refit's start. Same case: the true candidate 1st (objective 1.34 against 1.96 for the next
and 2.17 for the base's own four iterations; noise-level objective 0.54), and its full refit
from that start ends at the held-out noise level (0.708 dB against 0.696) where it ended at
the base's 2.56 dB before.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import ComputationError
from ..optim.problem import FitProblem
from .effects import Candidate
from .refit import Refit, State
from .scan_grid import scan_grid

#: damped Gauss–Newton iterations at each point of the profile
PROFILE_ITER = 4
#: the profile takes every this-many-th point of the candidate's scan grid
PROFILE_STRIDE = 2
#: initial Levenberg–Marquardt damping (relative to diag(JᵀJ)) of the short fits
PROFILE_DAMPING = 1e-2
#: tries (damping ×4 each) before an iteration gives up
_TRIES = 6


@dataclass(frozen=True)
class Profile:
    """A candidate's joint profile.

    Attributes:
        cost: lowest training objective reached (as :meth:`.refit.Refit.cost`; inf when
            every point failed).
        new: the candidate's own new parameters (SI) there.
    """

    cost: float
    new: tuple[float, ...]


def damped_step(J: np.ndarray, r: np.ndarray, damping: float) -> np.ndarray | None:
    """The Levenberg–Marquardt step ``δ = −(JᵀJ + λ diag(JᵀJ))⁻¹ Jᵀr`` ``(n,)`` of the
    residual ``r`` ``(m,)`` with Jacobian ``J`` ``(m, n)``; None when singular."""
    JtJ = J.T @ J
    d = np.maximum(np.diag(JtJ), 1e-12 * max(float(np.max(np.diag(JtJ))), 1e-300))
    try:
        return -np.linalg.solve(JtJ + damping * np.diag(d), J.T @ r)
    except np.linalg.LinAlgError:
        return None


def _cost(p: FitProblem, z: np.ndarray) -> float:
    """The objective of ``p`` at ``z``; inf where the model fails."""
    try:
        c = float(p.cost(z))
    except (ComputationError, np.linalg.LinAlgError, ValueError):
        return float("inf")
    return c if np.isfinite(c) else float("inf")


def short_joint_fit(
    refit: Refit, state: State, n_iter: int = PROFILE_ITER, damping: float = PROFILE_DAMPING
) -> tuple[float, State]:
    """``n_iter`` Levenberg–Marquardt iterations of every parameter of ``refit`` from
    ``state`` (a step is kept only when it lowers the objective; the damping ÷3 after a kept
    step, ×4 after a refused one); returns the objective and the state reached."""
    try:
        p = refit.at(state)
    except (ComputationError, np.linalg.LinAlgError, ValueError):
        return float("inf"), state
    z = p.z0.copy()
    c = _cost(p, z)
    if not np.isfinite(c):
        return c, state
    lam = damping
    for _ in range(n_iter):
        try:
            r, J = p.residual_and_jacobian(z)
        except (ComputationError, np.linalg.LinAlgError, ValueError):
            break
        for _try in range(_TRIES):
            step = damped_step(J, r, lam)
            if step is None:
                lam *= 4.0
                continue
            zn = np.clip(z + step, p.lbz, p.ubz)
            cn = _cost(p, zn)
            if cn < c:
                z, c, lam = zn, cn, lam / 3.0
                break
            lam *= 4.0
        else:
            break
    return c, State(p.values(z), p.theta(z))


def joint_profile(
    refit: Refit, cand: Candidate, hints_hz: Sequence[float] = (),
    n_iter: int = PROFILE_ITER, stride: int = PROFILE_STRIDE,
) -> Profile:  # fmt: skip
    """The joint profile of ``cand`` on ``refit`` (its model augmented with ``cand``), the
    scan grid with the scales that put its mode at each of ``hints_hz`` [Hz] (module
    docstring)."""
    exps = np.array([q.scan for q in cand.parameters], float)
    grid, _ = scan_grid(cand, hints_hz)
    scales = [1.0, *grid[:: max(1, int(stride))]]
    s0 = refit.state0
    best = Profile(float("inf"), tuple(float(v) for v in refit.new_values(s0)))
    for start in [s0, *refit.profile(s0, exps, scales[1:])]:
        c, st = short_joint_fit(refit, start, n_iter)
        if c < best.cost:
            best = Profile(c, tuple(float(v) for v in refit.new_values(st)))
    return best
