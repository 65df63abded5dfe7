"""The entries of the fit's decision vector ``z`` (:class:`~.layout.Layout` holds them in order).

* :class:`BodyBlock`: one fitted body's 10 entries ``z_b``, with ``ζ_b = shift_b + scale_b ∘
  z_b`` the log-Cholesky coordinates ``(α, δ₁, δ₂, δ₃, σ₁₂, σ₂₃, σ₁₃, t₁, t₂, t₃)`` and
  ``θ`` of :mod:`bondid.consistency.log_cholesky` (``δᵢ = α + dᵢ``, ``σ = e^α s``);
* :class:`JointVar`: a free ``JOINT.stiffness`` / ``JOINT.damping``, ``p = scale · z``;
* :class:`GainVar`: a free transducer gain, ``g = g₀ · e^z``;
* :class:`MixVar`: a free point mix, ``μ = μ₀ + scale · z``;
* :class:`RayleighVar`: a free Rayleigh coefficient, ``α = scale · z`` (``β`` alike).

The index tables say where each URDF component sits in ``θ``, ``ζ`` and the inertia matrix,
for the layout's maps and for the constraint expressions (:mod:`.constraints`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..consistency.hull import Hull
from ..consistency.pseudo_inertia import urdf_from_pi
from ..model.parameters import COM_AXES, INERTIA_COMPONENTS

# (row, col) of each URDF inertia component
_IJ = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}
_ALPHA, _T = 0, 7  # index of α and of t₁ in θ and ζ
_DIAG = (1, 2, 3)  # δ (ζ) / d (θ)
_OFF = ((4, 0, 1), (5, 1, 2), (6, 0, 2))  # σ₁₂, σ₂₃, σ₁₃ (ζ index, row, col of V)


@dataclass
class BodyBlock:
    """One fitted body: where its θ lives in ``z`` and which named parameters are free."""

    link: str
    body: int  # index in AffineModel.bodies
    offset: int  # first index in z
    shift: np.ndarray  # (10,)
    scale: np.ndarray  # (10,)
    length: float  # L, m
    inertia_scale: float  # kg·m², for scaling inertia constraints
    hull: Hull | None
    free: dict[str, int] = field(default_factory=dict)  # component -> index in names
    fixed: dict[str, float] = field(default_factory=dict)  # component -> URDF value
    # component -> (its leader's index in names, factor): a tied member, held equal to
    # factor · the leader's value by an equality constraint (:mod:`.constraints`)
    tied: dict[str, tuple[int, float]] = field(default_factory=dict)
    fixed_v: np.ndarray | None = None  # z of δ, σ when no inertia component is free

    def zeta(self, z: np.ndarray) -> np.ndarray:
        return self.shift + self.scale * z[self.offset : self.offset + 10]

    def theta(self, z: np.ndarray) -> np.ndarray:
        """Log-Cholesky θ (10,) of this body at ``z``."""
        ze = self.zeta(z)
        th = ze.copy()
        th[1:4] = ze[1:4] - ze[0]
        th[4:7] = ze[4:7] * np.exp(-ze[0])
        return th

    def dtheta_dz(self, z: np.ndarray) -> np.ndarray:
        """∂θ/∂z_b (10, 10)."""
        ze = self.zeta(z)
        D = np.eye(10)
        D[1:4, 0] = -1.0
        e = np.exp(-ze[0])
        D[4:7, 4:7] *= e
        D[4:7, 0] = -ze[4:7] * e
        return D * self.scale


@dataclass
class JointVar:
    name: str
    kind: str  # stiffness / damping
    dof: int  # index into the affine model's velocity coordinates
    index: int  # index in z
    name_index: int  # index in names (-1: a tied member, not a free name)
    scale: float
    factor: float = 1.0  # a tied member: value = factor · its leader's value
    leader: int = -1  # a tied member: its leader's position in Layout.joints


@dataclass
class GainVar:
    """A free transducer gain: ``g = g0 · e^z`` (log scale, the sign of ``g0`` kept)."""

    name: str
    index: int  # index in z
    name_index: int  # index in names
    g0: float = 1.0


@dataclass
class MixVar:
    """A free point mix (:mod:`bondid.cost.mixing`): ``μ = μ₀ + s · z``."""

    name: str  # mix.<point>
    point: str
    index: int  # index in z
    name_index: int  # index in names
    mu0: float = 0.0
    scale: float = 1.0


def named_from_pi(pi: np.ndarray) -> dict[str, float]:
    """URDF-form values ``{component: value}`` of one body's ``pi`` (10,)."""
    m, c, I_c = urdf_from_pi(pi)
    out = {"mass": m}
    out.update({f"com.{a}": float(c[k]) for k, a in enumerate(COM_AXES)})
    out.update({f"inertia.{n}": float(I_c[_IJ[n]]) for n in INERTIA_COMPONENTS})
    return out


@dataclass
class RayleighVar:
    """A free proportional-damping coefficient (``component`` ``alpha``, ``beta`` or ``eta``):
    value ``= s · z``."""

    name: str  # rayleigh.alpha / rayleigh.beta / rayleigh.eta
    component: str
    index: int  # index in z
    name_index: int  # index in names
    scale: float = 1.0
