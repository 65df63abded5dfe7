"""Named physical parameters of a model, read from and written to a :class:`UrdfDocument`.

Names are stable and readable:

=============================  ==========================================  ===============
name                           meaning                                      unit
=============================  ==========================================  ===============
``LINK.mass``                  mass                                         kg
``LINK.com.x`` (``.y``, ``.z``)  centre of mass in the link frame             m
``LINK.inertia.ixx`` (...)     inertia about the CoM, link-frame axes       kg·m²
``JOINT.stiffness``            Gazebo joint spring                          N/m, N·m/rad
``JOINT.damping``              joint viscous damper                         N·s/m, N·m·s/rad
``gain.in.X``, ``gain.out.Y``  transducer gain of input X / output Y         file unit per SI
``mix.P``                      share of point P's second component          per its kinds
``rayleigh.alpha``             mass-proportional damping α (D += α·M)       1/s
``rayleigh.beta``              stiffness-proportional damping β (D += β·K)  s
``rayleigh.eta``               structural loss factor η (K → K·(1 + jη))    1
``JOINT.multiplier``           a ``<mimic>`` joint's multiplier (δq = a·δq   its unit per
                               of the joint it mimics)                      the master's
=============================  ==========================================  ===============

``rayleigh.*`` exist only in a model that declares proportional damping
(:mod:`bondid.model.rayleigh`; ``rayleigh.eta`` only when it declares a loss factor); they
belong to ``all`` and (when not 0) to ``default``.

A mix is a parameter only for a point declared with a second component (a patch driving
bending and torsion: :mod:`bondid.model.points`); it belongs to the group ``mixes`` only.

A multiplier is a parameter of every ``<mimic>`` joint (a coupled drive's ratio; the
translation per radian that places a compliance's pivot, :mod:`bondid.linear.coupling`);
it belongs to the group ``couplings`` only.

A gain is a parameter only where the model declares it (``<transducer_gain>``, from a study's
``[gains]`` table or ``--points`` file; see :mod:`bondid.model.points`); it belongs to the
group ``gains`` and to no other group.

The inertia components are ``ixx ixy ixz iyy iyz izz``. A URDF ``<inertial>`` with a rotated
origin is read correctly (its tensor is rotated into the link frame); writing a parameter
stores the inertial with ``rpy = 0``.

Groups: ``inertial`` (the 10 parameters of every moving link with an ``<inertial>``),
``parasitic`` (stiffness and damping of every movable joint without a transmission),
``joints`` (stiffness and damping of every movable joint), ``all`` (``inertial`` + ``joints``
+ ``rayleigh.*``), ``gains`` (the declared transducer gains), ``mixes`` (the points' mixes),
``couplings`` (the mimic joints' multipliers), ``default`` (``inertial`` + every joint
stiffness and damping and Rayleigh coefficient whose model value is not 0: ``python -m
bondid.fit``'s default free set; a 0 the model sets, no spring on a driven axis, is a
modelling decision, not an uncertain number).
"""

from __future__ import annotations

import fnmatch
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..exceptions import ParameterError
from .document import UrdfDocument, rotation_and_translation
from .points import MIX_PREFIX
from .rayleigh import RAYLEIGH_OWNER, RAYLEIGH_UNITS, Rayleigh, model_rayleigh, set_rayleigh
from .ties import followers, model_ties

COM_AXES = ("x", "y", "z")
INERTIA_COMPONENTS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
#: (row, column) of each URDF inertia component in the 3×3 inertia tensor
INERTIA_ENTRY = {
    "ixx": (0, 0),
    "ixy": (0, 1),
    "ixz": (0, 2),
    "iyy": (1, 1),
    "iyz": (1, 2),
    "izz": (2, 2),
}
GROUPS = ("inertial", "parasitic", "joints", "all", "gains", "mixes", "couplings", "default")
#: the unit of each joint kind's coordinate (a multiplier's unit is the ratio of two)
_COORD_UNITS = {"prismatic": "m", "revolute": "rad", "continuous": "rad"}


