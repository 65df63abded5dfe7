"""``soft_mounts``: the base on compliant feet (6-DOF springs to ground) instead of grounded.

The grounded root body becomes movable: a new root link ``ground`` carries it through three
prismatic (x, y, z) and three revolute (x, y, z) sprung, damped joints whose axes pass through
one point, the mounts' elastic centre (``soft_mount_tx`` ... ``soft_mount_rz``), so the base's
mass and inertia now matter and the drives' reactions rock it. One candidate, located at the
root body.

Where the elastic centre lies is seldom known, and it enters the kinematics (a centre below
the CoM couples a horizontal translation with a rocking rotation), so the candidate carries
variants (:attr:`~.base.Candidate.variants`, screened like the pivots of a rotational joint
compliance): the centre at the root body's CoM (the candidate itself), below the CoM on the
bottom face of the root's collision hull (where a machine's feet stand), and at the centre of
that bottom face (:func:`centre_options`).

New parameters: the six mount stiffnesses (per direction, all independent: real mounts are
seldom equal) and six damping ratios, one per direction too (``zeta_tx`` ... ``zeta_rz``;
each joint's damper is ``2·ζ·√(k₀·m)`` with ``k₀`` the start stiffness and ``m`` the
machine's mass or the base's principal inertia about the centre). The start puts every mount
mode at 30 Hz, 5 % damping; the scan moves them together from 2 Hz to 500 Hz.

Why a damping per direction: the damper is linear in its parameter, so ``ζ`` is a damping
ratio at the start stiffness only; once the fit moves each stiffness its own way, mounts of
equal damping ratio (rubber, whose loss factor is much the same in every direction) have
dampers in the ratio of ``√(k·m)``, which one ratio shared by three directions cannot follow.
With mounts of the same 4 % damping in every direction and the true stiffnesses, two shared
ratios leave errors of up to 2 dB in the cross channels near the rocking modes, where one
ratio per direction leaves none. The price: a mount direction the data do not show is not
determined (its spring and damper may go anywhere at the same cost).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...model.document import UrdfDocument
from ...model.parameters import link_inertial
from . import register
from ._chain import ROTATIONS, TRANSLATIONS, add_link, dof_chain, total_mass
from .base import Candidate, Effect, NewParameter
from .topology import link_box

F0_HZ = 30.0
ZETA = 0.05
SCAN_HZ = tuple(float(f) for f in np.geomspace(2.0, 500.0, 58))
PREFIX = "soft_mount"
GROUND = "ground"
#: elastic centres closer than this to one already listed are not tried again [m]
CENTRE_TOL = 0.003


def centre_options(doc: UrdfDocument, root: str, com: np.ndarray) -> list[np.ndarray]:
    """Elastic centres (root frame, m) to try: the root's CoM, then the point of the bottom
    face of its collision hull below the CoM and that face's centre (none without a hull)."""
    out = [np.asarray(com, float)]
    box = link_box(doc, root)
    if box is not None:
        lo, hi = box
        for p in (np.array([com[0], com[1], lo[2]]), np.r_[(lo[:2] + hi[:2]) / 2, lo[2]]):
            if all(np.linalg.norm(p - q) > CENTRE_TOL for q in out):
                out.append(p)
    return out


def _inertias(m: float, com: np.ndarray, I_c: np.ndarray, centre: np.ndarray) -> list[float]:
    """Mass (x3) and the root's principal inertias about ``centre`` (parallel axes with the
    machine's mass ``m``): the scale of each mount DOF."""
    d = np.asarray(com, float) - np.asarray(centre, float)
    I_p = np.diag(I_c) + m * (d @ d - d**2)
    return [m, m, m, *np.maximum(I_p, 1e-9)]


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
        main, *others = (
            self._candidate(root, c, _inertias(m, com, I_c, c), k)
            for k, c in enumerate(centre_options(doc, root, com))
        )
        return [replace(main, variants=tuple(others))]

    def _candidate(self, root: str, centre: np.ndarray, inert: list[float], k: int) -> Candidate:
        w = 2 * np.pi * F0_HZ
        params = []
        for (ax, _, _), mi in zip(TRANSLATIONS + ROTATIONS, inert, strict=True):
            k0 = mi * w**2
            unit = "N/m" if ax[0] == "t" else "N*m/rad"
            params.append(
                NewParameter(
                    f"stiffness_{ax}", k0, k0 * (0.3 / F0_HZ) ** 2, k0 * (3000 / F0_HZ) ** 2,
                    unit, ((f"{PREFIX}_{ax}.stiffness", 1.0),), scan=1.0, strength=True,
                )
            )  # fmt: skip
        for (ax, _, _), p, mi in zip(TRANSLATIONS + ROTATIONS, params[:6], inert, strict=True):
            member = ((f"{PREFIX}_{ax}.damping", 2.0 * np.sqrt(p.initial * mi)),)
            params.append(NewParameter(f"zeta_{ax}", ZETA, 1e-4, 2.0, "1", member, scan=0.5))
        spec = {"root": root, "centre": [float(x) for x in centre]}
        grid = tuple((f / F0_HZ) ** 2 for f in SCAN_HZ)
        where = "CoM" if k == 0 else f"elastic centre {np.round(centre * 1e3, 1).tolist()} mm"
        return Candidate(
            self.name, root, tuple(params), spec, grid, f"{root} on 6-DOF mounts about {where}",
            F0_HZ,
        )  # fmt: skip

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        new = doc.copy()
        root = candidate.spec["root"]
        centre = np.asarray(candidate.spec["centre"], float)
        add_link(new, GROUND)
        p = {q.name: q for q in candidate.parameters}
        axes = [ax for ax, _, _ in TRANSLATIONS + ROTATIONS]
        ks = [p[f"stiffness_{ax}"].initial for ax in axes]
        ds = [0.0] * 6
        dampers = [f"{PREFIX}_{ax}.damping" for ax in axes]
        for q in candidate.parameters:
            for m, fac in q.members:
                if m.endswith(".damping"):
                    ds[dampers.index(m)] = fac * q.initial
        dof_chain(
            new, PREFIX, GROUND, root, TRANSLATIONS + ROTATIONS, xyz=list(centre),
            back=list(-centre), stiffness=ks, damping=ds,
        )  # fmt: skip
        return new
