"""The affine structure of the linearised dynamics in the physical parameters.

At a fixed configuration q0, Pinocchio's numbers enter as constants:

* ``M(π) = M_rest + Σ_b Σ_k π_bk · M_bk`` (mass matrix, exact: M is linear in π),
* ``G(π) = G_rest + Σ_b Σ_k π_bk · G_bk`` (gravity stiffness ∂g/∂q, linear in π too),
* ``K = G(π) + Σ_j k_j e_j e_jᵀ`` and ``D = D_rest + Σ_j d_j e_j e_jᵀ + α M(π) + β K`` (joint
  springs, dampers, and the model's proportional damping, :mod:`bondid.model.rayleigh`),

where ``π_b`` are the 10 dynamic parameters of link ``b`` in Pinocchio's order
``[m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]``, about the LINK frame origin and in
link-frame axes (not the joint frame: links merged into a joint by fixed joints keep their own
parameters). ``M_rest``/``G_rest`` hold what no parameterised link contributes. This is what
the fit and the sensitivities differentiate exactly.

A URDF ``floating`` joint (Pinocchio's free-flyer) makes a free-free structure: its six
velocity coordinates (``JOINT[vx]`` … ``JOINT[wz]``, body frame) have no spring, so the model
has rigid-body modes at 0 Hz; gravity is left out of such a model (the soft supports of a
free-free test carry the weight).

``<mimic>`` joints are coupled DOFs (:mod:`bondid.linear.mimic`): the model is reduced to
the independent coordinates, so ``dofs`` lists those only.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..consistency.pseudo_inertia import pi_from_urdf
from ..exceptions import ModelError
from ..model.document import UrdfDocument
from ..model.parameters import carries_mass, link_inertial
from ..model.rayleigh import model_rayleigh
from .bases import inertia_bases, link_placements
from .channels import channel_gains, io_matrices
from .channels import model_inputs as model_inputs  # re-exported: the model's channel names
from .channels import model_outputs as model_outputs
from .linear_model import LinearModel
from .mimic import (
    Coupled,
    Coupling,
    full_operating_point,
    mimic_couplings,
    reduce_matrices,
    reduction,
)
from .operating_point import configuration

#: pi_from_inertial is the consistency layer's map (mass, CoM, I about CoM) → π.
pi_from_inertial = pi_from_urdf

#: Velocity coordinates of a free-flyer (Pinocchio: linear then angular, in the body frame).
FREE_FLYER_AXES = ("vx", "vy", "vz", "wx", "wy", "wz")


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
        B: ``(nv, n_in)``; C: ``(n_out, nv)``: with the transducer gains applied,
            ``B = B_kin · diag(gain_in)``, ``C = diag(gain_out) · C_kin``.
        inputs, outputs: names of the inputs and outputs (joints or measurement points).
        q0: configuration ``(nq,)``; operating_point: the named joint values.
        B_kin, C_kin: the kinematic input / output matrices (joint selectors, and the frame
            Jacobian rows of measurement points).
        gain_in, gain_out: transducer gains ``(n_in,)``, ``(n_out,)`` (1 = none).
        alpha, beta: proportional damping ``α M + β K`` (1/s, s; 0 = none).
        eta: structural loss factor: the dynamic stiffness gets ``jη K`` (1; 0 = none).
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
    B_kin: np.ndarray | None = None
    C_kin: np.ndarray | None = None
    gain_in: np.ndarray | None = None
    gain_out: np.ndarray | None = None
    alpha: float = 0.0
    beta: float = 0.0
    eta: float = 0.0
    #: a model with ``<mimic>`` joints: its linearisation in every joint and the couplings
    #: (:class:`bondid.linear.mimic.Coupled`), so that a multiplier can be varied; None
    #: without mimic joints
    coupled: Any = None

    def __post_init__(self) -> None:
        if self.B_kin is None:
            self.B_kin = self.B.copy()
        if self.C_kin is None:
            self.C_kin = self.C.copy()
        if self.gain_in is None:
            self.gain_in = np.ones(self.B_kin.shape[1])
        if self.gain_out is None:
            self.gain_out = np.ones(self.C_kin.shape[0])

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

    def damping_matrix(
        self,
        damping: np.ndarray | None = None,
        pi: np.ndarray | None = None,
        stiffness: np.ndarray | None = None,
    ) -> np.ndarray:
        """D ``(nv, nv)`` = joint dampers + α M(π) + β K(π, k) (defaults: current values)."""
        d = self.damping if damping is None else damping
        D = self.D_rest + np.diag(d)
        if self.alpha:
            D = D + self.alpha * self.mass_matrix(pi)
        if self.beta:
            D = D + self.beta * self.stiffness_matrix(pi, stiffness)
        return D

    def loss_matrix(self, K: np.ndarray | None = None) -> np.ndarray | None:
        """The hysteretic stiffness ``η K`` ``(nv, nv)`` (``K``: the stiffness matrix, default
        the current one), or None without a loss factor."""
        if not self.eta:
            return None
        return self.eta * (self.stiffness_matrix() if K is None else K)

    def linear_model(self) -> LinearModel:
        """The numeric :class:`LinearModel` at the current parameters."""
        K = self.stiffness_matrix()
        return LinearModel(
            self.mass_matrix(),
            K,
            self.damping_matrix(),
            self.B.copy(),
            self.C.copy(),
            self.dofs,
            self.inputs,
            self.outputs,
            self.q0.copy(),
            self.loss_matrix(K),
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

    def with_rayleigh(self, alpha: float, beta: float, eta: float | None = None) -> AffineModel:
        """A copy with other proportional damping coefficients (1/s, s) and loss factor
        (None: this model's)."""
        eta = self.eta if eta is None else float(eta)
        return replace(self, alpha=float(alpha), beta=float(beta), eta=eta)

    def with_gains(
        self, gain_in: np.ndarray | None = None, gain_out: np.ndarray | None = None
    ) -> AffineModel:
        """A copy with other transducer gains (``(n_in,)``, ``(n_out,)``)."""
        assert self.B_kin is not None and self.C_kin is not None
        gi = self.gain_in if gain_in is None else np.asarray(gain_in, dtype=float)
        go = self.gain_out if gain_out is None else np.asarray(gain_out, dtype=float)
        assert gi is not None and go is not None
        return replace(
            self, B=self.B_kin * gi[None, :], C=go[:, None] * self.C_kin, gain_in=gi, gain_out=go
        )


def _dof_names(model, where: str) -> list[str]:
    """Name of each velocity coordinate: the joint's, ``JOINT[vx]``… for a free-flyer."""
    names = list(model.names)
    dofs: list[str] = [""] * model.nv
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        if jm.shortname() == "JointModelFreeFlyer":  # a URDF `floating` joint: free-free
            for k, axis in enumerate(FREE_FLYER_AXES):
                dofs[jm.idx_v + k] = f"{names[jid]}[{axis}]"
            continue
        if jm.nv != 1:
            raise ModelError(
                f"{where}: joint {names[jid]!r} has {jm.nv} DOF; bondid needs 1-DOF joints or"
                " one `floating` joint (a free-flyer)"
            )
        dofs[jm.idx_v] = names[jid]
    return dofs


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
        outputs: sensed joints or measurement points (default: the inputs — transmitted
            joints in transmission order, then the measurement points of ``doc``).

    Raises:
        ModelError: no inputs, unknown output, a multi-DOF joint, a point on an unknown
            frame, a gain on an unknown channel.
        OperatingPointError: the operating point names a joint the model lacks.
    """
    where = doc.source or "<URDF>"
    couplings = mimic_couplings(doc, where)
    model = doc.build_pinocchio_model()
    op = dict(operating_point or {})
    q0 = configuration(model, full_operating_point(op, couplings, where), where)
    nv = model.nv
    dofs = _dof_names(model, where)
    if any("[" in d for d in dofs):  # a free-free structure on soft supports: they carry
        model.gravity.linear = np.zeros(3)  # its weight
    B, C, inputs, outs = io_matrices(doc, model, q0, dofs, outputs)
    stiffness, damping = _springs_and_dampers(doc, dofs, where)
    grounded = doc.grounded_links()
    bodies = [lk.name for lk in doc.robot.links if carries_mass(lk) and lk.name not in grounded]
    placements = link_placements(model, bodies, where)
    pi = np.array([pi_from_urdf(*link_inertial(doc, b)) for b in bodies]).reshape(-1, 10)
    M_basis, G_basis, M_rest, G_rest = inertia_bases(model, q0, placements, bodies, pi)
    full = AffineModel(
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
    am = reduce_mimic(full, couplings) if couplings else full
    r = model_rayleigh(doc)
    if r is not None:
        am = am.with_rayleigh(r.alpha, r.beta, r.loss)
    return am.with_gains(*channel_gains(doc, inputs, outs))


def _springs_and_dampers(
    doc: UrdfDocument, dofs: list[str], where: str
) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and damping per velocity DOF ``(nv,)`` from the URDF's springs and dampers."""
    stiffness = np.zeros(len(dofs))
    damping = np.zeros(len(dofs))

    def v_index(joint: str, role: str) -> int:
        if joint not in dofs:
            raise ModelError(
                f"{where}: {role} joint {joint!r} is not a movable joint;"
                f" movable: {', '.join(dofs)}"
            )
        return dofs.index(joint)

    for j in doc.movable_joint_names:
        stiffness[v_index(j, "spring")] = doc.stiffness(j)
        damping[v_index(j, "damper")] = doc.damping(j)
    return stiffness, damping


def reduce_mimic(am: AffineModel, couplings: Mapping[str, Coupling]) -> AffineModel:
    """The model ``am`` (every joint free, no gains) in the independent coordinates of
    ``couplings`` (see :mod:`bondid.linear.mimic`); it keeps ``am`` and ``couplings`` in
    :attr:`AffineModel.coupled` (a multiplier may then be varied,
    :mod:`bondid.linear.coupling`)."""

    T, red = reduction(am.dofs, couplings)
    free = np.array([d not in couplings for d in am.dofs])
    fixed_k = np.diag(np.where(free, 0.0, am.stiffness))  # mimic joints' own springs
    fixed_d = np.diag(np.where(free, 0.0, am.damping))
    r = reduce_matrices(
        T,
        {"Mb": am.M_basis, "Gb": am.G_basis, "M": am.M_rest, "G": am.G_rest + fixed_k,
         "D": am.D_rest + fixed_d},
    )  # fmt: skip
    return AffineModel(
        dofs=red, bodies=am.bodies, pi=am.pi, M_basis=r["Mb"], G_basis=r["Gb"],
        M_rest=r["M"], G_rest=r["G"], D_rest=r["D"], stiffness=am.stiffness[free],
        damping=am.damping[free], B=T.T @ am.B, C=am.C @ T, inputs=am.inputs,
        outputs=am.outputs, q0=am.q0, operating_point=am.operating_point,
        coupled=Coupled(am, dict(couplings)),
    )  # fmt: skip


def linearise(
    doc: UrdfDocument,
    operating_point: Mapping[str, float] | None = None,
    *,
    outputs: tuple[str, ...] | None = None,
) -> LinearModel:
    """The numeric :class:`LinearModel` of ``doc`` at ``operating_point``."""
    return build_affine_model(doc, operating_point, outputs=outputs).linear_model()
