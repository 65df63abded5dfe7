"""Named parameters (URDF form) → the values of an :class:`AffineModel`, with the Jacobian.

A parameter vector ``p`` holds a chosen subset of the named parameters (``x_stage.mass``,
``x_guide_rx.stiffness``, ...). The map to the affine model's values is

* link parameters (mass m, CoM c, inertia about the CoM I_c) → π = [m, m·c, I_c + m(|c|²𝟙 − ccᵀ)]
  (non-linear in (m, c), affine in I_c),
* ``JOINT.stiffness`` / ``JOINT.damping`` → the spring / damper of that coordinate (identity),
* ``gain.in.X`` / ``gain.out.Y`` and ``mix.P`` → the transducer gains and the points' mixes
  (:meth:`ParameterMap.gain_values`, :meth:`ParameterMap.mix_values`),
* ``rayleigh.alpha`` / ``rayleigh.beta`` / ``rayleigh.eta`` → the proportional damping
  ``α M + β K`` and the loss factor of ``K`` (:meth:`ParameterMap.rayleigh_values`),
* ``JOINT.multiplier`` → a mimic joint's multiplier (:meth:`ParameterMap.coupling_values`,
  :mod:`.coupling`).

:meth:`ParameterMap.jacobian` gives the exact derivatives, so dH/dp follows by the chain rule.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..consistency.pseudo_inertia import pi_from_urdf, urdf_from_pi
from ..exceptions import ParameterError
from ..model.document import UrdfDocument
from ..model.parameters import COM_AXES, INERTIA_ENTRY, get_parameters, parameter_infos
from ..model.rayleigh import RAYLEIGH_UNITS
from .affine import AffineModel

#: parameter kinds that act on the model as a whole, not on π or a joint's spring/damper
_MODEL_LEVEL = ("gain", "mix", "rayleigh", "multiplier")
#: the proportional-damping coefficients in the order of ``rayleigh_values``
RAYLEIGH_COMPONENTS = tuple(RAYLEIGH_UNITS)
# position of each URDF inertia component in Pinocchio's π (Ixx, Ixy, Iyy, Ixz, Iyz, Izz)
_PI_SLOT = {"ixx": 4, "ixy": 5, "iyy": 6, "ixz": 7, "iyz": 8, "izz": 9}


@dataclass(frozen=True)
class _Slot:
    kind: str  # mass / com / inertia / stiffness / damping
    index: int  # body index or dof index
    component: str | None


class ParameterMap:
    """Map a vector of named parameters onto an :class:`AffineModel` (same for every pose).

    Args:
        doc: the model the parameters are named in.
        affine: any :class:`AffineModel` of ``doc`` (its ``bodies`` and ``dofs`` are used).
        names: the free parameters, in vector order.
    """

    def __init__(self, doc: UrdfDocument, affine: AffineModel, names: Sequence[str]):
        infos = {p.name: p for p in parameter_infos(doc)}
        self.names: tuple[str, ...] = tuple(names)
        self.slots: list[_Slot] = []
        for n in self.names:
            info = infos.get(n)
            if info is None:
                raise ParameterError(
                    f"{doc.source or '<URDF>'}: unknown parameter {n!r}; see parameter_names()"
                )
            if info.kind in _MODEL_LEVEL:
                comp = {"gain": info.name, "mix": info.owner, "multiplier": info.owner}.get(
                    info.kind, info.component
                )
                self.slots.append(_Slot(info.kind, -1, comp))
            elif info.is_inertial:
                if info.owner not in affine.bodies:
                    raise ParameterError(
                        f"{n}: link {info.owner!r} does not move; its inertia has no effect"
                    )
                self.slots.append(_Slot(info.kind, affine.bodies.index(info.owner), info.component))
            else:
                self.slots.append(_Slot(info.kind, affine.dofs.index(info.owner), None))
        self.base_pi = affine.pi.copy()
        self.base_stiffness = affine.stiffness.copy()
        self.base_damping = affine.damping.copy()
        self.base_rayleigh = (affine.alpha, affine.beta, affine.eta)
        self.p0 = get_parameters(doc, self.names)
        self.nb = len(affine.bodies)
        self.nv = affine.nv

    @property
    def size(self) -> int:
        return len(self.names)

    def _of_kind(self, kind: str, p: np.ndarray) -> dict[str, float]:
        """The free parameters of ``kind`` by their component (a gain's, a point's or a mimic
        joint's name) at ``p``: model-level parameters are their own values."""
        return {
            str(s.component): float(v)
            for s, v in zip(self.slots, np.asarray(p, dtype=float), strict=True)
            if s.kind == kind
        }

    def _rows_of_kind(self, kind: str) -> dict[str, np.ndarray]:
        """d value / d p ``(size,)`` of every free parameter of ``kind`` (a unit row)."""
        return {
            str(s.component): np.eye(self.size)[col]
            for col, s in enumerate(self.slots)
            if s.kind == kind
        }

    def gain_values(self, p: np.ndarray) -> dict[str, float]:
        """Free transducer gains by name (the gain part of the parameter-model protocol)."""
        return self._of_kind("gain", p)

    def gain_jacobian(self, p: np.ndarray) -> dict[str, np.ndarray]:
        """d g / d p ``(size,)`` of every free gain (a unit row: gains are parameters)."""
        return self._rows_of_kind("gain")

    def mix_values(self, p: np.ndarray) -> dict[str, float]:
        """Free mixes by point name (the mix part of the parameter-model protocol,
        :mod:`bondid.cost.mixing`)."""
        return self._of_kind("mix", p)

    def mix_jacobian(self, p: np.ndarray) -> dict[str, np.ndarray]:
        """d μ / d p ``(size,)`` of every free mix (a unit row)."""
        return self._rows_of_kind("mix")

    def coupling_values(self, p: np.ndarray) -> dict[str, float]:
        """Free mimic multipliers by joint name (the coupling part of the parameter-model
        protocol, :mod:`.coupling`)."""
        return self._of_kind("multiplier", p)

    def coupling_jacobian(self, p: np.ndarray) -> dict[str, np.ndarray]:
        """d a / d p ``(size,)`` of every free multiplier (a unit row)."""
        return self._rows_of_kind("multiplier")

    def rayleigh_values(self, p: np.ndarray) -> tuple[float, float, float] | None:
        """``(α (1/s), β (s), η)`` at ``p`` when one of them is free, else None (the
        proportional-damping part of the parameter-model protocol, :mod:`bondid.cost.problem`)."""
        ab = dict(zip(RAYLEIGH_COMPONENTS, self.base_rayleigh, strict=True))
        free = False
        for s, v in zip(self.slots, np.asarray(p, dtype=float), strict=True):
            if s.kind == "rayleigh":
                ab[str(s.component)], free = float(v), True
        return (ab["alpha"], ab["beta"], ab["eta"]) if free else None

    def rayleigh_jacobian(self, p: np.ndarray) -> np.ndarray:
        """``d(α, β, η)/dp`` ``(3, size)`` (unit rows: the coefficients are parameters)."""
        out = np.zeros((3, self.size))
        for col, s in enumerate(self.slots):
            if s.kind == "rayleigh":
                out[RAYLEIGH_COMPONENTS.index(str(s.component)), col] = 1.0
        return out

    def _inertials(self, p: np.ndarray) -> list[tuple[float, np.ndarray, np.ndarray]]:
        inert = [
            urdf_from_pi(pi) if pi[0] > 0 else (0.0, np.zeros(3), np.zeros((3, 3)))
            for pi in self.base_pi
        ]
        for s, v in zip(self.slots, p, strict=True):
            if s.kind == "mass":
                _, c, I = inert[s.index]
                inert[s.index] = (float(v), c, I)
            elif s.kind == "com":
                inert[s.index][1][COM_AXES.index(str(s.component))] = v
            elif s.kind == "inertia":
                r, q = INERTIA_ENTRY[str(s.component)]
                inert[s.index][2][r, q] = inert[s.index][2][q, r] = v
        return inert

    def values(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(π ``(nb, 10)``, stiffness ``(nv,)``, damping ``(nv,)``) for parameters ``p``."""
        p = np.asarray(p, dtype=float)
        inert = self._inertials(p)
        touched = {s.index for s in self.slots if s.kind in ("mass", "com", "inertia")}
        pi = self.base_pi.copy()
        for b in touched:
            pi[b] = pi_from_urdf(*inert[b])
        k = self.base_stiffness.copy()
        d = self.base_damping.copy()
        for s, v in zip(self.slots, p, strict=True):
            if s.kind == "stiffness":
                k[s.index] = v
            elif s.kind == "damping":
                d[s.index] = v
        return pi, k, d

    def jacobian(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact derivatives: dπ/dp ``(nb, 10, n_p)``, dk/dp ``(nv, n_p)``, dd/dp ``(nv, n_p)``."""
        p = np.asarray(p, dtype=float)
        inert = self._inertials(p)
        dpi = np.zeros((self.nb, 10, self.size))
        dk = np.zeros((self.nv, self.size))
        dd = np.zeros((self.nv, self.size))
        for col, s in enumerate(self.slots):
            if s.kind in _MODEL_LEVEL:
                continue
            if s.kind == "stiffness":
                dk[s.index, col] = 1.0
                continue
            if s.kind == "damping":
                dd[s.index, col] = 1.0
                continue
            m, c, _ = inert[s.index]
            g = np.zeros(10)
            if s.kind == "mass":
                S = c @ c * np.eye(3) - np.outer(c, c)
                g[0] = 1.0
                g[1:4] = c
                g[4:] = [S[0, 0], S[0, 1], S[1, 1], S[0, 2], S[1, 2], S[2, 2]]
            elif s.kind == "com":
                a = COM_AXES.index(str(s.component))
                e = np.zeros(3)
                e[a] = 1.0
                S = m * (2 * c[a] * np.eye(3) - np.outer(e, c) - np.outer(c, e))
                g[1 + a] = m
                g[4:] = [S[0, 0], S[0, 1], S[1, 1], S[0, 2], S[1, 2], S[2, 2]]
            else:
                g[_PI_SLOT[str(s.component)]] = 1.0
            dpi[s.index, :, col] = g
        return dpi, dk, dd
