"""The Pinocchio side of the affine model: mass-matrix and gravity-stiffness bases per body.

At a configuration ``q0`` the mass matrix and the gravity stiffness ``∂g/∂q`` are linear in
each body's 10 dynamic parameters π (Pinocchio's order, about the link frame origin, link-frame
axes); :func:`inertia_bases` gives the matrix of each parameter, ``(n_bodies, 10, nv, nv)``,
and what no parameterised body contributes (:mod:`bondid.linear.affine` assembles them).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ModelError

_REF_PI = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0])


def link_placements(model, links: list[str], where: str) -> dict[str, tuple[int, object]]:
    """For each link: (parent joint id, placement of the link frame in the joint frame)."""
    import pinocchio as pin

    out = {}
    for name in links:
        if not model.existFrame(name, pin.FrameType.BODY):
            raise ModelError(f"{where}: Pinocchio has no body frame for link {name!r}")
        f = model.frames[model.getFrameId(name, pin.FrameType.BODY)]
        out[name] = (int(f.parentJoint), f.placement)
    return out


def _transport_matrix(placement) -> np.ndarray:
    """10×10 linear map: dynamic parameters in a link frame → in its joint's frame."""
    import pinocchio as pin

    def f(p: np.ndarray) -> np.ndarray:
        return np.asarray(
            pin.Inertia.FromDynamicParameters(p).se3Action(placement).toDynamicParameters()
        )

    base = f(_REF_PI)
    T = np.empty((10, 10))
    for k in range(10):
        e = _REF_PI.copy()
        e[k] += 1.0
        T[:, k] = f(e) - base
    return T


def _joint_bases(model, data, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint-frame bases ``(njoints, 10, nv, nv)`` of M (columns from the torque regressor,
    gravity off) and of the gravity stiffness (by differencing unit inertias)."""
    import pinocchio as pin

    nv = model.nv
    zero = np.zeros(nv)
    saved_gravity = model.gravity.linear.copy()
    model.gravity.linear = np.zeros(3)
    Mj = np.zeros((model.njoints, 10, nv, nv))
    for col in range(nv):
        a = np.zeros(nv)
        a[col] = 1.0
        Y = np.reshape(pin.computeJointTorqueRegressor(model, data, q0, zero, a), (nv, -1))
        for jid in range(1, model.njoints):
            Mj[jid, :, :, col] = Y[:, 10 * (jid - 1) : 10 * jid].T
    model.gravity.linear = saved_gravity
    Gj = np.zeros((model.njoints, 10, nv, nv))
    saved = [model.inertias[j].copy() for j in range(model.njoints)]
    for jid in range(1, model.njoints):
        model.inertias[jid] = pin.Inertia.FromDynamicParameters(_REF_PI)
        g0 = pin.computeGeneralizedGravityDerivatives(model, data, q0).copy()
        for k in range(10):
            e = _REF_PI.copy()
            e[k] += 1.0
            model.inertias[jid] = pin.Inertia.FromDynamicParameters(e)
            Gj[jid, k] = pin.computeGeneralizedGravityDerivatives(model, data, q0) - g0
        model.inertias[jid] = saved[jid]
    return Mj, Gj


def inertia_bases(
    model,  # pinocchio.Model
    q0: np.ndarray,
    placements: dict[str, tuple[int, object]],
    bodies: list[str],
    pi: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(M_basis, G_basis, M_rest, G_rest)``: the mass matrix and gravity stiffness at
    ``q0`` per inertial parameter of each body, ``(n_bodies, 10, nv, nv)``, and what is left
    of the full matrices ``(nv, nv)`` at the bodies' parameters ``pi`` ``(n_bodies, 10)``."""
    import pinocchio as pin

    nv = model.nv
    data = model.createData()
    Mj, Gj = _joint_bases(model, data, q0)
    M_basis = np.zeros((len(bodies), 10, nv, nv))
    G_basis = np.zeros((len(bodies), 10, nv, nv))
    for b, name in enumerate(bodies):
        jid, placement = placements[name]
        if jid == 0:
            continue
        T = _transport_matrix(placement)
        M_basis[b] = np.einsum("mk,mij->kij", T, Mj[jid])
        G_basis[b] = np.einsum("mk,mij->kij", T, Gj[jid])
    M_full = pin.crba(model, data, q0)
    M_full = np.triu(M_full) + np.triu(M_full, 1).T
    G_full = pin.computeGeneralizedGravityDerivatives(model, data, q0).copy()
    M_rest = M_full - np.einsum("bk,bkij->ij", pi, M_basis)
    G_rest = G_full - np.einsum("bk,bkij->ij", pi, G_basis)
    return M_basis, G_basis, M_rest, G_rest
