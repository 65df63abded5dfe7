"""The fit's model-level variables: transducer gains, point mixes and Rayleigh coefficients.

Each is one entry of the decision vector ``z`` (after the bodies and the joint parameters,
:mod:`.layout`):

* a transducer gain ``g = g₀ · e^z`` (log scale, the sign of ``g₀`` kept);
* a point mix ``μ = μ₀ + s · z`` with ``s = max(|μ₀|, 1)`` (a mix may change sign);
* a mimic multiplier ``a = a₀ + s · z`` with ``s = max(|a₀|, s_min)`` (it may change sign;
  ``s_min`` = :data:`MULTIPLIER_SCALE`, the size of a pivot's shift per radian);
* a Rayleigh coefficient ``α = s · z`` (``β = s · z``) with ``s`` its start, or, for a start
  at 0, the model's reference coefficient (:func:`bondid.linear.rayleigh.reference`): a zero
  start then moves off its bound by a fraction of a light damping, not of 1 s.

Their records are in :mod:`.variables`; :class:`ModelVars` gives :class:`~.layout.Layout`
the optional parts of the parameter-model protocol (:class:`bondid.cost.ParameterModel`):
``gain_values``/``gain_jacobian``, ``mix_values``/``mix_jacobian``,
``coupling_values``/``coupling_jacobian`` and ``rayleigh_values``/``rayleigh_jacobian``.
"""

from __future__ import annotations

import numpy as np

from ..linear.affine import AffineModel
from ..linear.parameter_map import RAYLEIGH_COMPONENTS
from .variables import GainVar, MixVar, RayleighVar

#: the smallest variable scale of a mimic multiplier: a free pivot (m/rad) starts at 0 and
#: moves by centimetres (a gear ratio is scaled by its own size)
MULTIPLIER_SCALE = 0.01


