"""The affine structure of the linearised dynamics in the physical parameters.

At a fixed configuration q0, Pinocchio's numbers enter as constants:

* ``M(π) = M_rest + Σ_b Σ_k π_bk · M_bk`` (mass matrix, exact: M is linear in π),
* ``G(π) = G_rest + Σ_b Σ_k π_bk · G_bk`` (gravity stiffness ∂g/∂q, linear in π too),
* ``K = G(π) + Σ_j k_j e_j e_jᵀ`` and ``D = D_rest + Σ_j d_j e_j e_jᵀ`` (joint springs, dampers),

where ``π_b`` are the 10 dynamic parameters of link ``b`` in Pinocchio's order
``[m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]``, about the LINK frame origin and in
link-frame axes (not the joint frame: links merged into a joint by fixed joints keep their own
parameters). ``M_rest``/``G_rest`` hold what no parameterised link contributes. This is what
the fit and the sensitivities differentiate exactly.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from ..consistency.pseudo_inertia import pi_from_urdf
from ..exceptions import ModelError
from ..model.document import UrdfDocument
from ..model.parameters import link_inertial
from .linear_model import LinearModel
from .operating_point import configuration

#: pi_from_inertial is the consistency layer's map (mass, CoM, I about CoM) → π.
pi_from_inertial = pi_from_urdf

_REF_PI = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0])


@dataclass
class AffineModel:
    """Affine parameterisation of ``(M, K, D)`` at one operating point.

    Attributes:
        dofs: joint name per velocity coordinate, length ``nv``.
        bodies: parameterised link names, length ``nb``.
        pi: dynamic parameters per body, ``(nb, 10)``.
        M_basis, G_basis: ``(nb, 10, nv, nv)`` basis matrices.
        M_rest, G_rest, D_rest: ``(nv, nv)``.
        stiffness, damping: per velocity coordinate, ``(nv,)`` (joint springs, dampers).
        B: ``(nv, n_in)``; C: ``(n_out, nv)``.
        inputs, outputs: joint names of the inputs and outputs.
        q0: configuration ``(nq,)``; operating_point: the named joint values.
    """

    dofs: tuple[str, ...]
    bodies: tuple[str, ...]
    pi: np.ndarray
    M_basis: np.ndarray
    G_basis: np.ndarray
    M_rest: np.ndarray
    G_rest: np.ndarray
    D_rest: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    B: np.ndarray
    C: np.ndarray
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    q0: np.ndarray
    operating_point: dict[str, float]

    @property
    def nv(self) -> int:
        return len(self.dofs)

    def mass_matrix(self, pi: np.ndarray | None = None) -> np.ndarray:
        """M ``(nv, nv)`` for body parameters ``pi`` ``(nb, 10)`` (default: current)."""
        p = self.pi if pi is None else pi
        return self.M_rest + np.einsum("bk,bkij->ij", p, self.M_basis)

    def stiffness_matrix(
        self, pi: np.ndarray | None = None, stiffness: np.ndarray | None = None
    ) -> np.ndarray:
        """K ``(nv, nv)`` = gravity stiffness(π) + diag(joint springs)."""
        p = self.pi if pi is None else pi
        k = self.stiffness if stiffness is None else stiffness
        return self.G_rest + np.einsum("bk,bkij->ij", p, self.G_basis) + np.diag(k)

    def damping_matrix(self, damping: np.ndarray | None = None) -> np.ndarray:
        d = self.damping if damping is None else damping
        return self.D_rest + np.diag(d)

    def linear_model(self) -> LinearModel:
        """The numeric :class:`LinearModel` at the current parameters."""
        return LinearModel(
            self.mass_matrix(),
            self.stiffness_matrix(),
            self.damping_matrix(),
            self.B.copy(),
            self.C.copy(),
            self.dofs,
            self.inputs,
            self.outputs,
            self.q0.copy(),
        )

    def with_values(
        self,
        pi: np.ndarray | None = None,
        stiffness: np.ndarray | None = None,
        damping: np.ndarray | None = None,
    ) -> AffineModel:
        """A copy with other parameter values (the bases are shared, not copied)."""
        return replace(
            self,
            pi=self.pi if pi is None else np.asarray(pi, dtype=float),
            stiffness=self.stiffness if stiffness is None else np.asarray(stiffness, float),
            damping=self.damping if damping is None else np.asarray(damping, float),
        )


def _link_placements(model, links: list[str], where: str) -> dict[str, tuple[int, object]]:
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


def build_affine_model(
    doc: UrdfDocument,
    operating_point: Mapping[str, float] | None = None,
    *,
    outputs: tuple[str, ...] | None = None,
) -> AffineModel:
    """Linearise ``doc`` at ``operating_point`` and expose the affine parameter structure.

    Args:
        doc: the model.
        operating_point: joint positions (m or rad) by name; others at neutral.
        outputs: sensed joints (default: the transmitted joints, in transmission order).

    Raises:
        ModelError: no transmissions, unknown output joint, a multi-DOF joint.
        OperatingPointError: the operating point names a joint the model lacks.
    """
    import pinocchio as pin

    where = doc.source or "<URDF>"
    model = doc.build_pinocchio_model()
    op = dict(operating_point or {})
    q0 = configuration(model, op, where)
    nv = model.nv
    names = list(model.names)
    dofs: list[str] = [""] * nv
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        if jm.nv != 1:
            raise ModelError(
                f"{where}: joint {names[jid]!r} has {jm.nv} DOF; bondid needs 1-DOF joints"
            )
        dofs[jm.idx_v] = names[jid]

    def v_index(joint: str, role: str) -> int:
        if joint not in dofs:
            raise ModelError(
                f"{where}: {role} joint {joint!r} is not a movable joint;"
                f" movable: {', '.join(dofs)}"
            )
        return dofs.index(joint)

    inputs = tuple(t.joint for t in doc.transmissions)
    if not inputs:
        raise ModelError(f"{where}: no <transmission> elements, so the model has no FRF inputs")
    outs = tuple(outputs) if outputs is not None else inputs
    B = np.zeros((nv, len(inputs)))
    for i, j in enumerate(inputs):
        B[v_index(j, "transmission"), i] = 1.0
    C = np.zeros((len(outs), nv))
    for i, j in enumerate(outs):
        C[i, v_index(j, "output")] = 1.0

    stiffness = np.zeros(nv)
    damping = np.zeros(nv)
    for j in doc.movable_joint_names:
        stiffness[v_index(j, "spring")] = doc.stiffness(j)
        damping[v_index(j, "damper")] = doc.damping(j)

    grounded = doc.grounded_links()
    bodies = [
        lk.name for lk in doc.robot.links if lk.inertial is not None and lk.name not in grounded
    ]
    placements = _link_placements(model, bodies, where)
    pi = np.array([pi_from_urdf(*link_inertial(doc, b)) for b in bodies]).reshape(-1, 10)

    # joint-frame bases: M columns from the torque regressor (gravity off), G by differencing
    data = model.createData()
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

    nb = len(bodies)
    M_basis = np.zeros((nb, 10, nv, nv))
    G_basis = np.zeros((nb, 10, nv, nv))
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
    return AffineModel(
        dofs=tuple(dofs),
        bodies=tuple(bodies),
        pi=pi,
        M_basis=M_basis,
        G_basis=G_basis,
        M_rest=M_rest,
        G_rest=G_rest,
        D_rest=np.zeros((nv, nv)),
        stiffness=stiffness,
        damping=damping,
        B=B,
        C=C,
        inputs=inputs,
        outputs=outs,
        q0=q0,
        operating_point=op,
    )


def linearise(
    doc: UrdfDocument,
    operating_point: Mapping[str, float] | None = None,
    *,
    outputs: tuple[str, ...] | None = None,
) -> LinearModel:
    """The numeric :class:`LinearModel` of ``doc`` at ``operating_point``."""
    return build_affine_model(doc, operating_point, outputs=outputs).linear_model()
