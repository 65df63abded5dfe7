"""The pivot of a rotational joint compliance, refined continuously (:func:`refine_pivot`).

Where a guide or bearing really pivots is seldom known, and the pivot enters the kinematics
(a pivot off the bearing centre couples the rotation with translations of the child), so the
refit cannot vary it as a parameter. The candidate's variants (:func:`.effects.joint_compliance
.pivot_options`) try a few discrete levels, one direction across the axis at a time; a real
pivot lies anywhere across the axis, and 2 cm off changes the fit far more than the noise.
When the refit at the kept pivot ends above the noise level
(:func:`.alternatives.at_refined_pivot`), :func:`refine_pivot` moves that pivot by a compass
(pattern) search in the plane across the axis, inside the child's hull's bounding box: steps
of a quarter of the hull's extent (:data:`FIRST_STEP` when it has no hull), halved after a
round without a better point, each point judged by the training cost of the second origin's
short start (:func:`.runner._alt_start`, the screening's figure) or, once a refit's spring
sits at a mode, by a solve of the new parameters from that refit
(:func:`.alternatives.refine_job_pivot`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .effects import Candidate

#: first step when the child has no collision hull [m]
FIRST_STEP = 0.02
#: steps no smaller than this [m]
MIN_STEP = 0.002
#: the first step as a share of the child's hull extent across the axis
STEP_SHARE = 0.25
#: cost evaluations per refinement at most (the start's included)
MAX_EVALS = 16
#: IPOPT iterations of the solve of every parameter that judges one pivot, when a pivot is
#: judged that way (:func:`.alternatives.refine_job_pivot` with ``full``, :mod:`.final_pivot`)
FULL_EVAL_ITER = 40
#: pivots judged that way per refinement at most (each solve far dearer than a solve of the
#: new parameters alone; measured on bonder/jcr/acc, stop 32: 16 stopped 5 mm short of the
#: truth's pivot)
FULL_MAX_EVALS = 24


def is_rotational_compliance(cand: Candidate | None) -> bool:
    return (
        cand is not None
        and cand.effect == "joint_compliance"
        and cand.spec.get("kind") == "revolute"
    )


def with_pivot(cand: Candidate, pivot: np.ndarray) -> Candidate:
    """``cand`` with its pivot at ``pivot`` (child frame, m) and no variants."""
    spec = {**cand.spec, "pivot": [float(x) for x in pivot]}
    head = cand.description.split(" pivot ")[0]
    where = np.round(pivot * 1e3, 1).tolist()
    return replace(cand, spec=spec, variants=(), description=f"{head} pivot {where} mm")


def child_box(urdf: str, child: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Lower and upper corners (m, child frame) of ``child``'s collision hull's bounding box,
    or None without a hull."""
    from ..consistency.hull import link_hull
    from ..model.document import UrdfDocument

    hull = link_hull(UrdfDocument.from_string(urdf).link(child))
    return None if hull is None else (hull.vertices.min(axis=0), hull.vertices.max(axis=0))


def first_steps(extent: np.ndarray | None, across: np.ndarray) -> np.ndarray:
    """Start steps (m) per direction ``across`` the axis from the child's hull ``extent``."""
    if extent is None:
        return np.full(across.size, FIRST_STEP)
    return np.maximum(STEP_SHARE * np.asarray(extent, float)[across], MIN_STEP)


def refine_pivot(
    cand: Candidate,
    cost: Callable[[Candidate], float],
    extent: np.ndarray | None = None,
    move: Callable[[Candidate, np.ndarray], Candidate] = with_pivot,
    box: tuple[np.ndarray, np.ndarray] | None = None,
    max_evals: int = MAX_EVALS,
) -> tuple[Candidate, float, int]:
    """The compass search of the module docstring from ``cand``'s pivot.

    Args:
        cand: a rotational joint-compliance candidate (``spec``: ``axis``, ``pivot``).
        cost: the figure of a candidate (lower is better; inf where the model fails).
        extent: the child's hull extent (m, child frame) or None.
        move: ``cand`` about another pivot (default :func:`with_pivot`: the same parameters;
            the diagnosis rebuilds them about the pivot, :meth:`.effects.joint_compliance.
            JointCompliance.at_pivot`).
        box: lower and upper corners (m, child frame) the pivot stays in (the child's hull's
            bounding box, :func:`child_box`: a bearing pivots within its body), or None.
        max_evals: cost evaluations at most, the start's included.

    Returns:
        The candidate at the best pivot found, its cost and the number of evaluations.
    """
    axis = np.asarray(cand.spec["axis"], float)
    across = np.flatnonzero(np.abs(axis) < 0.5)
    best_p = np.asarray(cand.spec["pivot"], float)
    best = cost(cand)
    n = 1
    steps = first_steps(extent, across)
    while n < max_evals and np.any(steps >= MIN_STEP):
        moved = False
        for k, d in enumerate(across):
            for sign in (1.0, -1.0):
                if n >= max_evals:
                    break
                p = best_p.copy()
                p[d] += sign * steps[k]
                if box is not None and not box[0][d] <= p[d] <= box[1][d]:
                    continue
                c = cost(move(cand, p))
                n += 1
                if c < best:
                    best, best_p, moved = c, p, True
                    break
        if not moved:
            steps = steps / 2
    return move(cand, best_p), best, n
