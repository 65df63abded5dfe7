"""Proportional damping of a model: ``D = D_joints + α·M + β·K``, and a structural loss factor.

Besides one viscous damper per joint, a model may carry *proportional* damping: the
mass-proportional coefficient ``α`` (1/s) and the stiffness-proportional coefficient ``β``
(s), added to the joint dampers. ``M`` is the mass matrix and ``K`` the whole stiffness
matrix (joint springs and gravity stiffness) at the operating point, so a mode of natural
angular frequency ``ω`` gets the damping ratio ``α/(2ω) + βω/2`` on top of what the joint
dampers give it. It is a URDF extension element that other URDF readers ignore, so every
command and every copy of the model (``fitted.urdf`` too) sees it::

    <rayleigh_damping alpha="0.8" beta="2.5e-06"/>

Its two coefficients are the model parameters ``rayleigh.alpha`` and ``rayleigh.beta``
(:mod:`bondid.model.parameters`); a model without the element has neither (α = β = 0).

The element may also carry a *structural loss factor* ``eta`` (dimensionless): the stiffness
becomes complex, ``K (1 + jη)`` — hysteretic damping, whose dissipation per cycle does not
depend on frequency, as in a lightly damped metal structure. Every mode of a model whose
stiffness is all elastic then gets the same damping ratio ``η/2``, which no choice of ``α``
and ``β`` gives over a wide band (``α`` damps the low modes, ``β`` the high ones). The
parameter ``rayleigh.eta`` exists only when the element carries the attribute::

    <rayleigh_damping alpha="0" beta="0" eta="0.008"/>

A complex stiffness has no time-domain form, so the FRF uses it exactly and the modes and
state-space exports use its viscous equivalent at each mode's frequency
(:meth:`bondid.linear.linear_model.LinearModel.viscous`).
How a command declares it (``--damping``): :mod:`bondid.setup.damping`.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

from ..exceptions import ModelError

RAYLEIGH_TAG = "rayleigh_damping"
#: the owner part of the parameter names (``rayleigh.alpha``, ``rayleigh.beta``)
RAYLEIGH_OWNER = "rayleigh"
#: coefficient → SI unit (``alpha`` multiplies M, ``beta`` multiplies K, ``eta`` is the
#: structural loss factor of K)
RAYLEIGH_UNITS = {"alpha": "1/s", "beta": "s", "eta": "1"}
#: the coefficients every declared element has (``eta`` only when it is written)
VISCOUS = ("alpha", "beta")
RAYLEIGH_NAMES = tuple(f"{RAYLEIGH_OWNER}.{c}" for c in VISCOUS)
LOSS_NAME = f"{RAYLEIGH_OWNER}.eta"


@dataclass(frozen=True)
class Rayleigh:
    """The coefficients of ``α·M + β·K``: ``alpha`` in 1/s, ``beta`` in s, both ≥ 0, and the
    structural loss factor ``eta`` (≥ 0; None: not declared, i.e. 0 and no parameter)."""

    alpha: float
    beta: float
    eta: float | None = None

    @property
    def components(self) -> tuple[str, ...]:
        """The declared coefficients: ``alpha``, ``beta`` (and ``eta`` when declared)."""
        return VISCOUS if self.eta is None else (*VISCOUS, "eta")

    @property
    def loss(self) -> float:
        """The loss factor (0 when not declared)."""
        return 0.0 if self.eta is None else float(self.eta)

    def get(self, component: str) -> float:
        """``alpha``, ``beta`` or ``eta`` (0 when not declared)."""
        return {"alpha": self.alpha, "beta": self.beta, "eta": self.loss}[component]

    def to_element(self) -> ET.Element:
        attrs = {c: repr(float(self.get(c))) for c in self.components}
        return ET.Element(RAYLEIGH_TAG, attrs)


def check_coefficient(value: Any, component: str, where: str) -> float:
    """A coefficient as a float: finite and ≥ 0 (else :class:`ModelError` naming ``where``,
    the coefficient and what is valid)."""
    ok = isinstance(value, int | float | str) and not isinstance(value, bool)
    try:
        v = float(value) if ok else math.nan
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v >= 0.0):
        unit = RAYLEIGH_UNITS[component]
        raise ModelError(
            f"{where}: Rayleigh {component} {value!r} is not a finite number >= 0"
            f" ({'dimensionless' if unit == '1' else unit})"
        )
    return v


def rayleigh_from_element(el: ET.Element, where: str) -> Rayleigh:
    """A ``<rayleigh_damping alpha="…" beta="…" [eta="…"]/>`` element → :class:`Rayleigh` (a
    missing ``alpha`` or ``beta`` is 0, a missing ``eta`` not declared; raises
    :class:`ModelError`)."""
    at = f"{where}: <{RAYLEIGH_TAG}>"
    unknown = sorted(set(el.attrib) - set(RAYLEIGH_UNITS))
    if unknown:
        raise ModelError(f"{at}: unknown attribute {unknown[0]!r}; valid: alpha, beta, eta")
    eta = el.get("eta")
    return Rayleigh(
        check_coefficient(el.get("alpha", "0"), "alpha", at),
        check_coefficient(el.get("beta", "0"), "beta", at),
        None if eta is None else check_coefficient(eta, "eta", at),
    )


def model_rayleigh(doc: Any) -> Rayleigh | None:
    """The Rayleigh damping a :class:`~bondid.model.document.UrdfDocument` declares, or None.

    Raises:
        ModelError: more than one element, or a coefficient that is not a number ≥ 0.
    """
    where = doc.source or "<URDF>"
    found = [el for el in doc.extras if el.tag == RAYLEIGH_TAG]
    if len(found) > 1:
        raise ModelError(f"{where}: {len(found)} <{RAYLEIGH_TAG}> elements; give at most one")
    return rayleigh_from_element(found[0], where) if found else None


def set_rayleigh(doc: Any, value: Rayleigh) -> None:
    """Declare (or replace) the model's Rayleigh damping."""
    where = doc.source or "<URDF>"
    for c in value.components:
        check_coefficient(value.get(c), c, where)
    drop_rayleigh(doc)
    doc.extras.append(value.to_element())


def drop_rayleigh(doc: Any) -> None:
    """Remove the model's Rayleigh damping (its joint dampers stay)."""
    doc.extras = [el for el in doc.extras if el.tag != RAYLEIGH_TAG]
