"""``joint_compliance``: a compliant DOF (spring + damper) at an interface and axis that has none.

Every interface between two bodies (:func:`~.topology.interfaces`) × every axis ``tx ty tz rx
ry rz`` (child-body frame) along which its chain does not move yet is one candidate, located
``"PARENT->CHILD:AXIS"``. The DOF is inserted with
:func:`bondid.model.insert_parasitic_joint` after the interface's last joint, so the child
body keeps its placement and its parameters; a rotational DOF pivots about the interface's
bearing centre (the mean of its existing parasitic pivots; the child's CoM when it has none);
where a guide really pivots is seldom known, so the candidate carries variants
(:attr:`~.base.Candidate.variants`, each with a start of its own) whose pivot is moved, one
direction across the axis at a time, to the child frame's origin, the child's CoM and the two
faces of its collision hull (:func:`pivot_options`).
New parameters: the joint's stiffness and damping. The start puts its mode at 300 Hz with 3 %
damping (from the DOF's effective inertia); the starting-point scan moves it from 15 Hz to
12 kHz keeping the damping ratio.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...model.authoring import insert_parasitic_joint
from ...model.document import UrdfDocument, rotation_and_translation
from . import register
from .base import Candidate, Effect, spring_parameters
from .topology import Interface, axis_vector, effective_inertia, interfaces, link_box

#: a link's hull box: lower and upper corners (m, link frame)
Box = tuple[np.ndarray, np.ndarray]

F_REF_HZ = 300.0
ZETA = 0.03
SCAN_HZ = tuple(float(f) for f in np.geomspace(15.0, 12000.0, 70))


#: pivots closer than this to one already listed are not tried again [m]
PIVOT_TOL = 0.003


def pivot_options(
    doc: UrdfDocument, itf: Interface, axis: np.ndarray, box: Box | bool | None = True
) -> list[np.ndarray]:
    """Pivots (child frame, m) to try for a rotational DOF about ``axis`` at ``itf``: the
    bearing centre first (:meth:`~.topology.Interface.pivot`), then, for each of the two
    coordinate directions across the axis, that coordinate moved to the child frame's origin,
    the child's CoM and the extremes of its collision hull (the others kept). ``box``: the
    child's hull box (:func:`~.topology.link_box`; None: no hull), True: found here."""
    centre = np.asarray(itf.pivot(doc), float)
    lk = doc.link(itf.child)
    levels = [np.zeros(3)]
    if lk.inertial is not None:
        levels.append(rotation_and_translation(lk.inertial.origin)[1])
    if box is True:
        box = link_box(doc, itf.child)
    if box:
        levels += [np.asarray(box[0], float), np.asarray(box[1], float)]
    out = [centre]
    for d in np.flatnonzero(np.abs(axis) < 0.5):
        for level in levels:
            p = centre.copy()
            p[d] = level[d]
            if all(np.linalg.norm(p - q) > PIVOT_TOL for q in out):
                out.append(p)
    return out


def joint_name(parent: str, child: str, axis: str) -> str:
    return f"{child}_compliance_{axis}"


@register
class JointCompliance(Effect):
    name = "joint_compliance"
    description = "a compliant DOF at an interface x axis that has none (every one tried)"

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        out = []
        for itf in interfaces(doc):
            box = None
            for axis in itf.missing:
                kind, vec = axis_vector(axis)
                if kind != "revolute":
                    out.append(self._candidate(doc, itf, axis, np.zeros(3)))
                    continue
                if box is None:  # the child's hull, read once per interface
                    box = (link_box(doc, itf.child),)
                main, *others = pivot_options(doc, itf, vec, box[0])
                variants = tuple(self._candidate(doc, itf, axis, p) for p in others)
                cand = self._candidate(doc, itf, axis, main)
                out.append(replace(cand, variants=variants))
        return out

    def _candidate(
        self, doc: UrdfDocument, itf: Interface, axis: str, pivot: np.ndarray
    ) -> Candidate:
        """The candidate about ``pivot`` (child frame, m)."""
        kind, vec = axis_vector(axis)
        jname = joint_name(itf.parent, itf.child, axis)
        spec: dict = {
            "after": itf.last_joint,
            "joint": jname,
            "kind": kind,
            "axis": [float(x) for x in vec],
            "pivot": [float(x) for x in pivot],
        }
        probe = self._insert(doc, spec, 1.0, 0.0)
        m = effective_inertia(probe, jname)
        k0 = m * (2 * np.pi * F_REF_HZ) ** 2
        d0 = 2 * ZETA * np.sqrt(k0 * m)
        params = spring_parameters(
            jname, k0, d0, ((3.0 / F_REF_HZ) ** 2, (40000 / F_REF_HZ) ** 2), kind != "prismatic"
        )
        where = "" if kind == "prismatic" else f" pivot {np.round(pivot * 1e3, 1).tolist()} mm"
        return Candidate(
            self.name,
            f"{itf.parent}->{itf.child}:{axis}",
            params,
            spec,
            tuple((f / F_REF_HZ) ** 2 for f in SCAN_HZ),
            f"{kind} DOF along {axis} between {itf.parent} and {itf.child}{where}",
            F_REF_HZ,
        )

    @staticmethod
    def _insert(doc: UrdfDocument, spec: dict, k: float, d: float) -> UrdfDocument:
        new = doc.copy()
        insert_parasitic_joint(
            new,
            spec["joint"],
            after=spec["after"],
            kind=spec["kind"],
            axis=spec["axis"],
            pivot=spec["pivot"],
            stiffness=k,
            damping=d,
        )
        return new

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        k, d = (p.initial for p in candidate.parameters)
        return self._insert(doc, candidate.spec, k, d)
