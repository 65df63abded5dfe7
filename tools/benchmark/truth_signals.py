"""Truth builders of the sensor- and actuator-side causes beyond the first five, and how a
truth machine is *observed*: its exact FRF as the benchmark's files hold it.

Built unlike the diagnosis's candidates (or with no candidate at all):

- ``sensor_dynamics`` (a read head on a compliant bracket): a real extra body (20 g) on a
  cantilever bracket (3 cm, a sprung revolute joint about the axis across it and the
  measuring direction) fixed to the measured body, its mass and its reaction part of the
  machine, and the output read at the head: the drive's reading plus the head's deflection
  along the axis, ``ℓθ`` (the candidate: a head of another mass on a sprung slide along the
  axis, at the body's centre of mass or at a face of its hull);
- ``sensor_misalignment`` (sensors turned in the plane of two drives): the readings of the
  pair rotated, ``cos α`` of the sensor's own drive and ``sin α`` of the other, each sensor by
  its own angle (the candidate: a first-order mixing ``I + E``);
- ``transducer_gain``: the model's own ``[gains]`` element in the truth URDF (the
  candidate: a factor on the row or column);
- ``amplifier_highpass`` (outside the library: an AC-coupled, second-order amplifier on an
  input): ``(jω/ωc)² / (1 + 2ζ jω/ωc + (jω/ωc)²)`` on the input's column, ζ = 0.7;
- ``actuator_crosstalk`` (a drive's force turned toward another drive's axis): the command of
  input ``a`` drives its own input by ``cos α`` and input ``b`` by ``sin α`` = the share (the
  candidate: a first-order mixing ``H (I + F)``).

:func:`observe` simulates a truth at an operating point with the extra outputs these need
(the read heads' brackets), combines the rows into the files' readings (:func:`readings`), and
applies the input mixings and the signal factors.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from bondid.data.measurement import FrfData
from bondid.diagnose.effects._chain import add_joint, add_link
from bondid.model import UrdfDocument
from bondid.model.parameters import link_inertial

from .truth_structures import drive_axis, moved_body

HEAD_MASS = 0.02
BRACKET = 0.03


def bracket_joint(output: str) -> str:
    """The bracket's joint of the read head on ``output``."""
    return f"truth_bracket_{output}"


def add_sensor_head(doc: UrdfDocument, output: str, f: float, zeta: float = 0.03) -> UrdfDocument:
    """The read head of the module docstring for the drive ``output``; the bracket's
    spring alone on the head would resonate at ``f`` Hz, ``zeta`` damped."""
    out = doc.copy()
    body = moved_body(out, output)
    a = drive_axis(out, output, body)
    n = np.eye(3)[int(np.argmin(np.abs(a) + np.array([0.0, 0.0, -1e-9])))]  # across a, z first
    b = np.cross(n, a)
    b /= np.linalg.norm(b)
    _, com, _ = link_inertial(out, body)
    add_link(out, bracket_joint(output))
    add_link(out, f"truth_head_{output}", HEAD_MASS, radius=0.005)
    inertia = HEAD_MASS * BRACKET**2 + 0.4 * HEAD_MASS * 0.005**2
    k = inertia * (2 * np.pi * f) ** 2
    add_joint(out, bracket_joint(output), "revolute", body, bracket_joint(output),
              axis=tuple(b), xyz=tuple(com + 0.02 * n), stiffness=k,
              damping=2 * zeta * np.sqrt(k * inertia))  # fmt: skip
    add_joint(out, f"truth_head_{output}", "fixed", bracket_joint(output),
              f"truth_head_{output}", xyz=tuple(BRACKET * n))  # fmt: skip
    return out


def highpass(w: np.ndarray, fc: float, zeta: float = 0.7) -> np.ndarray:
    """``(jω/ωc)² / (1 + 2ζ jω/ωc + (jω/ωc)²)`` at angular frequencies ``w``."""
    s = 1j * w / (2 * np.pi * fc)
    return s**2 / (1 + 2 * zeta * s + s**2)


def input_mixing(effects: Sequence[Any], inputs: Sequence[str]) -> np.ndarray | None:
    """The input mixing ``(n_in, n_in)`` of the ``actuator_crosstalk`` effects (None: none)."""
    R = np.eye(len(inputs), dtype=complex)
    found = False
    for e in effects:
        if e.effect != "actuator_crosstalk":
            continue
        a, b = e.location.split(",")
        if a in inputs and b in inputs:
            i, j = inputs.index(a), inputs.index(b)
            R[j, i] += e.spec["share"]
            R[i, i] *= np.sqrt(1.0 - e.spec["share"] ** 2)
            found = True
    return R if found else None


def readings(effects: Sequence[Any], outputs: Sequence[str]) -> tuple[np.ndarray, tuple[str, ...]]:
    """``(C, extra)``: the files' rows are ``C`` ``(n_out, n_out + n_extra)`` times the
    truth's rows of ``outputs`` and then of the extra outputs ``extra`` (the read heads'
    bracket joints): a read head adds its bracket's deflection along the axis (``ℓθ``) to its
    output; a turned pair of sensors reads ``cos α`` of its own and ``sin α`` of the other."""
    outs = list(outputs)
    extra = [bracket_joint(e.location) for e in effects
             if e.effect == "sensor_dynamics" and e.location in outs]  # fmt: skip
    n = len(outs)
    C = np.hstack([np.eye(n), np.zeros((n, len(extra)))])
    for e in effects:
        if e.effect == "sensor_dynamics" and e.location in outs:
            C[outs.index(e.location), n + extra.index(bracket_joint(e.location))] += BRACKET
        elif e.effect == "sensor_misalignment":
            a, b = e.spec["sensor"], e.spec["toward"]
            if a not in outs or b not in outs:
                continue
            i, j = outs.index(a), outs.index(b)
            M = np.eye(n)
            for r, s, deg in ((i, j, e.spec["deg"]), (j, i, e.spec.get("deg_other", 0.0))):
                t = np.radians(deg)
                M[r, r], M[r, s] = np.cos(t), np.sin(t)
            C = M @ C
    return C, tuple(extra)


def observe(
    truth: UrdfDocument, effects: Sequence[Any], op: dict[str, float], f: np.ndarray,
    quantity: str, outputs: Sequence[str] | None = None, factor: Any = None,
) -> FrfData:  # fmt: skip
    """The exact FRF of ``truth`` at ``op`` as measured (module docstring): ``outputs``
    (default: its transmitted joints) and its inputs, in ``quantity``; ``factor(f,
    outputs, inputs)`` is the elementwise signal factor (:func:`.truth.signal_factor`)."""
    from bondid.simulate import simulate

    outs = tuple(outputs) if outputs is not None else tuple(t.joint for t in truth.transmissions)
    C, extra = readings(effects, outs)
    d = simulate(truth, op, f, noise=0.0, quantity=quantity, outputs=outs + extra)
    H = d.H if not extra and np.array_equal(C, np.eye(len(outs))) else np.einsum(
        "ab,bcf->acf", C, d.H)  # fmt: skip
    ins = tuple(d.inputs)
    R = input_mixing(effects, ins)
    if R is not None:
        H = np.einsum("abf,bd->adf", H, R)
    if factor is not None:
        H = H * factor(f, outs, ins)
    return FrfData(f, outs, ins, H, d.quantity, dict(d.operating_point), None)
