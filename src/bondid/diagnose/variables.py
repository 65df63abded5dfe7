"""Refit variables of the diagnosis (:class:`Variable`) and those of the nominal parameters
(:func:`nominal_variables`): what the refit engine (:mod:`.engine`) varies and within which
bounds.

A variable ``v`` either sets named URDF parameters linearly (``URDF value = factor · v`` for
each of its ``members``) or is a parameter of an FRF modifier; it is refitted as ``ln v``
unless marked linear (CoM coordinates, products of inertia).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import ConfigError
from ..model.document import UrdfDocument
from ..model.parameters import get_parameter, parameter_infos


@dataclass(frozen=True)
class Variable:
    """One refit variable (see the module docstring).

    Attributes:
        name: readable name.
        initial, lower, upper: start and bounds (SI), ``0 < lower ≤ upper``.
        members: ``((URDF parameter name, factor), ...)``; empty for a modifier parameter.
        modifier: index into the modifier's parameter vector, or None.
        unit: SI unit text.
        log: refit on a log scale (default); False = linear (CoM, products of inertia), where
            ``lower`` may be ≤ 0.
    """

    name: str
    initial: float
    lower: float
    upper: float
    members: tuple[tuple[str, float], ...] = ()
    modifier: int | None = None
    unit: str = ""
    log: bool = True


def nominal_variables(
    doc: UrdfDocument, names: Sequence[str], reference: UrdfDocument | None = None
) -> list[Variable]:
    """Refit variables for named nominal parameters, starting at ``doc``'s values.

    Masses, joint stiffnesses and dampers with a positive value become one log-scaled variable
    each (bounds: mass ×/÷ 2, stiffness ×/÷ 3, damping ×/÷ 5); any inertia component of a link
    makes one variable scaling its principal moments (ixx, iyy, izz) together (×/÷ 2); CoM
    coordinates (± max(50 %, 1 cm)) and products of inertia (± max(50 %, 5 % of the mean
    moment)) named in ``names`` are linear variables. Zero-valued springs are left out.
    Bounds are taken around the values of ``reference`` (default ``doc``), so refits started
    from different points share one box.
    """
    ref = doc if reference is None else reference
    infos = {p.name: p for p in parameter_infos(doc)}
    out: list[Variable] = []
    scaled: list[str] = []
    for n in names:
        info = infos.get(n)
        if info is None:
            raise ConfigError(f"{doc.source or '<URDF>'}: unknown parameter {n!r}")
        if info.kind == "inertia":
            if info.owner not in scaled:
                scaled.append(info.owner)
            continue
        if info.kind == "com":
            v, c = get_parameter(doc, n), get_parameter(ref, n)
            half = max(0.5 * abs(c), COM_HALF_WIDTH)
            lo, hi = min(c - half, v), max(c + half, v)
            out.append(Variable(n, v, lo, hi, ((n, 1.0),), unit=info.unit, log=False))
            continue
        v, c = get_parameter(doc, n), get_parameter(ref, n)
        if v <= 0 or c <= 0 or not np.isfinite(v):
            continue
        f = {"mass": 2.0, "stiffness": 3.0, "damping": 5.0}[info.kind]
        lo, hi = min(c / f, v), max(c * f, v)
        out.append(Variable(n, v, lo, hi, ((n, 1.0),), unit=info.unit))
    for link in scaled:
        members = tuple(
            (f"{link}.inertia.{comp}", get_parameter(doc, f"{link}.inertia.{comp}"))
            for comp in ("ixx", "iyy", "izz")
        )
        out.append(Variable(f"{link}.inertia_scale", 1.0, 0.5, 2.0, members, unit="1"))
        mean = float(np.mean([abs(f) for _, f in members]))
        for comp in ("ixy", "ixz", "iyz"):
            n = f"{link}.inertia.{comp}"
            if n not in names:
                continue
            v, r = get_parameter(doc, n), get_parameter(ref, n)
            half = max(0.5 * abs(r), 0.05 * mean)
            lo, hi = min(r - half, v), max(r + half, v)
            out.append(Variable(n, v, lo, hi, ((n, 1.0),), unit="kg*m^2", log=False))
    return out


#: smallest half-width of the CoM bounds in the refit [m]
COM_HALF_WIDTH = 0.01
