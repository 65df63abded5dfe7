"""Operating points: joint positions by name → Pinocchio configuration vector."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..exceptions import OperatingPointError


def configuration(model, values: Mapping[str, float] | None, where: str = "<model>") -> np.ndarray:
    """Configuration ``q`` (nq,) with the named 1-DOF joints at ``values`` (m or rad).

    Joints not named stay at their neutral value. Continuous joints take an angle.
    Raises :class:`OperatingPointError` for unknown joints or non-finite values.
    """
    import pinocchio as pin

    q = pin.neutral(model)
    if not values:
        return q
    dq = np.zeros(model.nv)
    names = list(model.names)
    for name, value in values.items():
        if name not in names or name == "universe":
            movable = ", ".join(n for n in names[1:])
            raise OperatingPointError(
                f"{where}: operating point names joint {name!r}, which the model lacks;"
                f" valid: {movable}"
            )
        jid = names.index(name)
        joint = model.joints[jid]
        if joint.nv != 1:
            raise OperatingPointError(
                f"{where}: operating point joint {name!r} has {joint.nv} DOF; only 1-DOF joints"
            )
        v = float(value)
        if not np.isfinite(v):
            raise OperatingPointError(f"{where}: operating point {name}={value} is not finite")
        dq[joint.idx_v] = v
    return pin.integrate(model, q, dq)


def parse_operating_point(text: str, where: str = "<operating point>") -> dict[str, float]:
    """Parse ``"x=0.01 y=-0.02"`` (spaces or commas) into ``{"x": 0.01, "y": -0.02}``."""
    out: dict[str, float] = {}
    for token in text.replace(",", " ").split():
        name, sep, value = token.partition("=")
        if not sep or not name:
            raise OperatingPointError(f"{where}: {token!r} is not JOINT=VALUE")
        try:
            out[name] = float(value)
        except ValueError as exc:
            raise OperatingPointError(f"{where}: {token!r}: {value!r} is not a number") from exc
    return out
