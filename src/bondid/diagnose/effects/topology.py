"""The interfaces of a model: which bodies are joined, through which joints, along which axes.

A *body* is a link with a positive mass, or the root link. Between a body and the body it is
mounted on, the kinematic chain runs through massless links (the primary joint, the parasitic
joints and their fixed offsets). That chain is an *interface*; the axes along which it already
moves (``tx ty tz rx ry rz`` in the child body's frame at the neutral configuration) are its
compliant (or driven) directions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...exceptions import ModelError
from ...model.document import MOVABLE_TYPES, UrdfDocument, rotation_and_translation

AXES: tuple[str, ...] = ("tx", "ty", "tz", "rx", "ry", "rz")
_ALIGN = 0.99


@dataclass(frozen=True)
class Interface:
    """The chain joining body ``parent`` to body ``child``.

    Attributes:
        parent, child: body link names.
        joints: joint names from ``parent`` to ``child``.
        last_joint: the joint whose child link is ``child`` (new joints go after it).
        present: axes (``tx`` ... ``rz``) the chain already moves along, child frame.
        pivots: ``(n, 3)`` positions of its revolute joints in the child frame [m].
    """

    parent: str
    child: str
    joints: tuple[str, ...]
    last_joint: str
    present: frozenset[str]
    pivots: np.ndarray

    @property
    def missing(self) -> list[str]:
        """Axes with no joint yet, in ``AXES`` order."""
        return [a for a in AXES if a not in self.present]

    def pivot(self, doc: UrdfDocument) -> np.ndarray:
        """Point for a new rotational joint (child frame): the mean of the chain's revolute
        parasitic pivots (the bearing centre), else the child's CoM, else its origin."""
        if self.pivots.size:
            return np.asarray(self.pivots.mean(axis=0))
        lk = doc.link(self.child)
        if lk.inertial is not None:
            return rotation_and_translation(lk.inertial.origin)[1]
        return np.zeros(3)


def bodies(doc: UrdfDocument) -> list[str]:
    """Links with a positive mass, plus the root link (file order)."""
    root = doc.root_link()
    out = []
    for lk in doc.robot.links:
        m = 0.0 if lk.inertial is None else float(lk.inertial.mass or 0.0)
        if m > 0 or lk.name == root:
            out.append(lk.name)
    return out


def interfaces(doc: UrdfDocument) -> list[Interface]:
    """Every interface between two bodies (child bodies in file order)."""
    parent_joint = {j.child: j for j in doc.robot.joints}
    body_set = set(bodies(doc))
    out = []
    for child in bodies(doc):
        if child not in parent_joint:
            continue
        chain = []
        link = child
        while True:
            j = parent_joint[link]
            chain.append(j)
            link = j.parent
            if link in body_set or link not in parent_joint:
                break
        chain.reverse()
        # transforms of each joint frame relative to the parent body, at q = 0
        T = np.eye(4)
        frames = []
        for j in chain:
            Tj = np.eye(4) if j.origin is None else np.asarray(j.origin, float)
            T = T @ Tj
            frames.append(T.copy())
        Tc = T  # child body frame
        Rc, pc = Tc[:3, :3], Tc[:3, 3]
        present: set[str] = set()
        pivots = []
        for j, F in zip(chain, frames, strict=True):
            if j.type == "floating":  # a free-free structure's base: free along every axis
                present.update(AXES)
                continue
            if j.type not in MOVABLE_TYPES or getattr(j, "mimic", None) is not None:
                continue  # a mimic joint follows another (a free pivot): no DOF of its own
            axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), float)
            a = Rc.T @ (F[:3, :3] @ (axis / np.linalg.norm(axis)))
            k = int(np.argmax(np.abs(a)))
            if abs(a[k]) >= _ALIGN:
                present.add(("t" if j.type == "prismatic" else "r") + "xyz"[k])
            if j.type != "prismatic" and j is not chain[0]:
                pivots.append(Rc.T @ (F[:3, 3] - pc))
        out.append(
            Interface(
                parent=link,
                child=child,
                joints=tuple(j.name for j in chain),
                last_joint=chain[-1].name,
                present=frozenset(present),
                pivots=np.array(pivots).reshape(-1, 3),
            )
        )
    return out