class ModelVars:
    """The model-level variables of a :class:`~.layout.Layout` (module docstring)."""

    size: int
    gains: list[GainVar]
    mixes: list[MixVar]
    #: the free mimic multipliers (``point`` holds the mimic joint's name)
    couplings: list[MixVar]
    rayleigh: list[RayleighVar]

    def _model_vars_of(self, affine: AffineModel) -> None:
        """Keep what the Rayleigh variables need of ``affine``: the coefficients that are
        not free, and the reference scales (when one is free)."""
        self.base_rayleigh = (affine.alpha, affine.beta, affine.eta)
        self.rayleigh_ref = (1.0, 1.0, 1.0)
        if self.rayleigh:
            from ..linear.rayleigh import reference

            self.rayleigh_ref = reference(affine)

    def _start_model_vars(self, p0: np.ndarray, z: np.ndarray) -> None:
        """Scales and ``z`` entries ``(size,)`` of the variables for named values ``p0``."""
        for gv in self.gains:
            gv.g0 = float(p0[gv.name_index])
            z[gv.index] = 0.0
        for mv in self.mixes:
            mv.mu0 = float(p0[mv.name_index])
            mv.scale = max(abs(mv.mu0), 1.0)
            z[mv.index] = 0.0
        for cv in self.couplings:
            cv.mu0 = float(p0[cv.name_index])
            cv.scale = max(abs(cv.mu0), MULTIPLIER_SCALE)
            z[cv.index] = 0.0
        for rv in self.rayleigh:
            v = float(p0[rv.name_index])
            ref = self.rayleigh_ref[RAYLEIGH_COMPONENTS.index(rv.component)]
            rv.scale = abs(v) if v != 0 else ref
            z[rv.index] = v / rv.scale

    def _named_model_vars(self, z: np.ndarray, out: np.ndarray) -> None:
        """Write the named values of the variables at ``z`` into ``out`` ``(n,)``."""
        for gv in self.gains:
            out[gv.name_index] = gv.g0 * float(np.exp(z[gv.index]))
        for mv in [*self.mixes, *self.couplings]:
            out[mv.name_index] = mv.mu0 + mv.scale * float(z[mv.index])
        for rv in self.rayleigh:
            out[rv.name_index] = rv.scale * float(z[rv.index])

    def _bound_model_vars(
        self, lower: np.ndarray, upper: np.ndarray, lbz: np.ndarray, ubz: np.ndarray
    ) -> list[tuple[str, int]]:
        """Set the bounds ``lbz``, ``ubz`` ``(size,)`` of the variables from the named bounds
        ``lower``, ``upper`` ``(n,)``; returns their labels ``(name, z index)``."""
        labels = []
        for gv in self.gains:
            r = sorted((lower[gv.name_index] / gv.g0, upper[gv.name_index] / gv.g0))
            lbz[gv.index] = np.log(r[0]) if r[0] > 0 else -np.inf
            ubz[gv.index] = np.log(r[1]) if r[1] > 0 and np.isfinite(r[1]) else np.inf
            labels.append((gv.name, gv.index))
        for mv in [*self.mixes, *self.couplings]:
            lbz[mv.index] = (lower[mv.name_index] - mv.mu0) / mv.scale
            ubz[mv.index] = (upper[mv.name_index] - mv.mu0) / mv.scale
            labels.append((mv.name, mv.index))
        for rv in self.rayleigh:
            lbz[rv.index] = lower[rv.name_index] / rv.scale
            ubz[rv.index] = upper[rv.name_index] / rv.scale
            labels.append((rv.name, rv.index))
        return labels

    # -- point mixes and mimic multipliers (optional parts of the protocol) -----------------
    @staticmethod
    def _linear_values(vs: list[MixVar], z: np.ndarray) -> dict[str, float]:
        """``μ₀ + s·z`` of the linear variables ``vs`` by owner (point or mimic joint)."""
        return {v.point: v.mu0 + v.scale * float(z[v.index]) for v in vs}

    def _linear_rows(self, vs: list[MixVar]) -> dict[str, np.ndarray]:
        """d value / d z ``(size,)`` of the linear variables ``vs`` by owner."""
        out = {}
        for v in vs:
            row = np.zeros(self.size)
            row[v.index] = v.scale
            out[v.point] = row
        return out

    def mix_values(self, z: np.ndarray) -> dict[str, float]:
        """Free mixes by point name at ``z``."""
        return self._linear_values(self.mixes, z)

    def mix_jacobian(self, z: np.ndarray) -> dict[str, np.ndarray]:
        """d μ / d z ``(size,)`` of every free mix."""
        return self._linear_rows(self.mixes)

    def coupling_values(self, z: np.ndarray) -> dict[str, float]:
        """Free multipliers by mimic joint at ``z``."""
        return self._linear_values(self.couplings, z)

    def coupling_jacobian(self, z: np.ndarray) -> dict[str, np.ndarray]:
        """d a / d z ``(size,)`` of every free multiplier."""
        return self._linear_rows(self.couplings)

    # -- transducer gains (the optional gain part of the parameter-model protocol) ----------
    def gain_values(self, z: np.ndarray) -> dict[str, float]:
        """Free gains by name at ``z``."""
        return {g.name: g.g0 * float(np.exp(z[g.index])) for g in self.gains}

    def gain_jacobian(self, z: np.ndarray) -> dict[str, np.ndarray]:
        """d g / d z ``(size,)`` of every free gain."""
        out = {}
        for g in self.gains:
            row = np.zeros(self.size)
            row[g.index] = g.g0 * float(np.exp(z[g.index]))
            out[g.name] = row
        return out

    # -- proportional damping (the optional Rayleigh part of the protocol) -------------------
    def rayleigh_values(self, z: np.ndarray) -> tuple[float, float, float] | None:
        """``(α (1/s), β (s), η)`` at ``z`` when one is free (the others the model's), else
        None."""
        if not self.rayleigh:
            return None
        ab = dict(zip(RAYLEIGH_COMPONENTS, self.base_rayleigh, strict=True))
        for rv in self.rayleigh:
            ab[rv.component] = rv.scale * float(z[rv.index])
        return ab["alpha"], ab["beta"], ab["eta"]

    def rayleigh_jacobian(self, z: np.ndarray) -> np.ndarray:
        """``d(α, β, η)/dz`` ``(3, size)``."""
        out = np.zeros((3, self.size))
        for rv in self.rayleigh:
            out[RAYLEIGH_COMPONENTS.index(rv.component), rv.index] = rv.scale
        return out
