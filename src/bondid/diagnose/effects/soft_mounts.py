"""``soft_mounts``: the base on compliant feet (6-DOF springs to ground) instead of grounded.

The grounded root body becomes movable: a new root link ``ground`` carries it through three
prismatic (x, y, z) and three revolute (x, y, z) sprung, damped joints whose axes pass through
the root body's CoM (``soft_mount_tx`` ... ``soft_mount_rz``), so the base's mass and inertia
now matter and the drives' reactions rock it. One candidate, located at the root body.

New parameters: the six mount stiffnesses (per direction) and two damping ratios, one for the
translations and one for the rotations (each joint's damper is ``2·ζ·√(k₀·m)`` with ``k₀`` the
start stiffness and ``m`` the machine's mass or the base's principal inertia). The start puts
every mount mode at 30 Hz, 5 % damping; the scan moves them together from 2 Hz to 500 Hz.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from ...model.parameters import link_inertial
from . import register
from ._chain import ROTATIONS, TRANSLATIONS, add_link, dof_chain, total_mass
from .base import Candidate, Effect, NewParameter

F0_HZ = 30.0
ZETA = 0.05
SCAN_HZ = tuple(float(f) for f in np.geomspace(2.0, 500.0, 58))
PREFIX = "soft_mount"
GROUND = "ground"


@register
class SoftMounts(Effect):
    name = "soft_mounts"
    description = "the grounded base on compliant feet (6-DOF springs and dampers to ground)"

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        root = doc.root_link()
        lk = doc.link(root)
        if lk.inertial is None or not (lk.inertial.mass or 0) > 0:
            return []
        _, com, I_c = link_inertial(doc, root)
        m = total_mass(doc)
        w = 2 * np.pi * F0_HZ
        inert = [m, m, m, *np.maximum(np.diag(I_c), 1e-9)]
        params = []
        for (ax, _, _), mi in zip(TRANSLATIONS + ROTATIONS, inert, strict=True):
            k0 = mi * w**2
            unit = "N/m" if ax[0] == "t" else "N*m/rad"
            params.append(
                NewParameter(
                    f"stiffness_{ax}", k0, k0 * (0.3 / F0_HZ) ** 2, k0 * (3000 / F0_HZ) ** 2,
                    unit, ((f"{PREFIX}_{ax}.stiffness", 1.0),), scan=1.0,
                )
            )  # fmt: skip
        for group, axes, sl in (("zeta_t", TRANSLATIONS, slice(0, 3)),
                                ("zeta_r", ROTATIONS, slice(3, 6))):  # fmt: skip
            members = tuple(
                (f"{PREFIX}_{ax}.damping", 2.0 * np.sqrt(p.initial * mi))
                for (ax, _, _), p, mi in zip(axes, params[sl], inert[sl], strict=True)
            )
            params.append(NewParameter(group, ZETA, 1e-4, 2.0, "1", members, scan=0.5))
        spec = {"root": root, "com": [float(x) for x in com]}
        grid = tuple((f / F0_HZ) ** 2 for f in SCAN_HZ)
        return [
            Candidate(self.name, root, tuple(params), spec, grid, f"{root} on 6-DOF mounts", F0_HZ)
        ]

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        new = doc.copy()
        root = candidate.spec["root"]
        com = np.asarray(candidate.spec["com"], float)
        add_link(new, GROUND)
        p = {q.name: q for q in candidate.parameters}
        ks = [p[f"stiffness_{ax}"].initial for ax, _, _ in TRANSLATIONS + ROTATIONS]
        ds = [0.0] * 6
        for q in candidate.parameters:
            for m, fac in q.members:
                if m.endswith(".damping"):
                    ds[
                        [f"{PREFIX}_{ax}.damping" for ax, _, _ in TRANSLATIONS + ROTATIONS].index(m)
                    ] = fac * q.initial
        dof_chain(
            new, PREFIX, GROUND, root, TRANSLATIONS + ROTATIONS, xyz=list(com), back=list(-com),
            stiffness=ks, damping=ds,
        )  # fmt: skip
        return new
