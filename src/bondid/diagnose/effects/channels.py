"""The channels an FRF-modifier effect can act on: the model's sensors and actuators, and
what kind of quantity each sensor measures (a translation or a rotation)."""

from __future__ import annotations

from ...model.document import UrdfDocument


def sensors(doc: UrdfDocument) -> tuple[str, ...]:
    """The output names a measurement of ``doc`` usually has: its transmitted joints (the
    encoders of its drives, file order), then its measurement points."""
    return tuple(t.joint for t in doc.transmissions) + tuple(p.name for p in doc.points)


def actuators(doc: UrdfDocument) -> tuple[str, ...]:
    """The input names of ``doc``: transmitted joints, then measurement points."""
    from ...linear.channels import model_inputs

    return tuple(model_inputs(doc))


def sensor_kind(doc: UrdfDocument, name: str) -> str:
    """``"translation"`` (m) or ``"rotation"`` (rad): what the sensor ``name`` (a joint or a
    measurement point of ``doc``) measures."""
    points = {p.name: p for p in doc.points}
    if name in points:
        return points[name].kind
    return "translation" if doc.joint(name).type == "prismatic" else "rotation"
