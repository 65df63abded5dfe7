"""Small URDF edits shared by the effects that free the grounded root: a chain of 1-DOF
joints (through massless links) from a new ground link to the old root."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...exceptions import ModelError
from ...model.document import UrdfDocument


def add_link(doc: UrdfDocument, name: str, mass: float = 0.0, radius: float = 0.01) -> None:
    """Append a link; with ``mass > 0`` a point-like inertial (sphere of ``radius`` m)."""
    import yourdfpy

    if name in doc.link_names:
        raise ModelError(f"{doc.source or '<URDF>'}: link {name!r} already exists")
    inertial = None
    if mass > 0:
        inertial = yourdfpy.Inertial(
            origin=np.eye(4), mass=float(mass), inertia=np.eye(3) * 0.4 * mass * radius**2
        )
    doc.robot.links.append(yourdfpy.Link(name=name, inertial=inertial, visuals=[], collisions=[]))


def add_joint(
    doc: UrdfDocument,
    name: str,
    kind: str,
    parent: str,
    child: str,
    *,
    axis: Sequence[float] = (1.0, 0.0, 0.0),
    xyz: Sequence[float] = (0.0, 0.0, 0.0),
    stiffness: float | None = None,
    damping: float = 0.0,
    limit: float = 0.01,
) -> None:
    """Append a joint ``parent → child`` at ``xyz`` (parent frame); a spring when given."""
    import yourdfpy

    if name in doc.joint_names:
        raise ModelError(f"{doc.source or '<URDF>'}: joint {name!r} already exists")
    T = np.eye(4)
    T[:3, 3] = np.asarray(xyz, float)
    movable = kind != "fixed"
    doc.robot.joints.append(
        yourdfpy.Joint(
            name=name,
            type=kind,
            parent=parent,
            child=child,
            origin=T,
            axis=np.asarray(axis, float) if movable else None,
            dynamics=yourdfpy.Dynamics(damping=float(damping), friction=None) if movable else None,
            limit=yourdfpy.Limit(effort=1e6, velocity=1e3, lower=-limit, upper=limit)
            if movable
            else None,
        )
    )
    if movable and stiffness is not None:
        doc.set_stiffness(name, float(stiffness), reference=0.0)


def dof_chain(
    doc: UrdfDocument,
    prefix: str,
    parent: str,
    child: str,
    dofs: Sequence[tuple[str, str, Sequence[float]]],
    *,
    xyz: Sequence[float] = (0.0, 0.0, 0.0),
    back: Sequence[float] | None = None,
    stiffness: Sequence[float | None] | None = None,
    damping: Sequence[float] | None = None,
) -> list[str]:
    """Join ``parent`` to ``child`` through 1-DOF joints ``{prefix}_{suffix}`` (massless links
    between them); the first sits at ``xyz`` in the parent frame, and a fixed joint at
    ``back`` (child side) ends the chain when given. ``dofs`` = ``[(suffix, kind, axis)]``.
    Returns the new joint names."""
    names = []
    link = parent
    n = len(dofs)
    for i, (suffix, kind, axis) in enumerate(dofs):
        jn = f"{prefix}_{suffix}"
        last = i == n - 1 and back is None
        nxt = child if last else f"{jn}_link"
        if not last:
            add_link(doc, nxt)
        add_joint(
            doc, jn, kind, link, nxt, axis=axis, xyz=xyz if i == 0 else (0.0, 0.0, 0.0),
            stiffness=None if stiffness is None else stiffness[i],
            damping=0.0 if damping is None else damping[i],
        )  # fmt: skip
        names.append(jn)
        link = nxt
    if back is not None:
        add_joint(doc, f"{prefix}_offset", "fixed", link, child, xyz=back)
    return names


TRANSLATIONS = (("tx", "prismatic", (1.0, 0.0, 0.0)), ("ty", "prismatic", (0.0, 1.0, 0.0)),
                ("tz", "prismatic", (0.0, 0.0, 1.0)))  # fmt: skip
ROTATIONS = (("rx", "revolute", (1.0, 0.0, 0.0)), ("ry", "revolute", (0.0, 1.0, 0.0)),
             ("rz", "revolute", (0.0, 0.0, 1.0)))  # fmt: skip


def total_mass(doc: UrdfDocument) -> float:
    return float(sum(float(lk.inertial.mass or 0.0) for lk in doc.robot.links if lk.inertial))
