"""``joint_compliance``: a compliant DOF (spring + damper) at an interface and axis that has none.

Every interface between two bodies (:func:`~.topology.interfaces`) × every axis ``tx ty tz rx
ry rz`` (child-body frame) along which its chain does not move yet is one candidate, located
``"PARENT->CHILD:AXIS"``. The DOF is inserted with
:func:`bondid.model.insert_parasitic_joint` after the interface's last joint, so the child
body keeps its placement and its parameters.

A rotational DOF pivots about a point the data choose: where a guide really pivots is seldom
known, so the pivot is a parameter. The joint is inserted at the interface's bearing centre
(the mean of its existing parasitic pivots; the child's CoM when it has none) and its pivot
freed across the axis (:func:`bondid.model.pivot.free_pivot`: two shifts, ``pivot_u`` and
``pivot_v`` [m/rad], that enter the linearised model exactly). The pivot's cost landscape has
walls (a shift moves the new mode's residues through zero) and the basin of the right pivot is
narrow: on a link of a few centimetres' section a refit started 5 mm off the pivot in both
directions across the axis finds it, one started 10 mm off does not. A guide seldom pivots on
a line through its bearing centre, so the candidate carries variants
(:attr:`~.base.Candidate.variants`, each a start of its own for the same model) whose pivot
starts on a :data:`PIVOT_GRID` × :data:`PIVOT_GRID` grid over the cross-section of the child's
collision hull across the axis (without a hull: the child frame's origin and CoM, in every
combination; :func:`pivot_options`). The screening ranks them after the nominal parameters
have relaxed around each (:func:`bondid.diagnose.starts.relaxed`) and the refit tries the best.
New parameters: the joint's stiffness and damping (and the two pivot shifts). The start puts
its mode at 300 Hz with 3 % damping (from the DOF's effective inertia); the starting-point
scan moves it from 15 Hz to 12 kHz keeping the damping ratio.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...model.authoring import insert_parasitic_joint
from ...model.document import UrdfDocument, rotation_and_translation
from ...model.pivot import across, free_pivot, pivot_joints, pivot_of
from . import register
from .base import Candidate, Effect, NewParameter, spring_parameters
from .topology import Interface, axis_vector, effective_inertia, interfaces, link_box

#: a link's hull box: lower and upper corners (m, link frame)
Box = tuple[np.ndarray, np.ndarray]

F_REF_HZ = 300.0
ZETA = 0.03
SCAN_HZ = tuple(float(f) for f in np.geomspace(15.0, 12000.0, 70))


#: pivot starts per direction across the axis, spread over the child's hull: a spacing of a
#: sixth of the hull's width puts one start within the few millimetres of a hand-sized
#: link's pivot that its refit needs
PIVOT_GRID = 7
#: pivots closer than this to one already listed are not tried again [m]
PIVOT_TOL = 0.003
#: how far a free pivot may move from the bearing centre of a child without geometry [m]
REACH_M = 0.2


def pivot_options(
    doc: UrdfDocument, itf: Interface, axis: np.ndarray, box: Box | bool | None = True
) -> list[np.ndarray]:
    """Pivots (child frame, m) to try for a rotational DOF about ``axis`` at ``itf``: the
    bearing centre first (:meth:`~.topology.Interface.pivot`), then both coordinates across
    the axis on a :data:`PIVOT_GRID` grid spanning the child's collision hull box (without a
    hull: each at the bearing centre's, the child frame's origin's and the child's CoM's
    value), the coordinate along the axis kept. ``box``: the child's hull box
    (:func:`~.topology.link_box`; None: no hull), True: found here."""
    centre = np.asarray(itf.pivot(doc), float)
    if box is True:
        box = link_box(doc, itf.child)
    u, v = np.flatnonzero(np.abs(axis) < 0.5)[:2]
    if box:
        lo, hi = np.asarray(box[0], float), np.asarray(box[1], float)
        spans = [np.linspace(lo[d], hi[d], PIVOT_GRID) for d in (u, v)]
    else:
        lk = doc.link(itf.child)
        com = None if lk.inertial is None else rotation_and_translation(lk.inertial.origin)[1]
        spans = [np.array([centre[d], 0.0, *([] if com is None else [com[d]])]) for d in (u, v)]
    out = [centre]
    for a in spans[0]:
        for b in spans[1]:
            p = centre.copy()
            p[u], p[v] = a, b
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
                    out += [c for c in [self._candidate(doc, itf, axis, np.zeros(3))] if c]
                    continue
                if box is None:  # the child's hull, read once per interface
                    box = (link_box(doc, itf.child),)
                centre, *others = pivot_options(doc, itf, vec, box[0])
                cand = self._candidate(doc, itf, axis, centre, box[0])
                if cand is not None:
                    variants = tuple(_starting_at(cand, p) for p in others)
                    out.append(replace(cand, variants=variants))
        return out

    def _candidate(
        self, doc: UrdfDocument, itf: Interface, axis: str, pivot: np.ndarray,
        box: Box | None = None,
    ) -> Candidate | None:  # fmt: skip
        """The candidate about ``pivot`` (child frame, m); a rotational one with its pivot
        free within ``box`` (the child's hull box) enlarged by half its size. None when the
        DOF would move no inertia of its own (:func:`~.topology.effective_inertia`)."""
        kind, vec = axis_vector(axis)
        jname = joint_name(itf.parent, itf.child, axis)
        spec: dict = {
            "after": itf.last_joint,
            "joint": jname,
            "kind": kind,
            "axis": [float(x) for x in vec],
            "pivot": [float(x) for x in pivot],
        }
        probe = self._insert(doc, spec, 1.0, 0.0, ())
        m = effective_inertia(probe, jname)
        if m <= 0:
            return None
        k0 = m * (2 * np.pi * F_REF_HZ) ** 2
        d0 = 2 * ZETA * np.sqrt(k0 * m)
        params: tuple[NewParameter, ...] = spring_parameters(
            jname, k0, d0, ((3.0 / F_REF_HZ) ** 2, (40000 / F_REF_HZ) ** 2), kind != "prismatic"
        )
        where = ""
        if kind != "prismatic":
            reach = _reach(box)
            params = (*params, *(
                NewParameter(f"pivot_{c}", 0.0, -reach, reach, "m/rad",
                             ((f"{n}.multiplier", 1.0),), signed=True, typical=reach / 10)
                for c, n in zip("uv", pivot_joints(jname), strict=True)
            ))  # fmt: skip
            spec["free_pivot"] = True
            where = f" pivot free across the axis from {_mm(pivot)} mm"
        location = f"{itf.parent}->{itf.child}:{axis}"
        return Candidate(
            self.name,
            location,
            params,
            spec,
            tuple((f / F_REF_HZ) ** 2 for f in SCAN_HZ),
            _what(kind, location) + where,
            F_REF_HZ,
        )

    @staticmethod
    def _insert(
        doc: UrdfDocument, spec: dict, k: float, d: float, shifts: tuple[float, ...]
    ) -> UrdfDocument:
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
        if spec.get("free_pivot"):
            for name, v in zip(free_pivot(new, spec["joint"]), shifts or (0.0, 0.0), strict=True):
                new.joint(name).mimic.multiplier = float(v)
        return new

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        k, d, *shifts = (p.initial for p in candidate.parameters)
        return self._insert(doc, candidate.spec, k, d, tuple(shifts))

    def detail(self, doc: UrdfDocument, candidate: Candidate) -> str:
        """Where the fitted model ``doc`` pivots (rotational candidates)."""
        if not candidate.spec.get("free_pivot") or candidate.spec["joint"] not in doc.joint_names:
            return ""
        return f"pivot {_mm(pivot_of(doc, candidate.spec['joint']))} mm"


def _reach(box: Box | None) -> float:
    """How far [m] a free pivot may move from the bearing centre: the diagonal of the child's
    hull box (its half on either side, and half as much again), else :data:`REACH_M`."""
    if box is None:
        return REACH_M
    return float(np.linalg.norm(np.asarray(box[1], float) - np.asarray(box[0], float)))


def _what(kind: str, location: str) -> str:
    """``"revolute DOF along ry between A and B"`` for ``location`` ``"A->B:ry"``."""
    pair, axis = location.rsplit(":", 1)
    parent, child = pair.split("->")
    return f"{kind} DOF along {axis} between {parent} and {child}"


def _mm(p: np.ndarray) -> list[float]:
    """A point [m] in millimetres, to 0.1 mm, for the descriptions."""
    return np.round(np.asarray(p, float) * 1e3, 1).tolist()


def _starting_at(cand: Candidate, pivot: np.ndarray) -> Candidate:
    """``cand`` (variants cleared) with its pivot shifts starting where they place the pivot
    at ``pivot`` (child frame, m; its part across the axis): ``u = a × (p₀ − p)``,
    :mod:`bondid.model.pivot`."""
    a = np.asarray(cand.spec["axis"], float)
    u = np.cross(a, np.asarray(cand.spec["pivot"], float) - np.asarray(pivot, float))
    shifts = {f"pivot_{c}": float(e @ u) for c, e in zip("uv", across(a), strict=True)}
    pars = tuple(
        replace(p, initial=float(np.clip(shifts[p.name], p.lower, p.upper)))
        if p.name in shifts else p
        for p in cand.parameters
    )  # fmt: skip
    what = _what(cand.spec["kind"], str(cand.location))
    return replace(cand, parameters=pars, variants=(),
                   description=f"{what} pivot starting at {_mm(pivot)} mm")  # fmt: skip
