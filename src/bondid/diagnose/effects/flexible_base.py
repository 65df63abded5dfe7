"""``flexible_base``: the elastic base or chassis, lumped.

The report models the base as a block of height L whose horizontal (shear) and vertical
(compression) motion propagates as waves, with a stress-free bottom (weak legs), and suggests
"a small number of individual masses linked by springs and dampers". That is what is built
here: the grounded root body becomes the top node of a chain of ``N = 6`` lumped masses joined
by shear springs (x, y) and compression springs (z) with dampers; the bottom node is free to
translate (stress-free bottom: zero-stiffness joints to a new root ``ground``). The stages
ride on the top node (the original root link). Node masses start at the consistent lumping
of a uniform rod, ``M·(0.1, 0.2, 0.2, 0.2, 0.2, 0.1)``, so each direction has a rigid-body
translation and five wave-like elastic modes at frequency ratios 1 : 1.9 : 2.6 : 3.1 : 3.2
(the continuum's 1 : 2 : 3 : 4 : 5 compressed at the top, as any lumping). (The continuous
``coth`` impedance of the report is not used: the lumped chain keeps the model an ordinary
URDF that can be written out, and its first modes follow the continuum's.) A real chassis is
not square, so the two shear directions have their own stiffness.

Why six nodes, and a four-node variant: a measured band usually holds more of a chassis'
wave modes than the first two or three, and a chain has ``N − 1`` per direction; but a chain
whose shape is not the chassis' may stall where a shorter one fits, and neither length fits
every chassis best. So the candidate carries a four-node chain as its variant
(:data:`VARIANT_NODES`; ``spec["nodes"]`` tells them apart); the node masses differ, so the
variant gets starts of its own (:func:`..refit_job.screening_starts`), and a refit tries the
best-figured starts of both.

Joints: ``flexible_base_{level}_{tx,ty,tz}``, level 0 the free bottom, 1 … N−1 the elastic
segments; links ``flexible_base_0`` (bottom) … ``flexible_base_{N−2}``. One candidate, located
at the root body. New parameters: the mass of every node, each on its own (``node{i}_mass``,
bottom first, then ``top_mass``, the root link's; the uniform rod's shares of ``M`` at the
start, M the root body's mass in the model), shear stiffness in x and in y, one shear damper
(every segment, both directions), compression stiffness and damper. The masses are free
because the model's value says little about them: a grounded root's inertia has no effect on
the nominal model's FRF, so no fit of it ever tested that mass (it is often a placeholder, and
it is as uncertain as any other mass), and a real chassis is seldom a uniform rod (a heavy bed
plate puts its mass low, a top plate high; the share that rides with the stages sets how
strongly the chain's modes show in the drives' FRFs, the distribution the ratios of the
modes); held at the rod's shares, the true chain's refit of a chassis heavier at the bottom
stays well above the truth model's figure. Start: first
shear modes at 1 kHz (compression 3.5× stiffer, as for ν ≈ 0.3), 2 % damping; the scan moves
all stiffnesses together from 100 Hz to 12 kHz (:mod:`..starts`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np

from ...exceptions import ConfigError
from ...model.document import UrdfDocument
from ...model.parameters import link_inertial
from . import register
from ._chain import TRANSLATIONS, add_link, dof_chain
from .base import Candidate, Effect, NewParameter

N_NODES = 6
#: the lengths of the candidate's variants (:attr:`~.base.Candidate.variants`)
VARIANT_NODES = (4,)
F0_HZ = 1000.0
ZETA = 0.02
COMPRESSION_RATIO = 3.5
HEIGHT = 0.1
SCAN_HZ = tuple(float(f) for f in np.geomspace(100.0, 12000.0, 50))
PREFIX = "flexible_base"
GROUND = "ground"
#: every node mass may move by this factor either way from its start
MASS_SPAN = 5.0


def rod_shares(n_nodes: int) -> np.ndarray:
    """Consistent lumping of a uniform rod on ``n_nodes`` nodes, bottom … top, shape
    ``(n_nodes,)`` (sum 1): the ends ``1/(2(N−1))``, the inner nodes ``1/(N−1)``."""
    n = int(n_nodes)
    return np.array([(0.5 if i in (0, n - 1) else 1.0) / (n - 1) for i in range(n)])


def first_mode_w2(masses: np.ndarray) -> float:
    """First elastic ω² [rad²/s²] of a free-free chain of ``masses`` [kg] joined by unit
    springs [N/m]."""
    n = masses.size
    K = np.zeros((n, n))
    for i in range(n - 1):
        K[i : i + 2, i : i + 2] += [[1.0, -1.0], [-1.0, 1.0]]
    w2 = np.linalg.eigvalsh(K / np.sqrt(np.outer(masses, masses)))
    return float(np.sort(w2)[1])


@register
class FlexibleBase(Effect):
    name = "flexible_base"
    description = "elastic base/chassis: lumped shear/compression chain"

    def __init__(
        self, n_nodes: int = N_NODES, variant_nodes: Iterable[int] = VARIANT_NODES
    ) -> None:
        """``n_nodes``: the chain's lumped masses, the root body the top one (≥ 2);
        ``variant_nodes``: the lengths of the candidate's variants (each ≥ 2; any iterable)."""
        if isinstance(variant_nodes, (str, bytes)) or not hasattr(variant_nodes, "__iter__"):
            raise ConfigError(
                f"flexible_base: variant_nodes={variant_nodes!r} is not valid; a tuple of"
                " integers ≥ 2 is"
            )
        variant_nodes = tuple(variant_nodes)  # a generator is iterated once, here
        lengths = [("n_nodes", n_nodes), *(("variant_nodes", n) for n in variant_nodes)]
        for what, n in lengths:
            if isinstance(n, bool) or not isinstance(n, int) or n < 2:
                raise ConfigError(f"flexible_base: {what} holds {n!r}; an integer ≥ 2 is valid")
        self.n_nodes = n_nodes
        self.variant_nodes = tuple(n for n in dict.fromkeys(variant_nodes) if n != n_nodes)

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        root = doc.root_link()
        lk = doc.link(root)
        if lk.inertial is None or not (lk.inertial.mass or 0) > 0:
            return []
        M = float(lk.inertial.mass)
        main = self._candidate(root, M, self.n_nodes)
        others = tuple(self._candidate(root, M, n) for n in self.variant_nodes)
        return [replace(main, variants=others)]

    def _candidate(self, root: str, M: float, n: int) -> Candidate:
        """The root body ``root`` (mass ``M`` [kg]) as an ``n``-node chain."""
        w = 2 * np.pi * F0_HZ
        split = rod_shares(n)
        m_eff = M * split[0]
        ks = M * w**2 / first_mode_w2(split)
        kc = COMPRESSION_RATIO * ks
        ds, dc = 2 * ZETA * np.sqrt(ks * m_eff), 2 * ZETA * np.sqrt(kc * m_eff)
        lo, hi = (30.0 / F0_HZ) ** 2, (40000.0 / F0_HZ) ** 2
        seg = [f"{PREFIX}_{lev}" for lev in range(1, n)]
        shear_kx = tuple((f"{s}_tx.stiffness", 1.0) for s in seg)
        shear_ky = tuple((f"{s}_ty.stiffness", 1.0) for s in seg)
        shear_d = tuple((f"{s}_{a}.damping", 1.0) for s in seg for a in ("tx", "ty"))
        comp_k = tuple((f"{s}_tz.stiffness", 1.0) for s in seg)
        comp_d = tuple((f"{s}_tz.damping", 1.0) for s in seg)
        nodes = [f"{PREFIX}_{i}" for i in range(n - 1)] + [root]
        masses = tuple(
            NewParameter(
                "top_mass" if node == root else f"node{i}_mass", M * share,
                M * share / MASS_SPAN, M * share * MASS_SPAN, "kg", ((f"{node}.mass", 1.0),),
            )
            for i, (node, share) in enumerate(zip(nodes, split, strict=True))
        )  # fmt: skip
        params = (
            *masses,
            NewParameter("shear_x_stiffness", ks, ks * lo, ks * hi, "N/m", shear_kx, scan=1.0,
                         strength=True),
            NewParameter("shear_y_stiffness", ks, ks * lo, ks * hi, "N/m", shear_ky, scan=1.0,
                         strength=True),
            NewParameter("shear_damping", ds, ds * 1e-3, ds * 1e3, "N*s/m", shear_d, scan=0.5),
            NewParameter("compression_stiffness", kc, kc * lo, kc * hi, "N/m", comp_k, scan=1.0,
                         strength=True),
            NewParameter("compression_damping", dc, dc * 1e-3, dc * 1e3, "N*s/m", comp_d,
                         scan=0.5),
        )  # fmt: skip
        grid = tuple((f / F0_HZ) ** 2 for f in SCAN_HZ)
        return Candidate(
            self.name, root, params, {"root": root, "nodes": n}, grid,
            f"{root} as a {n}-node elastic chain",
            F0_HZ,
        )  # fmt: skip

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        new = doc.copy()
        root = candidate.spec["root"]
        p = {q.name: q.initial for q in candidate.parameters}
        _, com, I_c = link_inertial(new, root)
        from ...model.parameters import set_link_inertial

        set_link_inertial(new, root, p["top_mass"], com, I_c)
        add_link(new, GROUND)
        n = sum(q.name.endswith("_mass") for q in candidate.parameters)  # the candidate's
        nodes = [f"{PREFIX}_{i}" for i in range(n - 1)]
        for i, node in enumerate(nodes):
            add_link(new, node, p[f"node{i}_mass"])
        nodes.append(root)
        dz = HEIGHT / (n - 1)
        dof_chain(new, f"{PREFIX}_0", GROUND, nodes[0], TRANSLATIONS, xyz=(0, 0, -HEIGHT),
                  stiffness=[0.0] * 3)  # fmt: skip
        k = [p["shear_x_stiffness"], p["shear_y_stiffness"], p["compression_stiffness"]]
        d = [p["shear_damping"], p["shear_damping"], p["compression_damping"]]
        for lev in range(1, n):
            dof_chain(
                new, f"{PREFIX}_{lev}", nodes[lev - 1], nodes[lev], TRANSLATIONS, xyz=(0, 0, dz),
                stiffness=k, damping=d,
            )  # fmt: skip
        return new
