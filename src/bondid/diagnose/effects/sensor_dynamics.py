"""``sensor_dynamics``: a sensor on a compliant mount, a light head on a spring that only its
own output reads.

A read head, a scale, a target mirror or an accelerometer fixed to the measured body through
a compliant bracket (or a glue or wax layer) moves as the body's motion *at the head's place*
filtered by the mount's own mode, and its output reads the body plus the head's deflection.
Two things make this more than a factor on the output's row: the head is excited by the
body's absolute motion there, rotations included (a head off the body's centre also reads
the body's small tilts, through its lever arm, which the other drives excite), and the
output's row of the model (a drive's encoder: a relative coordinate) is not that motion.

The candidate builds the mount in: a head link (1 % of the measured body's mass, or of its
inertia about the measuring axis for an angle sensor) on a sprung joint along the measuring
direction, fixed to the measured body, and a ``<sensor_mount>`` element (:mod:`bondid.model.
mounts`) that adds the joint's deflection to the output. Where the head sits is seldom known
and enters the kinematics, so a translation sensor's candidate carries variants
(:attr:`~.base.Candidate.variants`): the head at the body's centre of mass, and at the two
faces of its collision hull across the measuring direction, one direction at a time.

Candidates: each sensor (the transmitted joints' encoders and the measurement points;
location = the output). New parameters: the mount's stiffness (the strength: the mount is
rigid as it grows) and damping. The start puts the mount's mode at 1 kHz with 5 % damping;
the starting-point scan moves it from 50 Hz to 12 kHz keeping the damping ratio; bounds
from 20 Hz to 40 kHz.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...model.document import UrdfDocument
from ...model.mounts import SensorMount
from ...model.parameters import link_inertial
from . import register
from ._chain import add_joint, add_link
from .base import Candidate, Effect, spring_parameters
from .channels import sensors
from .topology import carried_body, joint_axis, link_box, link_placements

F0_HZ = 1000.0
ZETA0 = 0.05
SCAN_HZ = tuple(float(f) for f in np.geomspace(50.0, 12000.0, 60))
#: the head's mass (inertia) as a share of the measured body's: light, yet its own body
HEAD_SHARE = 0.01
#: an angle sensor's head: a sphere of this mass [kg], its radius setting its inertia
ROTARY_HEAD_KG = 0.01


def measured(doc: UrdfDocument, output: str) -> tuple[str, np.ndarray, str] | None:
    """``(body, direction (3,) in the body's axes, "prismatic" | "revolute")``: the body a
    sensor's head would be fixed to and along what it measures; None when the model says
    neither (a point relative to another frame measures no single body)."""
    W = link_placements(doc)
    points = {p.name: p for p in doc.points}
    if output in points:
        p = points[output]
        if p.relative_to is not None or p.second_kind is not None or p.link not in W:
            return None
        d = np.asarray(p.direction, float)
        if p.axes == "world":
            d = W[p.link][:3, :3].T @ d
        return p.link, d / np.linalg.norm(d), "prismatic" if p.kind == "translation" else "revolute"
    body = carried_body(doc, output)
    d = joint_axis(doc, output, body, W)
    return body, d, "prismatic" if doc.joint(output).type == "prismatic" else "revolute"


def head_places(doc: UrdfDocument, body: str, d: np.ndarray, com: np.ndarray) -> list:
    """Where a translation sensor's head may sit (body frame, m): its centre of mass first,
    then the faces of its collision hull along the two body axes most across ``d``."""
    box = link_box(doc, body)
    places = [com]
    if box is None:
        return places
    for k in np.argsort(np.abs(d))[:2]:
        for face in box:
            p = com.copy()
            p[k] = face[k]
            if abs(p[k] - com[k]) > 1e-6:
                places.append(p)
    return places


@register
class SensorDynamics(Effect):
    name = "sensor_dynamics"
    description = "a sensor on a compliant mount: a light head on a spring, read by its output"

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        out = []
        for s in sensors(doc):
            found = measured(doc, s)
            if found is None:
                continue
            body, d, kind = found
            if doc.link(body).inertial is None:
                continue
            mass, com, inertia = link_inertial(doc, body)
            if mass <= 0:
                continue
            if kind == "prismatic":
                m = HEAD_SHARE * mass
                places = head_places(doc, body, d, np.asarray(com, float))
            else:
                m = HEAD_SHARE * float(d @ np.asarray(inertia, float) @ d)
                places = [np.asarray(com, float)]
            main, *others = (self._candidate(s, body, d, kind, m, p) for p in places)
            out.append(replace(main, variants=tuple(others)))
        return out

    def _candidate(
        self, output: str, body: str, d: np.ndarray, kind: str, m: float, place: np.ndarray
    ) -> Candidate:
        """The mount of ``output``'s head at ``place`` (``body``'s frame, m); ``m`` the head's
        mass (kg) or inertia about ``d`` (kg·m²)."""
        joint = f"sensor_mount_{output}"
        k0 = m * (2 * np.pi * F0_HZ) ** 2
        c0 = 2 * ZETA0 * np.sqrt(k0 * m)
        span = ((20.0 / F0_HZ) ** 2, (40000.0 / F0_HZ) ** 2)
        params = spring_parameters(joint, k0, c0, span, kind != "prismatic")
        spec = {
            "output": output, "body": body, "joint": joint, "kind": kind, "mass": m,
            "axis": [float(x) for x in d], "place": [float(x) for x in place],
        }  # fmt: skip
        rot = kind != "prismatic"
        where = f" at {np.round(place * 1e3, 1).tolist()} mm on {body}" if not rot else ""
        return Candidate(
            self.name, output, params, spec, tuple((f / F0_HZ) ** 2 for f in SCAN_HZ),
            f"compliant mount of sensor {output}{where}", F0_HZ,
        )  # fmt: skip

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        new = doc.copy()
        s = candidate.spec
        k, c = (float(p.initial) for p in candidate.parameters)
        head = f"sensor_head_{s['output']}"
        if s["kind"] == "prismatic":
            add_link(new, head, s["mass"], radius=0.005)
        else:  # a disc whose inertia about any axis is the head's inertia about d
            r = float(np.sqrt(s["mass"] / (0.4 * ROTARY_HEAD_KG)))
            add_link(new, head, ROTARY_HEAD_KG, radius=r)
        add_joint(new, s["joint"], s["kind"], s["body"], head, axis=tuple(s["axis"]),
                  xyz=tuple(s["place"]), stiffness=k, damping=c)  # fmt: skip
        new.add_sensor_mount(SensorMount(s["output"], s["joint"]))
        return new