@dataclass(frozen=True)
class ParameterInfo:
    """What a named parameter is: ``kind`` in mass/com/inertia/stiffness/damping."""

    name: str
    kind: str
    owner: str
    component: str | None
    unit: str

    @property
    def is_inertial(self) -> bool:
        return self.kind in ("mass", "com", "inertia")

    @property
    def component_key(self) -> str:
        """What the parameter is of its owner: ``mass``, ``com.x``, ``inertia.iyy``; for
        any other parameter its kind (``stiffness``, ``damping``, ...). Parameters of one
        key are alike: a fit's body blocks are keyed by it, and a tie's members share it."""
        return f"{self.kind}.{self.component}" if self.kind in ("com", "inertia") else self.kind


def _joint_units(kind: str) -> tuple[str, str]:
    if kind == "prismatic":
        return "N/m", "N*s/m"
    return "N*m/rad", "N*m*s/rad"


def carries_mass(link: Any) -> bool:
    """Does a (yourdfpy) link carry inertial parameters? Not without ``<inertial>``, nor with
    one of mass 0 and a zero inertia tensor: ROS URDFs write their frames that way (UR5's
    ``ee_link``, ``base``), and such a link is massless. Any other ``<inertial>`` does (the
    model check rejects a mass 0 with a non-zero inertia)."""
    i = link.inertial
    if i is None:
        return False
    if float(i.mass or 0.0) != 0.0:
        return True
    return i.inertia is not None and bool(np.any(np.asarray(i.inertia, float) != 0.0))


def parameter_infos(doc: UrdfDocument) -> list[ParameterInfo]:
    """Every parameter of the document, links first (file order), then joints."""
    out: list[ParameterInfo] = []
    grounded = doc.grounded_links()
    for lk in doc.robot.links:
        if not carries_mass(lk) or lk.name in grounded:
            continue
        n = lk.name
        out.append(ParameterInfo(f"{n}.mass", "mass", n, None, "kg"))
        out += [ParameterInfo(f"{n}.com.{a}", "com", n, a, "m") for a in COM_AXES]
        out += [
            ParameterInfo(f"{n}.inertia.{c}", "inertia", n, c, "kg*m^2") for c in INERTIA_COMPONENTS
        ]
    mimic = doc.mimic_joints()  # their springs/dampers are folded into the master's
    for j in doc.robot.joints:
        if j.type not in ("revolute", "continuous", "prismatic") or j.name in mimic:
            continue
        ku, du = _joint_units(j.type)
        out.append(ParameterInfo(f"{j.name}.stiffness", "stiffness", j.name, None, ku))
        out.append(ParameterInfo(f"{j.name}.damping", "damping", j.name, None, du))
    for name, master in mimic.items():
        j = doc.joint(name)
        if j.type in _COORD_UNITS:
            unit = f"{_COORD_UNITS[j.type]}/{_COORD_UNITS.get(doc.joint(master).type, '1')}"
            out.append(ParameterInfo(f"{name}.multiplier", "multiplier", name, None, unit))
    for name in doc.gains:
        out.append(ParameterInfo(name, "gain", name, None, "1"))
    for pt in doc.points:
        if pt.mixed:
            out.append(ParameterInfo(f"{MIX_PREFIX}{pt.name}", "mix", pt.name, None, "1"))
    declared = model_rayleigh(doc)
    if declared is not None:
        for c in declared.components:
            unit = RAYLEIGH_UNITS[c]
            out.append(ParameterInfo(f"{RAYLEIGH_OWNER}.{c}", "rayleigh", RAYLEIGH_OWNER, c, unit))
    return out


def parameter_names(doc: UrdfDocument) -> list[str]:
    return [p.name for p in parameter_infos(doc)]


def _info(doc: UrdfDocument, name: str) -> ParameterInfo:
    quick = _quick_info(doc, name)
    if quick is not None:
        return quick
    for p in parameter_infos(doc):
        if p.name == name:
            return p
    raise ParameterError(
        f"{doc.source or '<URDF>'}: unknown parameter {name!r}; valid names look like"
        " LINK.mass, LINK.com.x, LINK.inertia.ixy, JOINT.stiffness, JOINT.damping"
        " (see `bondid.model.parameter_names`)"
    )


