"""A URDF file held in memory for reading and authoring: :class:`UrdfDocument`.

yourdfpy parses the kinematic tree (links, joints, inertials, geometry) but drops the
elements bondid also relies on: ``<transmission>`` (actuators = FRF inputs) and Gazebo's
``<gazebo reference="JOINT">`` extension (joint springs). This class keeps every top-level
element yourdfpy does not model, verbatim, and writes it back, and restores what yourdfpy's
writer drops inside links and joints (``<mimic>``, ``<safety_controller>``, ``<calibration>``,
unknown elements and attributes; :mod:`.preserve`), so nothing in a user's file is lost by a
read → write round trip. The text is read and written by :mod:`.urdf_xml`; transmissions and
springs are read and edited in the kept elements by :mod:`.joint_elements`.
"""

from __future__ import annotations

import copy
import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import refuse_overwrite, write_text_atomic
from ..exceptions import ModelError
from .joint_elements import (
    Spring,
    Transmission,
    set_spring,
    springs_in,
    transmission_element,
    transmissions_in,
)
from .mounts import MOUNT_TAG, SensorMount, mount_from_element
from .points import (
    GAIN_TAG,
    POINT_TAG,
    Point,
    check_gain_name,
    gain_from_element,
    point_from_element,
)
from .preserve import LostPart
from .urdf_xml import parse_urdf, urdf_text

MOVABLE_TYPES = ("revolute", "continuous", "prismatic")


