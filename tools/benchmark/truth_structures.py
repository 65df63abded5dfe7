"""Truth builders of the structural causes beyond the first five, each built unlike the
diagnosis's candidate for it (or with no candidate at all):

- ``drive_spring`` (a cable carrier): the drive's spring to its parent (the carrier's
  stiffness, 10 % damped) *and* the carrier's own moving mass, 8 % of what the drive moves,
  hung on the stage by a lossy spring (30 % damped) along the drive, its mode 5× the
  suspension's (the candidate: a spring and damper on the drive alone);
- ``flexible_link`` (a bending arm): the link as three rigid segments hinged at a third and
  two thirds of its collision hull's length, bending stiffness 1 : 1.6 about its two cross
  axes, the first bending mode at the given frequency (the candidate: one hinge, at a
  quarter, half or three quarters of the way from the link's origin to the far end of its
  equivalent-inertia box);
- ``attached_mass`` (outside the library: a hose loop, a loose cover, a motor coil on a soft
  mount): an extra body of a share of a stage's mass on a damped spring along the stage's
  drive, 3 % damped.
"""

from __future__ import annotations

import numpy as np

from bondid.diagnose.effects._chain import add_link, dof_chain
from bondid.diagnose.effects.topology import (
    carried_body,
    effective_inertia,
    interfaces,
    joint_axis,
    link_box,
)
from bondid.model import UrdfDocument
from bondid.model.document import rotation_and_translation
from bondid.model.parameters import link_inertial, set_link_inertial


def drive_axis(doc: UrdfDocument, joint: str, frame: str) -> np.ndarray:
    """The unit axis ``(3,)`` of ``joint`` in ``frame``'s axes at q = 0."""
    return joint_axis(doc, joint, frame)


def moved_body(doc: UrdfDocument, joint: str) -> str:
    """The body (a link with mass) that ``joint`` carries first."""
    return carried_body(doc, joint)


def add_cable_carrier(doc: UrdfDocument, joint: str, f: float) -> UrdfDocument:
    """The cable carrier of the module docstring on the drive ``joint``: its suspension
    mode (the spring alone on the drive's effective inertia) at ``f`` Hz."""
    out = doc.copy()
    m = effective_inertia(out, joint)
    k = m * (2 * np.pi * f) ** 2
    out.set_stiffness(joint, k, reference=0.0)
    out.set_damping(joint, out.damping(joint) + 2 * 0.10 * np.sqrt(k * m))
    body = moved_body(out, joint)
    axis = tuple(float(v) for v in drive_axis(out, joint, body))
    mc = 0.08 * m
    add_link(out, "truth_carrier", mc, radius=0.02)
    ka = mc * (2 * np.pi * 5 * f) ** 2
    dof_chain(out, "truth_carrier", body, "truth_carrier", [("t", "prismatic", axis)],
              stiffness=[ka], damping=[2 * 0.30 * np.sqrt(ka * mc)])  # fmt: skip
    return out


def add_attached_mass(doc: UrdfDocument, body: str, f: float, share: float) -> UrdfDocument:
    """The attached mass of the module docstring: ``share`` × ``body``'s mass on a spring
    whose mode (on that mass alone) is at ``f`` Hz, along the drive that moves ``body``."""
    out = doc.copy()
    m, c, _ = link_inertial(out, body)
    drive = next(i for i in interfaces(out) if i.child == body).joints[0]
    axis = tuple(float(v) for v in drive_axis(out, drive, body))
    ma = share * m
    add_link(out, "truth_appendage", ma, radius=0.02)
    k = ma * (2 * np.pi * f) ** 2
    dof_chain(out, "truth_appendage", body, "truth_appendage", [("t", "prismatic", axis)],
              xyz=list(c),
              stiffness=[k], damping=[2 * 0.03 * np.sqrt(k * ma)])  # fmt: skip
    return out


