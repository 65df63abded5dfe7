"""``flexible_base``: the elastic base/chassis of the seed report §4.2, lumped.

The report models the base as a block of height L whose horizontal (shear) and vertical
(compression) motion propagates as waves, with a stress-free bottom (weak legs), and suggests
"a small number of individual masses linked by springs and dampers". That is what is built
here: the grounded root body becomes the top node of a chain of ``N = 3`` lumped masses
(bottom, middle, top) joined by shear springs (x, y) and compression springs (z) with dampers;
the bottom node is free to translate (stress-free bottom: zero-stiffness joints to a new root
``ground``). The stages ride on the top node (the original root link). Node masses follow the
consistent lumping of a uniform rod, ``M·(1/4, 1/2, 1/4)``, so the chain has a rigid-body
translation and wave-like elastic modes at ``ω² = 4k/M`` and ``8k/M`` per direction. (The
continuous ``coth`` impedance of the report is not used: the lumped chain keeps the model an
ordinary URDF that can be written out, and its first modes match the continuum's.)

Joints: ``flexible_base_{level}_{tx,ty,tz}``, level 0 the free bottom, 1 and 2 the elastic
segments; links ``flexible_base_0`` (bottom) and ``flexible_base_1`` (middle). One candidate,
located at the root body. New parameters: total mass M (the root body's mass at the start),
shear stiffness and damper (both horizontal directions, every segment), compression stiffness
and damper. Start: first shear mode at 1 kHz (compression 3.5× stiffer, as for ν ≈ 0.3),
2 % damping; the scan moves both from 100 Hz to 12 kHz.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from ...model.parameters import link_inertial
from . import register
from ._chain import TRANSLATIONS, add_link, dof_chain
from .base import Candidate, Effect, NewParameter

N_NODES = 3
F0_HZ = 1000.0
ZETA = 0.02
COMPRESSION_RATIO = 3.5
HEIGHT = 0.1
SCAN_HZ = tuple(float(f) for f in np.geomspace(100.0, 12000.0, 50))
PREFIX = "flexible_base"
GROUND = "ground"
SPLIT = (0.25, 0.5, 0.25)  # bottom, middle, top


@register
class FlexibleBase(Effect):
    name = "flexible_base"
    description = "elastic base/chassis: lumped shear/compression chain (seed report 4.2)"

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        root = doc.root_link()
        lk = doc.link(root)
        if lk.inertial is None or not (lk.inertial.mass or 0) > 0:
            return []
        M = float(lk.inertial.mass)
        w = 2 * np.pi * F0_HZ
        ks = M * w**2 / 4.0
        kc = COMPRESSION_RATIO * ks
        m_eff = M / 4.0
        ds, dc = 2 * ZETA * np.sqrt(ks * m_eff), 2 * ZETA * np.sqrt(kc * m_eff)
        lo, hi = (30.0 / F0_HZ) ** 2, (40000.0 / F0_HZ) ** 2
        seg = [f"{PREFIX}_{lev}" for lev in (1, 2)]
        shear_k = tuple((f"{s}_{a}.stiffness", 1.0) for s in seg for a in ("tx", "ty"))
        shear_d = tuple((f"{s}_{a}.damping", 1.0) for s in seg for a in ("tx", "ty"))
        comp_k = tuple((f"{s}_tz.stiffness", 1.0) for s in seg)
        comp_d = tuple((f"{s}_tz.damping", 1.0) for s in seg)
        mass = ((f"{PREFIX}_0.mass", SPLIT[0]), (f"{PREFIX}_1.mass", SPLIT[1]),
                (f"{root}.mass", SPLIT[2]))  # fmt: skip
        params = (
            NewParameter("mass", M, M / 3, M * 3, "kg", mass),
            NewParameter("shear_stiffness", ks, ks * lo, ks * hi, "N/m", shear_k, scan=1.0),
            NewParameter("shear_damping", ds, ds * 1e-3, ds * 1e3, "N*s/m", shear_d, scan=0.5),
            NewParameter("compression_stiffness", kc, kc * lo, kc * hi, "N/m", comp_k, scan=1.0),
            NewParameter("compression_damping", dc, dc * 1e-3, dc * 1e3, "N*s/m", comp_d,
                         scan=0.5),
        )  # fmt: skip
        grid = tuple((f / F0_HZ) ** 2 for f in SCAN_HZ)
        return [
            Candidate(
                self.name,
                root,
                params,
                {"root": root},
                grid,
                f"{root} as a {N_NODES}-node elastic chain",
            )
        ]

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        new = doc.copy()
        root = candidate.spec["root"]
        p = {q.name: q.initial for q in candidate.parameters}
        M = p["mass"]
        _, com, I_c = link_inertial(new, root)
        from ...model.parameters import set_link_inertial

        set_link_inertial(new, root, M * SPLIT[2], com, I_c)
        add_link(new, GROUND)
        add_link(new, f"{PREFIX}_0", M * SPLIT[0])
        add_link(new, f"{PREFIX}_1", M * SPLIT[1])
        dz = HEIGHT / (N_NODES - 1)
        dof_chain(new, f"{PREFIX}_0", GROUND, f"{PREFIX}_0", TRANSLATIONS, xyz=(0, 0, -HEIGHT),
                  stiffness=[0.0] * 3)  # fmt: skip
        ks, kc = p["shear_stiffness"], p["compression_stiffness"]
        ds, dc = p["shear_damping"], p["compression_damping"]
        for lev, (a, b) in ((1, (f"{PREFIX}_0", f"{PREFIX}_1")), (2, (f"{PREFIX}_1", root))):
            dof_chain(
                new, f"{PREFIX}_{lev}", a, b, TRANSLATIONS, xyz=(0, 0, dz),
                stiffness=[ks, ks, kc], damping=[ds, ds, dc],
            )  # fmt: skip
        return new
