"""Rows of B and C for measurement points, from Pinocchio's frame Jacobians at a pose.

A point (:class:`bondid.model.points.Point`) measures ``y = dᵀ (J_A − J_B) δq`` where ``J_A`` is
the 3 translational (or rotational) rows of the ``LOCAL_WORLD_ALIGNED`` Jacobian of its frame
at the operating point, ``J_B`` the same of ``relative_to`` (absent = 0) and ``d`` the unit
direction in world axes (``axes = "local"``: the direction given in the frame's own axes,
rotated to world at the pose). As an input, the force (torque) ``u·d`` at the frame — with
the opposite reaction on ``relative_to`` — is the generalised force ``(J_A − J_B)ᵀ d u``.
So the same point as input and output gives ``b = cᵀ`` (reciprocity). A point with a second
component (:attr:`bondid.model.points.Point.mixed`) has the row ``r₁ + mix · r₂``, each
``rₖ`` the row of one component (its own kind and direction); :func:`component_rows` gives
both, from which the derivative in ``mix`` is ``r₂``.

The rows depend on the kinematics at the pose only, never on the inertial or joint
parameters, so the FRF derivatives of :mod:`bondid.frf.jacobian` stay exact.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..exceptions import ModelError
from ..model.points import Point


def _frame_id(model, name: str, where: str, point: str) -> int:
    import pinocchio as pin

    for ftype in (pin.FrameType.BODY, None):
        fid = model.getFrameId(name) if ftype is None else model.getFrameId(name, ftype)
        if fid < model.nframes:
            return int(fid)
    links = sorted({f.name for f in model.frames if f.type == pin.FrameType.BODY})
    raise ModelError(
        f"{where}: point {point!r} names frame {name!r}, which the model lacks; links:"
        f" {', '.join(links)}"
    )


def point_rows(model, q0: np.ndarray, points: Sequence[Point], where: str) -> np.ndarray:
    """Output rows ``(n_points, nv)`` of ``points`` at configuration ``q0``.

    Args:
        model: the Pinocchio model.
        q0: configuration ``(nq,)``.
        points: the points, in row order.
        where: the model file, for error messages.

    Returns:
        ``C`` rows (m/… or rad/… per generalised coordinate); the input columns are their
        transposes.
    """
    first, second = component_rows(model, q0, points, where)
    mix = np.array([p.mix if p.mixed else 0.0 for p in points])
    return first + mix[:, None] * second


def component_rows(
    model, q0: np.ndarray, points: Sequence[Point], where: str
) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``(n_points, nv)`` of each point's first component and of its second one (zero
    for a point without one) at configuration ``q0``: :func:`point_rows` is ``first + mix ·
    second``."""
    import pinocchio as pin

    first, second = np.zeros((len(points), model.nv)), np.zeros((len(points), model.nv))
    if not points:
        return first, second
    data = model.createData()
    pin.computeJointJacobians(model, data, q0)
    pin.updateFramePlacements(model, data)

    def row(p: Point, kind: str, direction: Sequence[float]) -> np.ndarray:
        rows = slice(0, 3) if kind == "translation" else slice(3, 6)
        d = np.asarray(direction, dtype=float)
        if p.axes == "local":
            fid = _frame_id(model, p.link, where, p.name)
            d = np.asarray(data.oMf[fid].rotation) @ d
        J = _jacobian(model, data, p.link, where, p.name)[rows]
        if p.relative_to:
            J = J - _jacobian(model, data, p.relative_to, where, p.name)[rows]
        return d @ J

    for i, p in enumerate(points):
        first[i] = row(p, p.kind, p.direction)
        if p.mixed:
            assert p.second_kind is not None and p.second_direction is not None
            second[i] = row(p, p.second_kind, p.second_direction)
    return first, second


def _jacobian(model, data, frame: str, where: str, point: str) -> np.ndarray:
    """The ``LOCAL_WORLD_ALIGNED`` Jacobian ``(6, nv)`` of ``frame`` (kinematics computed)."""
    import pinocchio as pin

    fid = _frame_id(model, frame, where, point)
    return np.asarray(
        pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    )
