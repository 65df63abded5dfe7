"""Splitting a link in two along its length, with physically consistent parts.

A link's mass distribution is represented by its *equivalent box*: the uniform box, centred
at the CoM along the principal axes, with the link's mass and second moments (half-extents
``hᵢ = √(3 Σᵢ/m)``, ``Σ = ½ tr(I_c)·𝟙 − I_c``). Cutting that box across its longest axis at a
coordinate ``u`` gives two uniform boxes whose masses, first and second moments add up to the
link's exactly: their pseudo-inertias ``J_A + J_B = J`` and each ``J ≻ 0`` (each is a real
uniform body), so every split is physically consistent for any consistent link.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...model.document import UrdfDocument, rotation_and_translation
from ...model.parameters import link_inertial

#: a link is a candidate to bend when its equivalent box is this many times longer than wide
ELONGATION = 1.5
#: children whose joint sits within this distance of the origin's projection decide nothing [m]
_TOL = 1e-6


@dataclass(frozen=True)
class Inertial:
    """Mass [kg], CoM ``(3,)`` [m] and inertia about the CoM ``(3, 3)`` [kg·m²], link frame."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class LinkAxis:
    """The long axis of a link's equivalent box (link frame).

    Attributes:
        link: the link.
        centre: the CoM ``(3,)`` [m] (the box centre).
        axis: unit vector ``(3,)`` along the box's length, pointing away from the link's
            origin (where its parent joint attaches).
        across: ``(2, 3)`` the two other principal axes (the bending axes), unit vectors.
        half: half-extents ``(3,)`` [m]: along ``axis``, then ``across``.
        u_origin: the origin's coordinate along ``axis`` from the centre [m] (≤ 0), clipped
            to the box.
    """

    link: str
    centre: np.ndarray
    axis: np.ndarray
    across: np.ndarray
    half: np.ndarray
    u_origin: float

    def cut(self, fraction: float) -> float:
        """The coordinate along :attr:`axis` [m] of a cut at ``fraction`` (0 … 1) of the way
        from the origin's projection to the far end."""
        return self.u_origin + fraction * (self.half[0] - self.u_origin)

    def point(self, u: float) -> np.ndarray:
        """The point ``(3,)`` [m] at coordinate ``u`` on the long axis (link frame)."""
        return self.centre + u * self.axis


def equivalent_box(inertial: Inertial) -> tuple[np.ndarray, np.ndarray]:
    """Principal axes ``R`` ``(3, 3)`` (columns) and half-extents ``(3,)`` [m] of the uniform
    box with the link's mass and second moments (module docstring)."""
    I_c = 0.5 * (inertial.inertia + inertial.inertia.T)
    sigma = 0.5 * np.trace(I_c) * np.eye(3) - I_c
    s, R = np.linalg.eigh(sigma)
    half = np.sqrt(np.maximum(3.0 * s / max(inertial.mass, 1e-300), 0.0))
    return R, half


def long_axis(doc: UrdfDocument, link: str) -> LinkAxis | None:
    """:class:`LinkAxis` of ``link``, or None when it has no mass or is not elongated (its box
    less than :data:`ELONGATION` times longer than wide)."""
    m, c, I_c = link_inertial(doc, link)
    if not m > 0:
        return None
    R, half = equivalent_box(Inertial(m, c, I_c))
    order = np.argsort(half)[::-1]
    if half[order[0]] < ELONGATION * half[order[1]]:
        return None
    e = R[:, order[0]].copy()
    u0 = float(e @ (np.zeros(3) - c))
    if abs(u0) <= _TOL:  # the origin at the CoM: point toward the children instead
        kids = [rotation_and_translation(j.origin)[1] for j in doc.robot.joints
                if j.parent == link and j.origin is not None]  # fmt: skip
        u0 = -float(np.mean([e @ (p - c) for p in kids])) if kids else 0.0
    if u0 > 0:
        e = -e
    u0 = -abs(u0)
    return LinkAxis(
        link, c, e, R[:, order[1:]].T.copy(), half[order], float(max(u0, -half[order[0]]))
    )


def split_inertial(inertial: Inertial, ax: LinkAxis, u: float) -> tuple[Inertial, Inertial]:
    """The parts of the link's equivalent box below (``A``, the origin's side) and above
    (``B``) the cut at coordinate ``u`` along ``ax.axis`` (link frame; module docstring)."""
    h = float(ax.half[0])
    u = float(np.clip(u, -h, h))
    frame = np.vstack([ax.axis, ax.across]).T  # columns: long axis, then across
    second = inertial.mass * ax.half**2 / 3.0  # second moments about the CoM, box axes
    parts = []
    for lo, hi in ((-h, u), (u, h)):
        share = (hi - lo) / (2 * h) if h > 0 else 0.5
        m = inertial.mass * share
        mid = 0.5 * (lo + hi)
        s = second * share
        s[0] = m * (hi - lo) ** 2 / 12.0
        sigma = frame @ np.diag(s) @ frame.T
        parts.append(Inertial(m, ax.centre + mid * ax.axis, np.trace(sigma) * np.eye(3) - sigma))
    return parts[0], parts[1]
