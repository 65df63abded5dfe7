"""FRF channels of a model: its inputs and outputs (joints and measurement points), the
kinematic B and C at a pose, and the transducer gains of each channel."""

from __future__ import annotations

import numpy as np

from ..exceptions import ModelError
from ..model.document import UrdfDocument
from ..model.points import check_gain_name
from .points import point_rows


def model_inputs(doc: UrdfDocument) -> tuple[str, ...]:
    """FRF input names of ``doc``: transmitted joints (file order), then measurement points."""
    return tuple(t.joint for t in doc.transmissions) + tuple(p.name for p in doc.points)


def model_outputs(doc: UrdfDocument) -> tuple[str, ...]:
    """Every name an FRF output may have: movable joints (encoders), then measurement points."""
    return tuple(doc.movable_joint_names) + tuple(p.name for p in doc.points)


def io_matrices(
    doc: UrdfDocument, model, q0: np.ndarray, dofs: list[str], outputs: tuple[str, ...] | None
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...], tuple[str, ...]]:
    """(B ``(nv, n_in)``, C ``(n_out, nv)``, inputs, outputs) without gains."""
    where = doc.source or "<URDF>"
    points = {p.name: p for p in doc.points}
    clash = set(points) & set(dofs)
    if clash:
        raise ModelError(f"{where}: measurement point(s) {sorted(clash)} named like a joint")
    inputs = model_inputs(doc)
    if not inputs:
        raise ModelError(
            f"{where}: no <transmission> elements and no measurement points, so the model has"
            " no FRF inputs"
        )
    outs = tuple(outputs) if outputs is not None else inputs
    rows = point_rows(model, q0, list(points.values()), where)

    def row(name: str, role: str) -> np.ndarray:
        r = np.zeros(len(dofs))
        if name in points:
            return rows[list(points).index(name)]
        if name not in dofs:
            raise ModelError(
                f"{where}: {role} {name!r} is neither a movable joint nor a measurement point;"
                f" valid: {', '.join(list(dofs) + list(points))}"
            )
        r[dofs.index(name)] = 1.0
        return r

    B = np.array([row(n, "input") for n in inputs]).reshape(len(inputs), len(dofs)).T
    C = np.array([row(n, "output") for n in outs]).reshape(len(outs), len(dofs))
    for m in doc.sensor_mounts:
        # a sensor on a compliant mount reads its own motion plus the mount's deflection
        if m.joint not in dofs:
            raise ModelError(
                f"{where}: <sensor_mount output={m.output!r} joint={m.joint!r}>: the joint is"
                f" not a movable joint; valid: {', '.join(dofs)}"
            )
        if m.output not in points and m.output not in dofs:
            raise ModelError(
                f"{where}: <sensor_mount output={m.output!r}>: not a movable joint nor a"
                f" measurement point; valid: {', '.join(list(dofs) + list(points))}"
            )
        if m.output in outs:
            C[outs.index(m.output), dofs.index(m.joint)] += 1.0
    return B, C, inputs, outs


def channel_gains(
    doc: UrdfDocument, inputs: tuple[str, ...], outputs: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """Transducer gains of the inputs and outputs (1 where none is declared)."""
    where = doc.source or "<URDF>"
    gi, go = np.ones(len(inputs)), np.ones(len(outputs))
    valid_out = set(model_outputs(doc))
    for name, value in doc.gains.items():
        side, chan = check_gain_name(name, where)
        if side == "in" and chan not in inputs:
            raise ModelError(
                f"{where}: gain {name!r}: {chan!r} is not an input; inputs: {', '.join(inputs)}"
            )
        if side == "out" and chan not in valid_out:
            raise ModelError(
                f"{where}: gain {name!r}: {chan!r} is not an output; valid:"
                f" {', '.join(sorted(valid_out))}"
            )
        if side == "in":
            gi[inputs.index(chan)] = value
        elif chan in outputs:
            go[outputs.index(chan)] = value
    return gi, go
