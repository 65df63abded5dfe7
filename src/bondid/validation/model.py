"""Checks that a model describes a machine that can exist: :func:`check_model`.

Errors (:class:`ModelError`, exit 2) name the file, the link or joint and what would be valid:

* the tree: a link that is the child of two joints (a kinematic loop), more than one root;
* actuators: no ``<transmission>`` at all, two on one joint, one on a fixed joint;
* joints: a zero or non-finite axis on a moving joint; a spring (``<gazebo reference>``) on a
  fixed joint; a negative or non-finite stiffness or damping;
* magnitudes: every mass, inertia, coordinate, size, spring, damper and joint limit within
  its physical range, and ``lower <= upper`` (:mod:`.magnitudes`);
* bodies: a negative or non-finite mass; an ``<inertial>`` with zero mass on a moving body; a
  negative principal moment of inertia; the triangle inequality ``I₁ + I₂ ≥ I₃`` violated
  (relative tolerance :data:`TRIANGLE_TOL`); a moving joint that moves no mass at all (its
  mass matrix would be singular).

Warnings (returned, the run goes on): a CoM outside its link's collision hull by more than
:data:`COM_OUTSIDE_FRACTION` of the hull's size (real CAD does that; the fit projects the
start into the hull), a mesh that cannot be read for that check.
"""

from __future__ import annotations

import math
import os

import numpy as np

from ..exceptions import BondidError, ModelError
from ..model.document import MOVABLE_TYPES, UrdfDocument, rotation_and_translation
from ..model.parameters import carries_mass
from .magnitudes import check_magnitudes

#: relative tolerance of the triangle inequality (of the trace of the inertia)
TRIANGLE_TOL = 1e-9
#: a CoM farther outside its hull than this fraction of the hull's size is reported
COM_OUTSIDE_FRACTION = 0.1


def _fmt(v: float) -> str:
    return f"{float(v):.6g}"


def check_model(doc: UrdfDocument) -> list[str]:
    """Raise :class:`ModelError` for an impossible model; return the warnings.

    Args:
        doc: the model (its ``source`` names it in the messages).

    Returns:
        Human-readable warnings (possibly empty).
    """
    where = doc.source or "<URDF>"
    _check_tree(doc, where)
    _check_transmissions(doc, where)
    _check_joints(doc, where)
    _check_bodies(doc, where)
    check_magnitudes(doc, where)
    _check_moved_mass(doc, where)
    _check_meshes(doc, where)
    doc.build_pinocchio_model()  # raises ModelError naming the file
    return _com_warnings(doc, where)


def _check_meshes(doc: UrdfDocument, where: str) -> None:
    """Every mesh file named by a path (not ``package://``) must exist, resolved against the
    URDF's folder."""
    base = os.path.dirname(os.path.abspath(doc.source)) if doc.source else os.getcwd()
    for lk in doc.robot.links:
        for el in [*(lk.collisions or []), *(lk.visuals or [])]:
            mesh = getattr(getattr(el, "geometry", None), "mesh", None)
            name = getattr(mesh, "filename", None) if mesh is not None else None
            if not name or name.startswith("package://"):
                continue
            path = name[len("file://") :] if name.startswith("file://") else name
            full = os.path.join(base, path)
            if not os.path.isfile(full):
                raise ModelError(
                    f"{where}: link {lk.name!r}: mesh file {name!r} not found (looked for"
                    f" {full}); valid: a path relative to the URDF's folder, or absolute"
                )


def _check_tree(doc: UrdfDocument, where: str) -> None:
    parents: dict[str, list[str]] = {}
    for j in doc.robot.joints:
        parents.setdefault(j.child, []).append(j.name)
    for link, joints in parents.items():
        if len(joints) > 1:
            raise ModelError(
                f"{where}: kinematic loop: link {link!r} is the child of joints"
                f" {', '.join(map(repr, joints))}; a URDF describes a tree (each link the child"
                " of at most one joint); model a closed chain by cutting it at one joint"
            )
    roots = [n for n in doc.link_names if n not in parents]
    if len(roots) != 1:
        raise ModelError(
            f"{where}: {len(roots)} root links ({', '.join(roots) or 'none: a loop'});"
            " valid: exactly one link that is no joint's child"
        )


def _check_transmissions(doc: UrdfDocument, where: str) -> None:
    tr = doc.transmissions
    if not tr and not doc.points:
        raise ModelError(
            f"{where}: no <transmission> and no measurement point: bondid needs at least one"
            " FRF input; add a ROS <transmission> with an effort interface on one of"
            f" {', '.join(doc.movable_joint_names) or 'the moving joints'} (their order fixes"
            " the FRF channels), or declare points (README: sensors and excitation at points)"
        )
    seen: dict[str, str] = {}
    for t in tr:
        if t.joint in seen:
            raise ModelError(
                f"{where}: joint {t.joint!r} is driven by two transmissions ({seen[t.joint]!r}"
                f" and {t.name!r}); valid: one transmission per joint"
            )
        seen[t.joint] = t.name
        if doc.joint(t.joint).type not in MOVABLE_TYPES:
            raise ModelError(
                f"{where}: transmission {t.name!r} drives joint {t.joint!r}, which is"
                f" {doc.joint(t.joint).type}; valid: a revolute, continuous or prismatic joint"
            )


