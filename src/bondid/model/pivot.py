"""A rotational parasitic joint whose pivot is a parameter.

Where a guide or a bearing really pivots is seldom known. A rotation ``θ`` about the axis
``a`` through a point ``p`` moves every point of the child as the same rotation through the
joint's pivot ``p₀`` plus the translation ``θ · a × (p₀ − p)``. So the pivot is freed by two
prismatic joints across the axis (directions ``e₁``, ``e₂``, :func:`across`) that *mimic* the
rotation: ``δu_k = d_k · δθ`` with ``d_k = e_k · (a × (p₀ − p))``, i.e.

    p = p₀ + a × (d₁ e₁ + d₂ e₂)       (the pivot, across the axis),

and the multipliers ``d_k`` [m/rad] are ordinary parameters (``JOINT.multiplier``) that enter
the linearised model exactly (:mod:`bondid.linear.coupling`). :func:`free_pivot` adds the two
joints, :func:`pivot_of` reads the pivot they place, :func:`settle_pivot` writes it back as
the joint's own pivot and removes them.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ModelError
from .authoring import insert_parasitic_joint, move_pivot
from .document import UrdfDocument, rotation_and_translation

#: suffixes of the two prismatic joints that carry a free pivot
SUFFIXES = ("_pivot_u", "_pivot_v")


def across(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``(3,)`` across ``axis``, ``(e₁, a × e₁)``: for a coordinate axis the
    next two in cyclic order (x → y, z; y → z, x; z → x, y)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    e1 = np.zeros(3)
    e1[(int(np.argmax(np.abs(a))) + 1) % 3] = 1.0
    e1 = e1 - a * (a @ e1)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def pivot_joints(joint: str) -> tuple[str, str]:
    """The names of the two joints that free ``joint``'s pivot."""
    return (f"{joint}{SUFFIXES[0]}", f"{joint}{SUFFIXES[1]}")


def _revolute(doc: UrdfDocument, joint: str) -> tuple[np.ndarray, np.ndarray]:
    """``(unit axis, pivot p₀)`` (child frame, m) of the parasitic revolute ``joint``."""
    j = doc.joint(joint)
    if j.type not in ("revolute", "continuous"):
        raise ModelError(
            f"{doc.source or '<URDF>'}: joint {joint!r} is {j.type}; a free pivot needs a"
            " revolute parasitic joint"
        )
    a = np.asarray(j.axis, float)
    return a / np.linalg.norm(a), rotation_and_translation(j.origin)[1]


def free_pivot(doc: UrdfDocument, joint: str) -> tuple[str, str]:
    """Free the pivot of the parasitic revolute ``joint`` (module docstring): two prismatic
    joints across its axis, mimicking it with multiplier 0 (the pivot where it is). Edits
    ``doc`` in place; returns their names."""
    import yourdfpy

    a, _ = _revolute(doc, joint)
    names = pivot_joints(joint)
    host = joint
    for name, e in zip(names, across(a), strict=True):
        insert_parasitic_joint(doc, name, after=host, kind="prismatic", axis=tuple(e))
        doc.joint(name).mimic = yourdfpy.Mimic(joint=joint, multiplier=0.0, offset=0.0)
        host = name
    return names


def pivot_of(doc: UrdfDocument, joint: str) -> np.ndarray:
    """The pivot ``(3,)`` (m, the child frame) of ``joint``, with the shift its free-pivot
    joints' multipliers place (module docstring)."""
    a, p0 = _revolute(doc, joint)
    u = np.zeros(3)
    for name, e in zip(pivot_joints(joint), across(a), strict=True):
        if name in doc.joint_names:
            m = doc.joint(name).mimic
            u += (0.0 if m is None or m.multiplier is None else float(m.multiplier)) * e
    return p0 + np.cross(a, u)


def settle_pivot(doc: UrdfDocument, joint: str) -> np.ndarray:
    """Write the pivot the free-pivot joints of ``joint`` place as its own pivot and remove
    them (the model is then the plain parasitic joint, exactly, to first order). Edits
    ``doc`` in place; returns the pivot ``(3,)`` [m]."""
    p = pivot_of(doc, joint)
    for name in reversed(pivot_joints(joint)):
        if name not in doc.joint_names:
            continue
        j = doc.joint(name)
        host = next(h for h in doc.robot.joints if h.child == j.parent)
        host.child = j.child
        doc.robot.joints.remove(j)
        doc.robot.links.remove(doc.link(j.parent))
        doc.extras[:] = [el for el in doc.extras if el.get("reference") != name]
    move_pivot(doc, joint, p)
    return p


def settle_pivots(doc: UrdfDocument) -> list[str]:
    """:func:`settle_pivot` every joint of ``doc`` whose pivot is free; returns their names.
    Edits ``doc`` in place."""
    masters = {m for name, m in doc.mimic_joints().items() if name in pivot_joints(m)}
    for joint in sorted(masters):
        settle_pivot(doc, joint)
    return sorted(masters)


def settled_text(text: str, source: str = "model") -> str:
    """The URDF ``text`` with every free pivot settled (:func:`settle_pivots`); unchanged
    when it has none."""
    if SUFFIXES[0] not in text:
        return text
    doc = UrdfDocument.from_string(text, source=source)
    return doc.to_string() if settle_pivots(doc) else text