def _quick_info(doc: UrdfDocument, name: str) -> ParameterInfo | None:
    """The info of a joint spring or damper named ``name``, read off the joint alone (the
    parameters a fit reads and writes most; :func:`parameter_infos` rebuilds every info of
    the document), or None for any other name or a joint that has no such parameter."""
    owner, _, kind = name.rpartition(".")
    if kind in COM_AXES or kind in INERTIA_COMPONENTS or kind == "mass":
        return _quick_link_info(doc, name)
    if kind not in ("stiffness", "damping") or not owner:
        return None
    for j in doc.robot.joints:
        if j.name == owner:
            if j.type not in ("revolute", "continuous", "prismatic"):
                return None
            if getattr(j, "mimic", None):
                return None
            ku, du = _joint_units(j.type)
            return ParameterInfo(name, kind, owner, None, ku if kind == "stiffness" else du)
    return None


def _quick_link_info(doc: UrdfDocument, name: str) -> ParameterInfo | None:
    """:func:`_quick_info` of a link's mass, CoM or inertia component."""
    parts = name.split(".")
    if len(parts) == 2 and parts[1] == "mass":
        link, kind, comp, unit = parts[0], "mass", None, "kg"
    elif len(parts) == 3 and parts[1] == "com" and parts[2] in COM_AXES:
        link, kind, comp, unit = parts[0], "com", parts[2], "m"
    elif len(parts) == 3 and parts[1] == "inertia" and parts[2] in INERTIA_COMPONENTS:
        link, kind, comp, unit = parts[0], "inertia", parts[2], "kg*m^2"
    else:
        return None
    lk = next((x for x in doc.robot.links if x.name == link), None)
    if lk is None or not carries_mass(lk) or link in doc.grounded_links():
        return None
    return ParameterInfo(name, kind, link, comp, unit)


def link_inertial(doc: UrdfDocument, link: str) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass kg, CoM (3,) m, inertia about the CoM (3,3) kg·m²) in the link frame."""
    lk = doc.link(link)
    if lk.inertial is None:
        raise ParameterError(f"{doc.source or '<URDF>'}: link {link!r} has no <inertial>")
    R, p = rotation_and_translation(lk.inertial.origin)
    I_raw = np.zeros((3, 3)) if lk.inertial.inertia is None else np.asarray(lk.inertial.inertia)
    I_link = R @ I_raw @ R.T
    return float(lk.inertial.mass or 0.0), p, 0.5 * (I_link + I_link.T)


def set_link_inertial(
    doc: UrdfDocument, link: str, mass: float, com: np.ndarray, inertia: np.ndarray
) -> None:
    """Write a link's inertial (origin rpy = 0, tensor in the link frame)."""
    lk = doc.link(link)
    if lk.inertial is None:
        raise ParameterError(f"{doc.source or '<URDF>'}: link {link!r} has no <inertial>")
    T = np.eye(4)
    T[:3, 3] = np.asarray(com, dtype=float)
    lk.inertial.origin = T
    lk.inertial.mass = float(mass)
    inertia = np.asarray(inertia, dtype=float)
    lk.inertial.inertia = 0.5 * (inertia + inertia.T)


def get_parameter(doc: UrdfDocument, name: str) -> float:
    """The value of parameter ``name`` (SI units, see the module table)."""
    info = _info(doc, name)
    if info.kind == "gain":
        return doc.gains[name]
    if info.kind == "mix":
        return next(p.mix for p in doc.points if p.name == info.owner)
    if info.kind == "multiplier":
        m = doc.joint(info.owner).mimic
        return 1.0 if m.multiplier is None else float(m.multiplier)
    if info.kind == "rayleigh":
        declared = model_rayleigh(doc)
        return 0.0 if declared is None else declared.get(str(info.component))
    if info.kind == "stiffness":
        return doc.stiffness(info.owner)
    if info.kind == "damping":
        return doc.damping(info.owner)
    m, c, I = link_inertial(doc, info.owner)
    if info.kind == "mass":
        return m
    if info.kind == "com":
        return float(c[COM_AXES.index(str(info.component))])
    r, s = INERTIA_ENTRY[str(info.component)]
    return float(I[r, s])