def _check_joints(doc: UrdfDocument, where: str) -> None:
    springs = doc.springs
    for j in doc.robot.joints:
        moving = j.type in MOVABLE_TYPES
        if moving:
            axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), float)
            if not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-12:
                raise ModelError(
                    f"{where}: joint {j.name!r} has axis {axis.tolist()}; valid: a finite,"
                    " non-zero vector such as '0 0 1'"
                )
        if j.name in springs:
            k = springs[j.name].stiffness
            if not moving:
                raise ModelError(
                    f"{where}: <gazebo reference={j.name!r}> sets a spring on a {j.type} joint;"
                    " valid: springs on revolute, continuous or prismatic joints only"
                )
            if not (math.isfinite(k) and k >= 0):
                raise ModelError(
                    f"{where}: joint {j.name!r} has springStiffness {_fmt(k)}; valid: a finite"
                    " value >= 0 (N/m or N·m/rad)"
                )
        d = None if j.dynamics is None else j.dynamics.damping
        if d is not None and not (math.isfinite(float(d)) and float(d) >= 0):
            raise ModelError(
                f"{where}: joint {j.name!r} has damping {_fmt(d)}; valid: a finite value >= 0"
                " (N·s/m or N·m·s/rad)"
            )


def _check_bodies(doc: UrdfDocument, where: str) -> None:
    grounded = doc.grounded_links()
    for lk in doc.robot.links:
        inertial = lk.inertial
        if inertial is None or not carries_mass(lk):  # a frame written with mass 0: massless
            continue
        m = float(inertial.mass if inertial.mass is not None else 0.0)
        if not math.isfinite(m) or m < 0 or (m == 0 and lk.name not in grounded):
            raise ModelError(
                f"{where}: link {lk.name!r} has mass {_fmt(m)}; valid: a finite mass > 0 for a"
                " moving body (a massless link has no <inertial> element)"
            )
        raw = inertial.inertia
        R, _ = rotation_and_translation(inertial.origin)
        I = R @ (np.zeros((3, 3)) if raw is None else np.asarray(raw, float)) @ R.T
        if not np.all(np.isfinite(I)):
            raise ModelError(f"{where}: link {lk.name!r} has a non-finite inertia tensor")
        ev = np.sort(np.linalg.eigvalsh(0.5 * (I + I.T)))
        scale = max(float(np.abs(ev).max()), 1e-300)
        if ev[0] < -TRIANGLE_TOL * scale:
            raise ModelError(
                f"{where}: link {lk.name!r} has a negative principal moment of inertia"
                f" ({_fmt(ev[0])} kg·m²; moments {', '.join(map(_fmt, ev))}); valid: a"
                " positive semi-definite tensor"
            )
        if ev[0] + ev[1] < ev[2] - TRIANGLE_TOL * float(ev.sum()):
            raise ModelError(
                f"{where}: link {lk.name!r} violates the triangle inequality of its principal"
                f" moments ({', '.join(map(_fmt, ev))} kg·m²: {_fmt(ev[0])} + {_fmt(ev[1])} <"
                f" {_fmt(ev[2])}); no mass distribution has these moments; valid: I₁ + I₂ ≥ I₃"
            )


def _check_moved_mass(doc: UrdfDocument, where: str) -> None:
    children: dict[str, list[str]] = {}
    for j in doc.robot.joints:
        children.setdefault(j.parent, []).append(j.child)

    def mass_below(link: str) -> float:  # a walk, not a recursion: chains may be long
        total, stack, seen = 0.0, [link], set()
        while stack:
            n = stack.pop()
            if n in seen:
                continue
            seen.add(n)
            lk = doc.link(n)
            total += float(lk.inertial.mass or 0.0) if lk.inertial is not None else 0.0
            stack.extend(children.get(n, []))
        return total

    for j in doc.robot.joints:
        if j.type in MOVABLE_TYPES and mass_below(j.child) <= 0:
            raise ModelError(
                f"{where}: joint {j.name!r} moves no mass (link {j.child!r} and the links"
                " beyond it have no <inertial>), so its mass matrix is singular; valid: give"
                " a body it carries a mass and inertia, or make the joint fixed"
            )


def _com_warnings(doc: UrdfDocument, where: str) -> list[str]:
    from ..consistency.hull import link_hull
    from ..model.packages import mesh_resolver

    resolve = mesh_resolver(doc)  # meshes found as every command finds them
    out: list[str] = []
    for lk in doc.robot.links:
        if lk.inertial is None or not (lk.inertial.mass or 0.0) > 0:
            continue
        try:
            hull = link_hull(lk, resolve, name=lk.name)
        except (BondidError, OSError, ValueError) as exc:
            out.append(f"{where}: link {lk.name!r}: CoM-in-geometry check skipped ({exc})")
            continue
        if hull is None:
            continue
        _, c = rotation_and_translation(lk.inertial.origin)
        outside = float(np.max(hull.A @ c - hull.b))
        size = float(np.linalg.norm(np.ptp(hull.vertices, axis=0)))
        if outside > COM_OUTSIDE_FRACTION * size:
            out.append(
                f"{where}: link {lk.name!r}: the CoM ({', '.join(map(_fmt, c))}) m lies"
                f" {_fmt(outside)} m outside its collision geometry (size {_fmt(size)} m);"
                " check the <inertial> origin (a fit projects it into the geometry)"
            )
    return out
