"""Sensor mounts: an output that also reads a joint's own deflection, kept in the URDF.

A read head, a scale or an accelerometer fixed to the measured body through a compliant
bracket does not read the body: it reads the body plus its own deflection on the bracket. A
model states this by giving the head a link of its own on a sprung joint (the mount) and
naming the mount's joint in a ``<sensor_mount>`` element::

    <sensor_mount output="y" joint="y_mount"/>

The FRF output ``y`` (a movable joint's encoder or a measurement point) then reads its own
motion plus the coordinate of ``y_mount``, the head's deflection along the measuring
direction. Other URDF readers ignore the element; every bondid command (and every copy of the
model) sees it.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

from ..exceptions import ModelError

MOUNT_TAG = "sensor_mount"


@dataclass(frozen=True)
class SensorMount:
    """An output that also reads a joint's deflection.

    Attributes:
        output: the FRF output (a movable joint or a measurement point).
        joint: the movable joint whose coordinate (m or rad) adds to its reading.
    """

    output: str
    joint: str

    def to_element(self) -> ET.Element:
        return ET.Element(MOUNT_TAG, {"output": self.output, "joint": self.joint})


def mount_from_element(el: ET.Element, where: str) -> SensorMount:
    """A ``<sensor_mount output="…" joint="…"/>`` element → :class:`SensorMount`."""
    output, joint = el.get("output", ""), el.get("joint", "")
    if not output or not joint:
        raise ModelError(
            f"{where}: <{MOUNT_TAG} output={output!r} joint={joint!r}>: give both an output"
            " (a movable joint or a measurement point) and the mount's movable joint"
        )
    return SensorMount(output, joint)
