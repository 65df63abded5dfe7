"""``flexible_link``: a moving link that bends, as two rigid parts joined by a compliant hinge.

An arm, a bridge or a long slide is seldom rigid up to the top of the band: its first bending
mode swings its far end (and everything mounted there) against its root. The candidate cuts
the link across its length (:mod:`.link_split`: the link's equivalent box, cut at a fraction
of the way from the origin, where its parent joint attaches, to its far end; the two parts'
masses and inertias add up to the link's exactly and each is physically consistent) and joins
the parts by two sprung, damped revolute joints about the two bending axes (the box's other
principal axes) at the cut. The part on the origin's side keeps the link's name, its geometry
and its parent joint; the far part becomes the link ``{link}_distal``, and the child joints
beyond the cut move onto it (placed as before).

Where a link bends most is seldom known: the candidate cuts it halfway and carries the cuts
at a quarter and three quarters as variants (:attr:`~.base.Candidate.variants`, each with a
start of its own, as the pivots of a rotational joint compliance). Candidates: every moving body
whose equivalent box is at least :data:`~.link_split.ELONGATION` times longer than wide
(location = the link). New parameters: the stiffness (the strength) and damping of each
bending hinge; the start puts each hinge's mode at 400 Hz on its effective inertia, 2 %
damping; the scan moves both from 30 Hz to 12 kHz keeping the damping ratio.

The link's own inertial parameters now describe the near part: the candidate says so
(``spec["replaces_inertial"]``), and a refit takes their values in the augmented model as
their nominal ones (:func:`bondid.diagnose.augmented.build`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...model.document import UrdfDocument, rotation_and_translation
from ...model.parameters import link_inertial, set_link_inertial
from . import register
from ._chain import dof_chain
from .base import Candidate, Effect, NewParameter
from .link_split import Inertial, LinkAxis, long_axis, split_inertial
from .topology import bodies, effective_inertia

F_REF_HZ = 400.0
ZETA = 0.02
SCAN_HZ = tuple(float(f) for f in np.geomspace(30.0, 12000.0, 60))
#: where the link is cut (fraction of the way from its origin to its far end): the
#: candidate's, then its variants'
FRACTIONS = (0.5, 0.25, 0.75)
_ALIGN = 0.99


def axis_label(v: np.ndarray, k: int) -> str:
    """``"rx"``/``"ry"``/``"rz"`` for a bending axis along a link-frame axis, else ``"b1"``,
    ``"b2"`` (``k`` = 0, 1)."""
    i = int(np.argmax(np.abs(v)))
    return f"r{'xyz'[i]}" if abs(v[i]) >= _ALIGN else f"b{k + 1}"


def distal_name(link: str) -> str:
    return f"{link}_distal"


def hinge_joint(link: str, label: str) -> str:
    return f"{link}_bend_{label}"


def build_split(doc: UrdfDocument, ax: LinkAxis, fraction: float, k: float, d: float,
                stiffness: list[float] | None = None,
                damping: list[float] | None = None) -> UrdfDocument:  # fmt: skip
    """A copy of ``doc`` with ``ax.link`` cut at ``fraction`` (module docstring); the hinges'
    springs and dampers ``stiffness``/``damping`` (one each per bending axis; default
    ``k``, ``d``)."""
    import yourdfpy

    new = doc.copy()
    link = ax.link
    m, c, I_c = link_inertial(new, link)
    u = ax.cut(fraction)
    near, far = split_inertial(Inertial(m, c, I_c), ax, u)
    hinge = ax.point(u)
    set_link_inertial(new, link, near.mass, near.com, near.inertia)
    T = np.eye(4)
    T[:3, 3] = far.com - hinge
    new.robot.links.append(yourdfpy.Link(
        name=distal_name(link), inertial=yourdfpy.Inertial(origin=T, mass=float(far.mass),
                                                           inertia=far.inertia),
        visuals=[], collisions=[],
    ))  # fmt: skip
    for j in new.robot.joints:  # the children beyond the cut ride on the far part
        if j.parent != link:
            continue
        p = rotation_and_translation(j.origin)[1] if j.origin is not None else np.zeros(3)
        if float(ax.axis @ (p - ax.centre)) > u:
            origin = np.eye(4) if j.origin is None else np.asarray(j.origin, float).copy()
            origin[:3, 3] = p - hinge
            j.parent, j.origin = distal_name(link), origin
    labels = [axis_label(v, i) for i, v in enumerate(ax.across)]
    dofs = [(f"bend_{lab}", "revolute", tuple(float(x) for x in v))
            for lab, v in zip(labels, ax.across, strict=True)]  # fmt: skip
    dof_chain(new, link, link, distal_name(link), dofs, xyz=[float(x) for x in hinge],
              stiffness=stiffness or [k, k], damping=damping or [d, d])  # fmt: skip
    return new


@register
class FlexibleLink(Effect):
    name = "flexible_link"
    description = "a moving link that bends: cut across its length, joined by a compliant hinge"

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        root = doc.root_link()
        out = []
        for link in bodies(doc):
            if link == root:
                continue
            ax = long_axis(doc, link)
            if ax is None:
                continue
            options = [c for c in (self._candidate(doc, ax, f) for f in FRACTIONS) if c]
            if options:
                main, *others = options
                out.append(replace(main, variants=tuple(others)))
        return out

    def _candidate(self, doc: UrdfDocument, ax: LinkAxis, fraction: float) -> Candidate | None:
        """The link cut at ``fraction`` of its length; None when a hinge there would move no
        inertia of its own (:func:`~.topology.effective_inertia`)."""
        link = ax.link
        labels = [axis_label(v, i) for i, v in enumerate(ax.across)]
        probe = build_split(doc, ax, fraction, 1.0, 0.0)
        params_k, params_d = [], []
        w = 2 * np.pi * F_REF_HZ
        for lab in labels:
            jn = hinge_joint(link, lab)
            m = effective_inertia(probe, jn)
            if m <= 0:
                return None
            k0 = m * w**2
            d0 = 2 * ZETA * np.sqrt(k0 * m)
            params_k.append(NewParameter(
                f"stiffness_{lab}", k0, k0 * (3.0 / F_REF_HZ) ** 2, k0 * (40000 / F_REF_HZ) ** 2,
                "N*m/rad", ((f"{jn}.stiffness", 1.0),), scan=1.0, strength=True,
            ))  # fmt: skip
            params_d.append(NewParameter(
                f"damping_{lab}", d0, d0 * 1e-3, d0 * 1e3, "N*m*s/rad", ((f"{jn}.damping", 1.0),),
                scan=0.5,
            ))  # fmt: skip
        spec = {"link": link, "fraction": float(fraction), "replaces_inertial": [link]}
        cut_mm = np.round(ax.point(ax.cut(fraction)) * 1e3, 1).tolist()
        return Candidate(
            self.name, link, (*params_k, *params_d), spec,
            tuple((f / F_REF_HZ) ** 2 for f in SCAN_HZ),
            f"{link} bending at {fraction:.0%} of its length (hinge at {cut_mm} mm)", F_REF_HZ,
        )  # fmt: skip

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        ax = long_axis(doc, candidate.spec["link"])
        if ax is None:
            from ...exceptions import ModelError

            raise ModelError(
                f"{doc.source or '<URDF>'}: link {candidate.spec['link']!r} has no long axis to"
                " bend about (massless or not elongated)"
            )
        p = [q.initial for q in candidate.parameters]
        n = len(p) // 2
        return build_split(doc, ax, candidate.spec["fraction"], 0.0, 0.0, p[:n], p[n:])