class UrdfDocument:
    """One URDF model in memory: yourdfpy's tree plus the extension elements it drops.

    Use :meth:`load` / :meth:`from_string` to read, :meth:`to_string` / :meth:`write` to
    write. Springs and transmissions are read from and written to the extension elements.
    """

    def __init__(
        self,
        urdf: object,
        extras: list[ET.Element],
        source: str | None = None,
        lost: list[LostPart] | None = None,
    ):
        self._urdf = urdf
        self.extras = extras
        self.source = source
        #: parts inside links/joints that yourdfpy does not write back (restored on writing)
        self.lost: list[LostPart] = list(lost or [])
        #: folders searched first for ``package://`` meshes (:mod:`.packages`)
        self.package_path: list[str] = []
        self._check()

    # -- reading ------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> UrdfDocument:
        """Read a URDF file. Raises :class:`ModelError` naming the file on failure."""
        from ..paths import check_input_file

        p = Path(path)
        check_input_file(p, "URDF file", ModelError)  # a FIFO would block, a folder is no file
        try:
            text = p.read_text(encoding="utf-8")
        except OSError as exc:
            raise ModelError(f"{p}: cannot read the URDF file ({exc.strerror})") from exc
        except UnicodeDecodeError as exc:
            raise ModelError(
                f"{p}: not a text file (byte {exc.start} is not UTF-8); valid: a URDF (XML) file"
            ) from exc
        return cls.from_string(text, source=str(p))

    @classmethod
    def from_string(cls, xml: str, source: str | None = None) -> UrdfDocument:
        """Parse URDF text; ``source`` names it in error messages."""
        urdf, extras, lost = parse_urdf(xml, source or "<URDF string>")
        return cls(urdf, extras, source, lost)

    def _check(self) -> None:
        where = self.source or "<URDF string>"
        for j in self.robot.joints:  # yourdfpy keeps <dynamics> values as text
            dyn = getattr(j, "dynamics", None)
            for attr in ("damping", "friction"):
                value = getattr(dyn, attr, None)
                if isinstance(value, str):
                    try:
                        setattr(dyn, attr, float(value))
                    except ValueError:
                        raise ModelError(
                            f"{where}: joint {j.name!r}: <dynamics {attr}={value!r}> is not a"
                            " number; valid: a number >= 0, or leave the attribute out"
                        ) from None
        links = {lk.name for lk in self.robot.links}
        for j in self.robot.joints:
            for end in (j.parent, j.child):
                if end not in links:
                    raise ModelError(
                        f"{where}: joint {j.name!r} refers to link {end!r}, which does not exist"
                    )
        for t in self.transmissions:
            if t.joint not in self.joint_names:
                raise ModelError(
                    f"{where}: transmission {t.name!r} names joint {t.joint!r}, which does not"
                    f" exist; joints: {', '.join(self.movable_joint_names)}"
                )
        for name in self.springs:
            if name not in self.joint_names:
                raise ModelError(
                    f"{where}: <gazebo reference={name!r}> sets a spring on a joint that does"
                    " not exist"
                )

    # -- the tree -----------------------------------------------------------------------
    @property
    def robot(self):  # -> yourdfpy.Robot
        """The yourdfpy ``Robot`` dataclass (links, joints, materials)."""
        return self._urdf.robot  # type: ignore[attr-defined]

    @property
    def name(self) -> str:
        return str(self.robot.name)

    @property
    def link_names(self) -> list[str]:
        return [lk.name for lk in self.robot.links]

    @property
    def joint_names(self) -> list[str]:
        return [j.name for j in self.robot.joints]

    @property
    def movable_joint_names(self) -> list[str]:
        """Joints with one degree of freedom (revolute, continuous, prismatic), file order."""
        return [j.name for j in self.robot.joints if j.type in MOVABLE_TYPES]

    def link(self, name: str):  # -> yourdfpy.Link
        return self._named(self.robot.links, "link", name)

    def joint(self, name: str):  # -> yourdfpy.Joint
        return self._named(self.robot.joints, "joint", name)

    def _named(self, items: list[Any], what: str, name: str) -> Any:
        """The element called ``name`` of ``items`` (links or joints, ``what``)."""
        for item in items:
            if item.name == name:
                return item
        valid = ", ".join(item.name for item in items)
        raise ModelError(f"{self.source or '<URDF>'}: no {what} {name!r}; {what}s: {valid}")

    def root_link(self) -> str:
        children = {j.child for j in self.robot.joints}
        roots = [n for n in self.link_names if n not in children]
        if len(roots) != 1:
            raise ModelError(f"{self.source or '<URDF>'}: expected one root link, found {roots}")
        return roots[0]

    def grounded_links(self) -> set[str]:
        """Links rigidly attached to the root (through fixed joints only), root included."""
        fixed: dict[str, list[str]] = {}
        for j in self.robot.joints:
            if j.type == "fixed":
                fixed.setdefault(j.parent, []).append(j.child)
        out, stack = set(), [self.root_link()]
        while stack:
            n = stack.pop()
            out.add(n)
            stack.extend(fixed.get(n, []))
        return out

    # -- extension elements: transmissions and springs ----------------------------------
    @property
    def transmissions(self) -> list[Transmission]:
        """Actuators in file order; a transmission with several joints gives several."""
        return transmissions_in(self.extras)

    @property
    def springs(self) -> dict[str, Spring]:
        """Joint springs by joint name (joints without one are absent = stiffness 0)."""
        return springs_in(self.extras, self.source or "<URDF>")

    def stiffness(self, joint: str) -> float:
        """Spring stiffness of ``joint`` [N/m or N·m/rad]; 0 when it has no spring."""
        self.joint(joint)
        s = self.springs.get(joint)
        return 0.0 if s is None else s.stiffness

    def set_stiffness(self, joint: str, value: float, reference: float | None = None) -> None:
        """Set (or create) the Gazebo spring of ``joint``."""
        self.joint(joint)
        set_spring(self.extras, joint, value, reference)

    def damping(self, joint: str) -> float:
        """Viscous damping of ``joint`` [N·s/m or N·m·s/rad]; 0 when absent."""
        j = self.joint(joint)
        if j.dynamics is None or j.dynamics.damping is None:
            return 0.0
        return float(j.dynamics.damping)

    def set_damping(self, joint: str, value: float) -> None:
        import yourdfpy

        j = self.joint(joint)
        if j.dynamics is None:
            j.dynamics = yourdfpy.Dynamics(damping=float(value), friction=None)
        else:
            j.dynamics.damping = float(value)

    def add_transmission(self, joint: str, name: str | None = None) -> None:
        """Append an effort transmission on ``joint`` (a new FRF input, last in order)."""
        self.joint(joint)
        self.extras.append(transmission_element(joint, name))

    def mimic_joints(self) -> dict[str, str]:
        """Joints with a ``<mimic>`` element → the joint they mimic."""
        return {j.name: str(j.mimic.joint) for j in self.robot.joints if getattr(j, "mimic", None)}

    def drop_mimic(self, joint: str) -> None:
        """Remove ``<mimic>`` from ``joint``: it becomes an independent DOF (bondid refuses
        to linearise a model with mimic joints, which it cannot couple)."""
        j = self.joint(joint)
        j.mimic = None
        key = ("joint", "name=" + joint)
        self.lost = [
            p
            for p in self.lost
            if not (p.path == (key,) and p.element is not None and p.element.tag == "mimic")
        ]

    # -- extension elements: measurement points and transducer gains --------------------
    @property
    def points(self) -> list[Point]:
        """Measurement points (``<measurement_point>``), file order (see :mod:`.points`)."""
        where = self.source or "<URDF>"
        return [point_from_element(el, where) for el in self.extras if el.tag == POINT_TAG]

    def set_point(self, point: Point) -> None:
        """Add a point, or replace the one of the same name."""
        self.extras = [
            el for el in self.extras if not (el.tag == POINT_TAG and el.get("name") == point.name)
        ]
        self.extras.append(point.to_element())

    @property
    def gains(self) -> dict[str, float]:
        """Transducer gains by name (``gain.in.X``, ``gain.out.Y``); absent = 1."""
        where = self.source or "<URDF>"
        return dict(gain_from_element(el, where) for el in self.extras if el.tag == GAIN_TAG)

    def set_gain(self, name: str, value: float) -> None:
        """Set (or create) the gain ``name`` (``gain.in.X`` / ``gain.out.Y``)."""
        check_gain_name(name, self.source or "<URDF>")
        for el in self.extras:
            if el.tag == GAIN_TAG and el.get("name") == name:
                el.set("value", repr(float(value)))
                return
        self.extras.append(ET.Element(GAIN_TAG, {"name": name, "value": repr(float(value))}))

    @property
    def sensor_mounts(self) -> list[SensorMount]:
        """Outputs that also read a mount's deflection (``<sensor_mount>``, :mod:`.mounts`)."""
        where = self.source or "<URDF>"
        return [mount_from_element(el, where) for el in self.extras if el.tag == MOUNT_TAG]

    def add_sensor_mount(self, mount: SensorMount) -> None:
        """Let ``mount.output`` also read the coordinate of ``mount.joint``."""
        if mount not in self.sensor_mounts:
            self.extras.append(mount.to_element())

    # -- writing ------------------------------------------------------------------------
    def to_string(self) -> str:
        """The whole model as URDF text (pretty-printed, full double precision)."""
        return urdf_text(self._urdf, self.lost, self.extras)

    def write(self, path: str | os.PathLike[str], *, overwrite_source: bool = False) -> Path:
        """Write the model atomically to ``path``.

        Refuses to overwrite the file it was loaded from unless ``overwrite_source``.
        """
        if self.source is not None and not overwrite_source:
            refuse_overwrite(path, [self.source])
        return write_text_atomic(path, self.to_string())

    def copy(self) -> UrdfDocument:
        """A deep copy (edits to it leave this document untouched)."""
        out = UrdfDocument(
            copy.deepcopy(self._urdf), copy.deepcopy(self.extras), self.source, self.lost
        )
        out.package_path = list(self.package_path)
        return out

    def build_pinocchio_model(self):  # -> pinocchio.Model
        """The Pinocchio model of this document (built from memory, no file written)."""
        import pinocchio as pin

        from .native_messages import captured_native_stderr

        text = self.to_string()
        try:
            with captured_native_stderr() as said:  # urdfdom prints its reasons on fd 2
                model = pin.buildModelFromXML(text)
        except Exception as exc:
            why = "; ".join([*said.messages(), " ".join(str(exc).split())])
            raise ModelError(
                f"{self.source or '<URDF>'}: Pinocchio could not build the model ({why})"
            ) from exc
        if said.text.strip():  # warnings of a model that was built: pass them on
            print(f"{self.source or '<URDF>'}: urdfdom: {said.one_line()}", file=sys.stderr)
        return model


def rotation_and_translation(T: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Split a 4×4 homogeneous transform (None = identity) into (R (3,3), p (3,))."""
    if T is None:
        return np.eye(3), np.zeros(3)
    T = np.asarray(T, dtype=float)
    return T[:3, :3].copy(), T[:3, 3].copy()