def set_parameter(doc: UrdfDocument, name: str, value: float) -> None:
    """Set parameter ``name`` to ``value`` (SI units). Edits ``doc`` in place."""
    info = _info(doc, name)
    value = float(value)
    if not np.isfinite(value):
        raise ParameterError(f"{name}: value {value} is not finite")
    if info.kind in ("stiffness", "damping", "mass", "rayleigh") and value < 0:
        raise ParameterError(f"{name}: value {value} is negative; valid: ≥ 0")
    if info.kind == "gain":
        if value == 0:
            raise ParameterError(f"{name}: a gain of 0 cuts the channel; valid: ≠ 0")
        doc.set_gain(name, value)
        return
    if info.kind == "mix":
        point = next(p for p in doc.points if p.name == info.owner)
        doc.set_point(replace(point, mix=value))
        return
    if info.kind == "multiplier":
        doc.joint(info.owner).mimic.multiplier = value
        return
    if info.kind == "rayleigh":
        old = model_rayleigh(doc) or Rayleigh(0.0, 0.0)
        set_rayleigh(doc, replace(old, **{str(info.component): value}))
        return
    if info.kind == "stiffness":
        doc.set_stiffness(info.owner, value)
        return
    if info.kind == "damping":
        doc.set_damping(info.owner, value)
        return
    m, c, I = link_inertial(doc, info.owner)
    if info.kind == "mass":
        m = value
    elif info.kind == "com":
        c[COM_AXES.index(str(info.component))] = value
    else:
        r, s = INERTIA_ENTRY[str(info.component)]
        I[r, s] = I[s, r] = value
    set_link_inertial(doc, info.owner, m, c, I)


def get_parameters(doc: UrdfDocument, names: Iterable[str]) -> np.ndarray:
    """Values of ``names``, shape ``(len(names),)``."""
    return np.array([get_parameter(doc, n) for n in names], dtype=float)


def set_parameters(doc: UrdfDocument, values: dict[str, float]) -> None:
    for n, v in values.items():
        set_parameter(doc, n, v)


def group_members(doc: UrdfDocument, group: str) -> list[str]:
    """The parameter names of a group (see the module docstring)."""
    infos = parameter_infos(doc)
    driven = {t.joint for t in doc.transmissions}
    if group == "inertial":
        return [p.name for p in infos if p.is_inertial]
    joint_kinds = ("stiffness", "damping")
    if group == "parasitic":
        return [p.name for p in infos if p.kind in joint_kinds and p.owner not in driven]
    if group == "joints":
        return [p.name for p in infos if p.kind in joint_kinds]
    if group == "all":
        return [p.name for p in infos if p.kind not in ("gain", "mix", "multiplier")]
    if group == "gains":
        return [p.name for p in infos if p.kind == "gain"]
    if group == "mixes":
        return [p.name for p in infos if p.kind == "mix"]
    if group == "couplings":
        return [p.name for p in infos if p.kind == "multiplier"]
    if group == "default":
        return [
            p.name
            for p in infos
            if p.is_inertial
            or (p.kind in (*joint_kinds, "rayleigh") and get_parameter(doc, p.name) != 0.0)
        ]
    raise ParameterError(f"unknown parameter group {group!r}; valid: {', '.join(GROUPS)}")


def select_parameters(
    doc: UrdfDocument, free: Iterable[str], fixed: Iterable[str] = ()
) -> list[str]:
    """Resolve names, glob patterns and groups into parameter names (model order).

    ``free`` and ``fixed`` items may be comma- or space-separated strings. ``fixed`` wins.
    A pattern that matches nothing raises :class:`ParameterError`. Of a tie declared in the
    model (:mod:`.ties`) only the first chosen member is returned: the others follow it.
    """
    all_names = parameter_names(doc)

    def expand(items: Iterable[str]) -> set[str]:
        out: set[str] = set()
        for item in items:
            for token in item.replace(",", " ").split():
                if token in GROUPS:
                    out.update(group_members(doc, token))
                    continue
                hits = [n for n in all_names if fnmatch.fnmatchcase(n, token)]
                if not hits:
                    raise ParameterError(
                        f"{doc.source or '<URDF>'}: {token!r} matches no parameter; use a name,"
                        f" a glob (x_stage.*, *.stiffness) or a group ({', '.join(GROUPS)})"
                    )
                out.update(hits)
        return out

    chosen = expand(free) - expand(fixed)
    ordered = [n for n in all_names if n in chosen]
    tied = followers(model_ties(doc), ordered)
    return [n for n in ordered if n not in tied]
