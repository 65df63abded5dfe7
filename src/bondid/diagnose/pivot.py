"""The pivot of a rotational joint compliance, refined continuously (:func:`refine_pivot`).

Where a guide or bearing really pivots is seldom known, and the pivot enters the kinematics
(a pivot off the bearing centre couples the rotation with translations of the child), so the
refit cannot vary it as a parameter. The candidate's variants (:func:`.effects.joint_compliance
.pivot_options`) try a few discrete levels, one direction across the axis at a time; a real
pivot lies anywhere across the axis, and 2 cm off changes the fit far more than the noise.
When the refit at the kept pivot ends above the noise level
(:func:`.alternatives.at_refined_pivot`), :func:`refine_pivot` moves that pivot by a compass
(pattern) search in the plane across the axis, inside :func:`pivot_box`: steps of a quarter
of the box's extent (:data:`FIRST_STEP` without a hull), halved after a round without a
better point, each point judged by the training cost of the second origin's short start
(:func:`.runner._alt_start`, the screening's figure) or, once a refit's spring sits at a mode,
by a solve of the new parameters from that refit (:func:`.alternatives.refine_job_pivot`).

The box is the child's hull's bounding box grown to take in the interface's bearing centre
(the candidate's own first pivot, :func:`.effects.joint_compliance.pivot_options`): a guide
pivots within its body or at the interface, which often lies outside the child's hull (below
its bottom face). Measured (stop 37) on bonder/jcr+al/coh, whose true pivot is 1 mm below the
y stage's hull (bearing centre 10 mm further down): the final model's objective on all data
(a 40-iteration solve of every parameter at each pivot) is 9.68 at the search's pivot
(z = +27 mm), 0.337 at the truth's; on a 10 mm grid it is below 3.5 in a basin 20–50 mm across
around the truth's pivot and 10–73 elsewhere, so a compass search from the search's pivot
cannot reach it. With ``grid`` the compass search therefore starts at the best point of a
coarse grid over the box (the start included), its first steps half the grid's spacing.
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
#: levels per direction of the grid that starts the final fit's pivot search (:mod:`.final_pivot`;
#: module docstring): 25 solves of every parameter for a pivot across two directions
FINAL_GRID = 5


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


def pivot_box(cand: Candidate) -> tuple[np.ndarray, np.ndarray] | None:
    """The box (lower and upper corners, m, child frame) a rotational compliance's pivot is
    searched in: the child's hull box (``spec["box"]``, recorded with the candidate:
    :func:`.effects.topology.link_box`) grown to take in the interface's bearing centre
    (``spec["bearing"]``, when the candidate records it) and the candidate's pivot (module
    docstring); None when the child has no hull."""
    box = cand.spec.get("box")
    if box is None:
        return None
    pts = [np.asarray(cand.spec["pivot"], float)]
    if "bearing" in cand.spec:
        pts.append(np.asarray(cand.spec["bearing"], float))
    lo, hi = np.asarray(box[0], float), np.asarray(box[1], float)
    return np.minimum(lo, np.min(pts, axis=0)), np.maximum(hi, np.max(pts, axis=0))


def grid_points(
    start: np.ndarray, across: np.ndarray, box: tuple[np.ndarray, np.ndarray], n: int
) -> tuple[list[np.ndarray], np.ndarray]:
    """``n`` evenly spaced levels per direction ``across`` the axis over ``box`` (the other
    coordinates at ``start``'s): the points (m) and the spacing per direction ``(n_across,)``."""
    levels = [np.linspace(box[0][d], box[1][d], n) for d in across]
    spacing = np.array([(box[1][d] - box[0][d]) / max(n - 1, 1) for d in across])
    out = []
    for combo in np.stack(np.meshgrid(*levels, indexing="ij"), -1).reshape(-1, across.size):
        p = np.asarray(start, float).copy()
        p[across] = combo
        out.append(p)
    return out, spacing


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
    grid: int = 0,
) -> tuple[Candidate, float, int]:
    """The compass search of the module docstring from ``cand``'s pivot.

    Args:
        cand: a rotational joint-compliance candidate (``spec``: ``axis``, ``pivot``).
        cost: the figure of a candidate (lower is better; inf where the model fails).
        extent: the child's hull extent (m, child frame) or None.
        move: ``cand`` about another pivot (default :func:`with_pivot`: the same parameters;
            the diagnosis rebuilds them about the pivot, :meth:`.effects.joint_compliance.
            JointCompliance.at_pivot`).
        box: lower and upper corners (m, child frame) the pivot stays in
            (:func:`pivot_box`: a bearing pivots within its body or at the interface), or None.
        max_evals: cost evaluations of the compass search at most, the start's included.
        grid: levels per direction across the axis of a grid over ``box`` judged first (the
            compass search starts at its best point, the start included; its evaluations
            come on top of ``max_evals``); 0 (or no box): none.

    Returns:
        The candidate at the best pivot found, its cost and the number of evaluations.
    """
    axis = np.asarray(cand.spec["axis"], float)
    across = np.flatnonzero(np.abs(axis) < 0.5)
    best_p = np.asarray(cand.spec["pivot"], float)
    best = cost(cand)
    n = 1
    steps = first_steps(extent, across)
    n_max = max_evals
    if grid > 1 and box is not None:
        points, spacing = grid_points(best_p, across, box, grid)
        for p in points:
            c = cost(move(cand, p))
            n += 1
            if c < best:
                best, best_p = c, p
        steps, n_max = np.maximum(spacing / 2, MIN_STEP), n + max_evals - 1
    while n < n_max and np.any(steps >= MIN_STEP):
        moved = False
        for k, d in enumerate(across):
            for sign in (1.0, -1.0):
                if n >= n_max:
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
