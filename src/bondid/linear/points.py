"""Rows of B and C for measurement points, from Pinocchio's frame Jacobians at a pose.

A point (:class:`bondid.model.points.Point`) measures ``y = dᵀ (J_A − J_B) δq`` where ``J_A`` is
the 3 translational (or rotational) rows of the ``LOCAL_WORLD_ALIGNED`` Jacobian of its frame
at the operating point, ``J_B`` the same of ``relative_to`` (absent = 0) and ``d`` the unit
direction in world axes (``axes = "local"``: the direction given in the frame's own axes,
rotated to world at the pose). As an input, the force (torque) ``u·d`` at the frame — with
the opposite reaction on ``relative_to`` — is the generalised force ``(J_A − J_B)ᵀ d u``.
So the same point as input and output gives ``b = cᵀ`` (reciprocity).

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
    import pinocchio as pin

    if not points:
        return np.zeros((0, model.nv))
    data = model.createData()
    pin.computeJointJacobians(model, data, q0)
    pin.updateFramePlacements(model, data)

    def jac(name: str, p: Point, rows: slice) -> np.ndarray:
        fid = _frame_id(model, name, where, p.name)
        J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        return np.asarray(J)[rows]

    out = np.zeros((len(points), model.nv))
    for i, p in enumerate(points):
        rows = slice(0, 3) if p.kind == "translation" else slice(3, 6)
        d = np.asarray(p.direction, dtype=float)
        if p.axes == "local":
            fid = _frame_id(model, p.link, where, p.name)
            d = np.asarray(data.oMf[fid].rotation) @ d
        J = jac(p.link, p, rows)
        if p.relative_to:
            J = J - jac(p.relative_to, p, rows)
        out[i] = d @ J
    return out
