"""``drive_spring``: a spring and a damper in parallel with a drive (a cable carrier, a drag
chain, a bellows, a hose, a flexure guide).

A driven joint that the model lets move freely (no spring: its rigid-body mode at 0 Hz) may
be held by the cables and hoses that follow the stage: the drive then sees a stiffness to its
parent, the low-frequency receptance levels off at ``1/k`` instead of rising as ``1/(mω²)``,
and the rigid-body mode becomes a suspension mode at ``√(k/m)``. The candidate gives the drive
joint a spring (``<springStiffness>``) and raises its damping.

Candidates: every transmitted joint with no spring (location = the joint). New parameters:
its stiffness (the strength) and its damping (the joint's whole damper: its model value plus
2 % of critical at the start). The start puts the suspension mode at 10 Hz on the joint's
effective inertia (:func:`~.topology.effective_inertia`); the scan moves it from 0.5 Hz to
500 Hz keeping the damping ratio; bounds from 0.05 Hz to 5 kHz.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from . import register
from .base import Candidate, Effect, spring_parameters
from .topology import effective_inertia

F_REF_HZ = 10.0
ZETA = 0.02
SCAN_HZ = tuple(float(f) for f in np.geomspace(0.5, 500.0, 50))


@register
class DriveSpring(Effect):
    name = "drive_spring"
    description = "a spring and damper in parallel with a drive (cable carrier, drag chain)"

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        out = []
        for t in doc.transmissions:
            j = t.joint
            if doc.joint(j).type not in ("prismatic", "revolute", "continuous"):
                continue
            if doc.stiffness(j) > 0:
                continue
            m = effective_inertia(doc, j)
            if m <= 0:  # a drive that moves nothing of its own: no spring to show
                continue
            k0 = m * (2 * np.pi * F_REF_HZ) ** 2
            d_model = doc.damping(j)
            d0 = d_model + 2 * ZETA * np.sqrt(k0 * m)
            rot = doc.joint(j).type != "prismatic"
            params = spring_parameters(
                j, k0, d0, ((0.05 / F_REF_HZ) ** 2, (5000.0 / F_REF_HZ) ** 2), rot
            )
            out.append(Candidate(
                self.name, j, params, {"joint": j},
                tuple((f / F_REF_HZ) ** 2 for f in SCAN_HZ),
                f"spring and damper in parallel with drive {j}", F_REF_HZ,
            ))  # fmt: skip
        return out

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        new = doc.copy()
        j = candidate.spec["joint"]
        k, d = (p.initial for p in candidate.parameters)
        new.set_stiffness(j, float(k), reference=0.0)
        new.set_damping(j, float(d))
        return new
