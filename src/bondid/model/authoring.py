"""Structural edits of a :class:`UrdfDocument`: insert a parasitic (compliant) joint.

A parasitic joint Q relaxes the interface between two links. It is inserted on the child side
of the existing joint J (primary or fixed) that connects them, through massless links::

    P --J--> Q_link --Q (origin = pivot)--> C                      (pivot at C's origin)
    P --J--> Q_link --Q (origin = pivot)--> Q_moving --Q_offset (fixed, −pivot)--> C

so C keeps its placement and its parameters. Q gets a Gazebo spring and a damper.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..exceptions import ModelError
from .document import UrdfDocument

_DEFAULT_LIMIT = {"prismatic": 1e-3, "revolute": 1e-2}


def find_joint_between(doc: UrdfDocument, parent: str, child: str) -> str:
    """Name of the joint whose parent link is ``parent`` and child link is ``child``."""
    for j in doc.robot.joints:
        if j.parent == parent and j.child == child:
            return str(j.name)
    pairs = ", ".join(f"{j.parent}->{j.child}" for j in doc.robot.joints)
    raise ModelError(
        f"{doc.source or '<URDF>'}: no joint connects link {parent!r} to link {child!r};"
        f" connected pairs: {pairs}"
    )


def insert_parasitic_joint(
    doc: UrdfDocument,
    name: str,
    *,
    after: str | None = None,
    parent: str | None = None,
    child: str | None = None,
    kind: str = "revolute",
    axis: Sequence[float] = (0.0, 0.0, 1.0),
    pivot: Sequence[float] = (0.0, 0.0, 0.0),
    stiffness: float = 0.0,
    damping: float = 0.0,
    limit: float | None = None,
) -> str:
    """Insert a compliant joint ``name`` after joint ``after`` (or between two links).

    Args:
        doc: the document, edited in place.
        name: the new joint's name; also names the massless links ``name_link`` (and
            ``name_moving`` with the fixed joint ``name_offset`` when ``pivot`` is not 0).
        after: existing joint whose child side is relaxed. Alternatively give ``parent``
            and ``child``, the two links it connects.
        kind: ``"revolute"`` or ``"prismatic"``.
        axis: joint axis in the child link's frame, shape (3,), normalised here.
        pivot: point of the axis in the child link's frame, shape (3,), m.
        stiffness: spring [N/m or N·m/rad], ≥ 0.
        damping: damper [N·s/m or N·m·s/rad], ≥ 0.
        limit: symmetric position limit (m or rad); default 1 mm or 10 mrad.

    Returns:
        The new joint's name.
    """
    import yourdfpy

    where = doc.source or "<URDF>"
    if kind not in _DEFAULT_LIMIT:
        raise ModelError(
            f"{where}: parasitic joint {name!r}: kind {kind!r}; valid: revolute, prismatic"
        )
    if after is None:
        if parent is None or child is None:
            raise ModelError(f"{where}: insert {name!r}: give `after` or both `parent` and `child`")
        after = find_joint_between(doc, parent, child)
    a, p = _check_parasitic(doc, name, axis, pivot, stiffness, damping)
    host = doc.joint(after)
    final_child = host.child
    link_in = f"{name}_link"
    host.child = link_in
    doc.robot.links.append(yourdfpy.Link(name=link_in, inertial=None, visuals=[], collisions=[]))
    lim = _DEFAULT_LIMIT[kind] if limit is None else float(limit)
    has_pivot = bool(np.any(p != 0.0))
    q_child = f"{name}_moving" if has_pivot else final_child
    doc.robot.joints.append(_compliant_joint(name, kind, (link_in, q_child), a, p, damping, lim))
    if has_pivot:
        _offset_back(doc, name, q_child, final_child, p)
    doc.set_stiffness(name, stiffness, reference=0.0)
    return name


def move_pivot(doc: UrdfDocument, name: str, pivot: Sequence[float] | np.ndarray) -> None:
    """Move the pivot of the parasitic joint ``name`` (one :func:`insert_parasitic_joint`
    made) to ``pivot`` (m, shape (3,), the frame the joint was inserted in); the child body
    keeps its placement, the joint its axis, stiffness and damping. Edits ``doc`` in place."""
    where = doc.source or "<URDF>"
    if name not in doc.joint_names:
        raise ModelError(f"{where}: no joint {name!r} to move the pivot of")
    p = np.asarray(pivot, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ModelError(f"{where}: parasitic joint {name!r}: pivot must be a finite 3-vector")
    joint = doc.joint(name)
    offset = f"{name}_offset"
    if offset not in doc.joint_names:  # inserted at its frame's origin: no offset joint yet
        if f"{name}_moving" in doc.link_names:
            raise ModelError(f"{where}: cannot move {name!r}: link {name}_moving already used")
        final_child = joint.child
        joint.child = f"{name}_moving"
        _offset_back(doc, name, joint.child, final_child, p)
    else:
        doc.joint(offset).origin = _translation(-p)
    joint.origin = _translation(p)


def _compliant_joint(
    name: str,
    kind: str,
    links: tuple[str, str],
    axis: np.ndarray,
    pivot: np.ndarray,
    damping: float,
    limit: float,
) -> Any:
    """The ``yourdfpy.Joint`` ``name`` from ``links = (parent, child)``, its origin at
    ``pivot`` (m), unit ``axis``, ``damping`` and position limits ``±limit``."""
    import yourdfpy

    return yourdfpy.Joint(
        name=name,
        type=kind,
        parent=links[0],
        child=links[1],
        origin=_translation(pivot),
        axis=axis / np.linalg.norm(axis),
        dynamics=yourdfpy.Dynamics(damping=float(damping), friction=None),
        limit=yourdfpy.Limit(effort=1e6, velocity=1e3, lower=-limit, upper=limit),
    )


def _translation(p: np.ndarray) -> np.ndarray:
    """The homogeneous transform ``(4, 4)`` of a pure translation by ``p`` (m)."""
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _check_parasitic(
    doc: UrdfDocument,
    name: str,
    axis: Sequence[float],
    pivot: Sequence[float],
    stiffness: float,
    damping: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Check that a parasitic joint's names are free and its axis, pivot, stiffness and
    damping valid; return ``(axis, pivot)`` as float arrays, shape (3,)."""
    where = doc.source or "<URDF>"
    existing = set(doc.link_names) | set(doc.joint_names)
    new_names = {name, f"{name}_link", f"{name}_moving", f"{name}_offset"}
    clash = sorted(new_names & existing)
    if clash:
        raise ModelError(f"{where}: cannot insert {name!r}: names already used: {', '.join(clash)}")
    a = np.asarray(axis, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
        raise ModelError(f"{where}: parasitic joint {name!r}: axis must be a non-zero 3-vector")
    p = np.asarray(pivot, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ModelError(f"{where}: parasitic joint {name!r}: pivot must be a finite 3-vector")
    if stiffness < 0 or damping < 0:
        raise ModelError(f"{where}: parasitic joint {name!r}: stiffness and damping must be ≥ 0")
    return a, p


def _offset_back(
    doc: UrdfDocument, name: str, moving: str, final_child: str, pivot: np.ndarray
) -> None:
    """The massless link ``moving`` and the fixed joint ``name_offset`` that takes the frame
    from the pivot back to the original child's origin."""
    import yourdfpy

    doc.robot.links.append(yourdfpy.Link(name=moving, inertial=None, visuals=[], collisions=[]))
    doc.robot.joints.append(
        yourdfpy.Joint(
            name=f"{name}_offset",
            type="fixed",
            parent=moving,
            child=final_child,
            origin=_translation(-pivot),
        )
    )


def add_floating_base(
    doc: UrdfDocument, joint: str = "floating_base", world: str = "world"
) -> None:
    """Make ``doc`` free-free: a new root link ``world`` and a URDF ``floating`` joint to the
    old root (a free-flyer: six free coordinates, rigid-body modes at 0 Hz, no gravity; see
    :mod:`bondid.linear.affine`). For robots such as solo12 that a URDF writes with their
    base as the root although it is not bolted down. Edits ``doc`` in place."""
    import yourdfpy

    where = doc.source or "<URDF>"
    if any(j.type == "floating" for j in doc.robot.joints):
        raise ModelError(f"{where}: the model already has a floating joint")
    for name, kind in ((world, "link"), (joint, "joint")):
        if name in (doc.link_names if kind == "link" else doc.joint_names):
            raise ModelError(f"{where}: a {kind} named {name!r} exists; choose another name")
    root = doc.root_link()
    rigid = doc.grounded_links()  # the root and what is fixed to it: the floating body
    if not any(doc.link(n).inertial is not None and doc.link(n).inertial.mass for n in rigid):
        raise ModelError(
            f"{where}: the root link {root!r} and the links fixed to it have no mass, so a"
            " floating joint above it would be a DOF without inertia; make the structure's"
            " first body the root (remove a 'ground'/'world' link and the joint below it)"
        )
    doc.robot.links.insert(0, yourdfpy.Link(name=world))
    doc.robot.joints.insert(
        0, yourdfpy.Joint(name=joint, type="floating", parent=world, child=root, origin=np.eye(4))
    )