def axis_vector(axis: str) -> tuple[str, np.ndarray]:
    """``"ry"`` → (``"revolute"``, (0, 1, 0)); ``"tx"`` → (``"prismatic"``, (1, 0, 0))."""
    kind = "prismatic" if axis[0] == "t" else "revolute"
    v = np.zeros(3)
    v["xyz".index(axis[1])] = 1.0
    return kind, v


def effective_inertia(doc: UrdfDocument, joint: str) -> float:
    """Inertia seen by a spring on ``joint`` with every other DOF free: ``1/(M⁻¹)_jj``
    [kg or kg·m²], from the linearised model at the neutral configuration; 0 when the mass
    matrix is singular (the DOF moves nothing another DOF does not already move: a spring
    there has no mode, and a candidate there nothing to show)."""
    from ...linear.affine import build_affine_model

    am = build_affine_model(doc)
    if joint not in am.dofs:
        raise ModelError(
            f"{doc.source or '<URDF>'}: no DOF {joint!r} to weigh; valid: {', '.join(am.dofs)}"
        )
    M = am.mass_matrix()
    j = am.dofs.index(joint)
    try:
        flexibility = float(np.linalg.inv(M)[j, j])
    except np.linalg.LinAlgError:
        return 0.0
    if not (np.isfinite(flexibility) and flexibility > 0):
        return 0.0
    return 1.0 / flexibility


def link_box(doc: UrdfDocument, link: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Lower and upper corners (m, ``link``'s frame) of the bounding box of its collision hull
    (:func:`bondid.consistency.hull.link_hull`; meshes found as every command finds them,
    :func:`bondid.model.packages.mesh_resolver`), or None when it has no geometry.

    Raises:
        ModelError: a mesh that cannot be found or read.
    """
    from ...consistency.hull import link_hull
    from ...model.packages import mesh_resolver

    hull = link_hull(doc.link(link), mesh_resolver(doc), name=link)
    return None if hull is None else (hull.vertices.min(axis=0), hull.vertices.max(axis=0))


def link_placements(doc: UrdfDocument) -> dict[str, np.ndarray]:
    """Every link's placement ``(4, 4)`` in the root frame at the neutral configuration."""
    out = {doc.root_link(): np.eye(4)}
    pending = list(doc.robot.joints)
    while pending:
        rest = [j for j in pending if j.parent not in out]
        for j in pending:
            if j.parent in out:
                T = np.eye(4) if j.origin is None else np.asarray(j.origin, float)
                out[j.child] = out[j.parent] @ T
        if len(rest) == len(pending):
            break
        pending = rest
    return out


def carried_body(doc: UrdfDocument, joint: str) -> str:
    """The body (a link with mass) that ``joint`` carries first: the child of the interface
    it belongs to (its own child link when it is in none)."""
    return next((i.child for i in interfaces(doc) if joint in i.joints), doc.joint(joint).child)


def joint_axis(
    doc: UrdfDocument, joint: str, frame: str, placements: dict[str, np.ndarray] | None = None
) -> np.ndarray:
    """The unit axis ``(3,)`` of ``joint`` in ``frame``'s axes at the neutral configuration
    (``placements``: :func:`link_placements` of ``doc``, when at hand)."""
    W = link_placements(doc) if placements is None else placements
    j = doc.joint(joint)
    T = W[j.parent] @ (np.eye(4) if j.origin is None else np.asarray(j.origin, float))
    a = T[:3, :3] @ np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), float)
    return W[frame][:3, :3].T @ (a / np.linalg.norm(a))
