"""Named parameters with ties, and the model document at a fit's solution.

A *tie* drives parameters that are not fitted on their own by a free one:
``{leader: [(member, factor), ...]}`` sets ``member = factor · leader`` (e.g. one shear
stiffness for every segment of a lumped chain a diagnosis candidate adds). Leader and members
are of one kind (:data:`bondid.model.ties.TIEABLE`): joint ``stiffness`` or ``damping``, or a
link's ``mass``, CoM component or inertia component. Ties declared in the model (``--tie``, a
study's ``[ties]``: :mod:`bondid.model.ties`) join the ones a caller gives
(:func:`check_ties`), so every fit of the model keeps them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..exceptions import ConfigError
from ..linear.affine import AffineModel
from ..linear.parameter_map import ParameterMap
from ..model.document import UrdfDocument
from ..model.parameters import COM_AXES, parameter_infos, set_link_inertial, set_parameter
from ..model.ties import TIEABLE as _TIEABLE
from ..model.ties import leader_ties, model_ties
from .layout import Layout
from .variables import _IJ


def check_ties(
    doc: UrdfDocument, names: Sequence[str], ties: Mapping[str, Sequence[tuple[str, float]]]
) -> dict[str, list[tuple[str, float]]]:
    """Validated ties (see the module docstring) as a plain dict: ``ties`` and those the
    model declares over ``names`` (:func:`bondid.model.ties.leader_ties`; a leader given in
    ``ties`` replaces the model's entry for it).

    Raises:
        ConfigError: a leader not among ``names``, a member that is free or tied twice, a
            parameter of a kind that cannot be tied or of another kind than its leader, or a
            factor that is not finite and > 0.
        ModelError: two members of a tie the model declares are both free.
    """
    infos = {p.name: p for p in parameter_infos(doc)}
    out: dict[str, list[tuple[str, float]]] = {}
    seen: set[str] = set()
    for leader, members in {**leader_ties(model_ties(doc), names), **ties}.items():
        if leader not in names:
            raise ConfigError(f"tie {leader!r}: the leader must be one of the free parameters")
        key = infos[leader].component_key if leader in infos else None
        for name in [leader, *(m for m, _ in members)]:
            p = infos.get(name)
            if p is None or p.kind not in _TIEABLE or p.component_key != key:
                raise ConfigError(
                    f"tie {leader!r}: {name!r} is not a parameter of"
                    f" {doc.source or '<URDF>'} of the leader's kind ({key}); a tie holds"
                    f" one kind of {', '.join(_TIEABLE)}"
                )
        for member, factor in members:
            if member in names or member in seen:
                raise ConfigError(f"tie {leader!r}: {member!r} is free or tied twice")
            if not (np.isfinite(factor) and factor > 0):
                raise ConfigError(f"tie {leader!r}: factor {factor!r} of {member}; give > 0")
            seen.add(member)
        out[leader] = [(m, float(f)) for m, f in members]
    return out


class TiedParameters:
    """A parameter model (:class:`bondid.cost.ParameterModel`) over the free named
    parameters ``x`` ``(n,)``, the tied members following their leaders.

    Args:
        doc, affine: as for :class:`~bondid.linear.parameter_map.ParameterMap`.
        names: the free parameters ``(n,)``.
        ties: validated ties (:func:`check_ties`).
    """

    def __init__(
        self,
        doc: UrdfDocument,
        affine: AffineModel,
        names: Sequence[str],
        ties: Mapping[str, Sequence[tuple[str, float]]],
    ):
        names = list(names)
        members = [(m, names.index(lead), f) for lead, ms in ties.items() for m, f in ms]
        self.names = tuple(names)
        self.map = ParameterMap(doc, affine, [*names, *(m for m, _, _ in members)])
        self.T = np.vstack([np.eye(len(names)), np.zeros((len(members), len(names)))])
        for row, (_, col, factor) in enumerate(members, start=len(names)):
            self.T[row, col] = factor

    @property
    def size(self) -> int:
        return len(self.names)

    def values(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(π ``(nb, 10)``, stiffness ``(nv,)``, damping ``(nv,)``) at ``x``."""
        return self.map.values(self.T @ np.asarray(x, dtype=float))

    def jacobian(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """dπ/dx ``(nb, 10, n)``, dk/dx ``(nv, n)``, dd/dx ``(nv, n)``."""
        dpi, dk, dd = self.map.jacobian(self.T @ np.asarray(x, dtype=float))
        return dpi @ self.T, dk @ self.T, dd @ self.T

    def gain_values(self, x: np.ndarray) -> dict[str, float]:
        return self.map.gain_values(self.T @ np.asarray(x, dtype=float))

    def gain_jacobian(self, x: np.ndarray) -> dict[str, np.ndarray]:
        jac = self.map.gain_jacobian(self.T @ np.asarray(x, dtype=float))
        return {k: v @ self.T for k, v in jac.items()}

    def mix_values(self, x: np.ndarray) -> dict[str, float]:
        return self.map.mix_values(self.T @ np.asarray(x, dtype=float))

    def mix_jacobian(self, x: np.ndarray) -> dict[str, np.ndarray]:
        jac = self.map.mix_jacobian(self.T @ np.asarray(x, dtype=float))
        return {k: v @ self.T for k, v in jac.items()}

    def coupling_values(self, x: np.ndarray) -> dict[str, float]:
        return self.map.coupling_values(self.T @ np.asarray(x, dtype=float))

    def coupling_jacobian(self, x: np.ndarray) -> dict[str, np.ndarray]:
        jac = self.map.coupling_jacobian(self.T @ np.asarray(x, dtype=float))
        return {k: v @ self.T for k, v in jac.items()}

    def rayleigh_values(self, x: np.ndarray) -> tuple[float, float, float] | None:
        return self.map.rayleigh_values(self.T @ np.asarray(x, dtype=float))

    def rayleigh_jacobian(self, x: np.ndarray) -> np.ndarray:
        """``d(α, β)/dx`` ``(2, n)``."""
        return self.map.rayleigh_jacobian(self.T @ np.asarray(x, dtype=float)) @ self.T


def fitted_document(
    doc: UrdfDocument, layout: Layout, z: np.ndarray, p: np.ndarray
) -> UrdfDocument:
    """A copy of ``doc`` with the fitted bodies at ``z`` and the joint parameters, gains,
    mixes, multipliers and Rayleigh coefficients ``p`` (named values ``(n,)``; tied members
    follow ``z``). Fixed inertial components keep their exact URDF values."""
    out = doc.copy()
    for link, vals in layout.body_values(z).items():
        blk = next(b for b in layout.blocks if b.link == link)
        vals = {**vals, **blk.fixed}
        c = np.array([vals[f"com.{a}"] for a in COM_AXES])
        I_c = np.zeros((3, 3))
        for comp, (r, s) in _IJ.items():
            I_c[r, s] = I_c[s, r] = vals[f"inertia.{comp}"]
        set_link_inertial(out, link, vals["mass"], c, I_c)
    for jv in layout.joints:
        v = p[jv.name_index] if jv.name_index >= 0 else jv.scale * z[jv.index]
        set_parameter(out, jv.name, max(float(v), 0.0))
    for gv in layout.gains:
        set_parameter(out, gv.name, float(p[gv.name_index]))
    for mv in [*layout.mixes, *layout.couplings]:
        set_parameter(out, mv.name, float(p[mv.name_index]))
    for rv in layout.rayleigh:
        set_parameter(out, rv.name, max(float(p[rv.name_index]), 0.0))
    return out