def add_bending_arm(doc: UrdfDocument, link: str, f: float) -> UrdfDocument:
    """The bending arm of the module docstring: ``link`` cut into three segments at a third
    and two thirds of its collision hull's length (the parts of its equivalent box,
    :mod:`bondid.diagnose.effects.link_split`, so that they add up to the link exactly);
    the hinges' springs in the ratios of their effective inertias (1 : 1/1.6 about the two
    cross axes) and scaled together so that the first bending mode of the arm clamped at its
    root (:func:`first_mode_hz`) is at ``f`` Hz, 2 % damped."""
    from dataclasses import replace

    from bondid.diagnose.effects.link_split import Inertial, long_axis, split_inertial

    out = doc.copy()
    ax = long_axis(out, link)
    box = link_box(out, link)
    if ax is None or box is None:
        raise ValueError(f"{doc.source}: link {link!r} is not a long body with a hull to cut")
    lo, hi = (np.asarray(b, float) for b in box)
    corners = np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)])  # fmt: skip
    u = (corners - ax.centre) @ ax.axis
    h = float(ax.half[0])
    cuts = [float(np.clip(u.min() + k / 3 * (u.max() - u.min()), -h, h)) for k in (1, 2)]
    m, c, I_c = link_inertial(out, link)
    near, rest = split_inertial(Inertial(m, c, I_c), ax, cuts[0])
    rest_ax = replace(ax, centre=ax.point(0.5 * (cuts[0] + h)),
                      half=np.r_[0.5 * (h - cuts[0]), ax.half[1:]])  # fmt: skip
    mid, tip = split_inertial(rest, rest_ax, cuts[1] - 0.5 * (cuts[0] + h))
    segs = [link, f"{link}_truth_mid", f"{link}_truth_tip"]
    at = [np.zeros(3), ax.point(cuts[0]), ax.point(cuts[1])]
    set_link_inertial(out, link, near.mass, near.com, near.inertia)
    for s, part in ((1, mid), (2, tip)):
        add_link(out, segs[s], part.mass)
        set_link_inertial(out, segs[s], part.mass, part.com - at[s], part.inertia)
    for j in out.robot.joints:  # the children ride on the segment they sit in
        if j.parent != link:
            continue
        p = rotation_and_translation(j.origin)[1] if j.origin is not None else np.zeros(3)
        s = int(np.searchsorted(cuts, float((p - ax.centre) @ ax.axis)))
        if s > 0:
            origin = np.asarray(j.origin, float).copy()
            origin[:3, 3] = p - at[s]
            j.parent, j.origin = segs[s], origin
    hinges = []
    for s in (1, 2):
        dofs = [(f"b{i + 1}", "revolute", tuple(float(x) for x in v))
                for i, v in enumerate(ax.across)]  # fmt: skip
        hinges += dof_chain(out, f"{link}_truth_hinge{s}", segs[s - 1], segs[s], dofs,
                            xyz=list(at[s] - at[s - 1]), stiffness=[1.0, 1.0],
                            damping=[0.0, 0.0])  # fmt: skip
    inertias = [effective_inertia(out, jn) for jn in hinges]
    ratios = (1.0, 1 / 1.6, 1.0, 1 / 1.6)
    scale = 1.0
    for _ in range(4):  # the hinges' springs scaled together until the first mode is at f
        for jn, mi, ratio in zip(hinges, inertias, ratios, strict=True):
            k = mi * (2 * np.pi * f) ** 2 * ratio * scale
            out.set_stiffness(jn, k)
            out.set_damping(jn, 2 * 0.02 * np.sqrt(k * mi))
        scale *= (f / first_mode_hz(out, link)) ** 2
    return out


def first_mode_hz(doc: UrdfDocument, link: str) -> float:
    """The first mode [Hz] of everything ``link`` carries (its own DOFs downstream) with its
    root clamped (the DOFs upstream locked), neutral configuration, undamped: a cantilever's
    first bending mode when ``link`` is cut by hinges. Rigid-body modes (a free drive
    downstream) are skipped."""
    import scipy.linalg

    from bondid.linear.affine import build_affine_model

    below, grew = {link}, True
    while grew:
        grew = False
        for j in doc.robot.joints:
            if j.parent in below and j.child not in below:
                below.add(j.child)
                grew = True
    am = build_affine_model(doc)
    joints = {j.name for j in doc.robot.joints if j.parent in below}
    idx = [k for k, d in enumerate(am.dofs) if d in joints]
    K = am.stiffness_matrix()[np.ix_(idx, idx)]
    M = am.mass_matrix()[np.ix_(idx, idx)]
    w2 = scipy.linalg.eigh(0.5 * (K + K.T), M, eigvals_only=True)
    return float(np.sqrt(w2[w2 > (2 * np.pi * 0.1) ** 2].min()) / (2 * np.pi))
