"""The URDF extension elements bondid reads on joints: transmissions and springs.

yourdfpy drops both, so :class:`~.document.UrdfDocument` keeps them among its verbatim
top-level elements (``extras``); these functions read and edit them there.

* ``<transmission>``: an actuator, a generalised force on a joint (an FRF input);
* Gazebo's ``<gazebo reference="JOINT">`` with ``<springStiffness>`` and
  ``<springReference>``: a joint spring.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

from ..exceptions import ModelError


@dataclass(frozen=True)
class Transmission:
    """One actuator: a generalised force on ``joint`` (an FRF input)."""

    name: str
    joint: str


@dataclass(frozen=True)
class Spring:
    """A joint spring from Gazebo's URDF extension: torque = −stiffness·(q − reference)."""

    stiffness: float
    reference: float = 0.0


def transmissions_in(extras: list[ET.Element]) -> list[Transmission]:
    """Actuators in file order; a transmission with several joints gives several."""
    out = []
    for el in extras:
        if el.tag != "transmission":
            continue
        for jel in el.findall("joint"):
            out.append(Transmission(el.get("name", ""), jel.get("name", "")))
    return out


def springs_in(extras: list[ET.Element], where: str) -> dict[str, Spring]:
    """Joint springs by joint name (joints without one are absent = stiffness 0); ``where``
    names the model in errors.

    Raises:
        ModelError: a non-numeric ``springStiffness`` or ``springReference``.
    """
    out = {}
    for el in extras:
        if el.tag != "gazebo" or el.get("reference") is None:
            continue
        k_el = el.find("springStiffness")
        if k_el is None:
            continue
        ref_el = el.find("springReference")
        name = str(el.get("reference"))
        try:
            k = float(k_el.text or "")
            ref = float(ref_el.text or "0") if ref_el is not None else 0.0
        except ValueError as exc:
            raise ModelError(
                f"{where}: <gazebo reference={name!r}> has a"
                f" non-numeric springStiffness/springReference ({exc})"
            ) from exc
        out[name] = Spring(k, ref)
    return out


def set_spring(
    extras: list[ET.Element], joint: str, value: float, reference: float | None = None
) -> None:
    """Set the stiffness ``value`` [N/m or N·m/rad] (and the ``reference``, m or rad, when
    given) of ``joint``'s spring, adding the ``<gazebo>`` element when it has none."""
    el = _spring_element(extras, joint)
    if el is None:
        el = ET.Element("gazebo", {"reference": joint})
        ET.SubElement(el, "springStiffness")
        ET.SubElement(el, "springReference").text = "0.0"
        extras.append(el)
    k_el = el.find("springStiffness")
    assert k_el is not None
    k_el.text = repr(float(value))
    if reference is not None:
        r_el = el.find("springReference")
        if r_el is None:
            r_el = ET.SubElement(el, "springReference")
        r_el.text = repr(float(reference))


def transmission_element(joint: str, name: str | None = None) -> ET.Element:
    """An effort transmission on ``joint`` (named ``name``, default ``JOINT_trans``)."""
    el = ET.Element("transmission", {"name": name or f"{joint}_trans"})
    ET.SubElement(el, "type").text = "transmission_interface/SimpleTransmission"
    jel = ET.SubElement(el, "joint", {"name": joint})
    ET.SubElement(jel, "hardwareInterface").text = "hardware_interface/EffortJointInterface"
    act = ET.SubElement(el, "actuator", {"name": f"{joint}_motor"})
    ET.SubElement(act, "mechanicalReduction").text = "1"
    return el


def _spring_element(extras: list[ET.Element], joint: str) -> ET.Element | None:
    for el in extras:
        if (
            el.tag == "gazebo"
            and el.get("reference") == joint
            and el.find("springStiffness") is not None
        ):
            return el
    return None
