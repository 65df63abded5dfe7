"""Physical magnitudes of a model: :func:`check_magnitudes`.

Every number of the model that enters the dynamics must lie in its physical range
(:mod:`bondid.ranges`): masses, principal moments of inertia, coordinates of joint, CoM and
geometry origins, geometry sizes, spring stiffnesses and references, dampings, joint limits
(and ``lower <= upper``). A value outside is refused (:class:`ModelError`, exit 2) naming
the file, the link or joint, the item and the range, before any computation: unchecked, a
spring of 1e300 runs (and is reported as a "negative stiffness" after round-off), and an
origin of 1e300 m fails deep inside the linearisation with a numerical warning instead.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np

from ..exceptions import ModelError
from ..model.document import MOVABLE_TYPES, UrdfDocument, rotation_and_translation
from ..model.parameters import carries_mass
from ..ranges import ANGLE, DAMPING, INERTIA, LENGTH, MASS, POSITION, STIFFNESS, Range


def _fmt(v: object) -> str:
    try:
        return f"{float(v):.6g}"  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return repr(v)


def _in(where: str, item: str, value: object, rng: Range) -> None:
    if value not in rng:
        raise ModelError(f"{where}: {item} is {_fmt(value)}; valid: {rng.text()}")


def _origin(where: str, item: str, T: Any) -> None:
    """A 4×4 origin: finite, its translation within :data:`LENGTH`."""
    if T is None:
        return
    arr = np.asarray(T, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ModelError(
            f"{where}: {item} origin is not finite; valid: xyz within ±{LENGTH.hi:g} m and rpy"
            f" within ±{ANGLE.hi:g} rad"
        )
    _, p = rotation_and_translation(arr)
    for axis, v in zip("xyz", p, strict=True):
        _in(where, f"{item} origin {axis}", float(v), LENGTH)


def _geometry(where: str, item: str, elements: Iterable[Any]) -> None:
    size = Range("a size", 0.0, 2 * LENGTH.hi, "m")
    for el in elements:
        _origin(where, item, getattr(el, "origin", None))
        g = getattr(el, "geometry", None)
        if g is None:
            continue
        if g.box is not None:
            for v in np.asarray(g.box.size, dtype=float).reshape(-1):
                _in(where, f"{item} box size", float(v), size)
        if g.cylinder is not None:
            _in(where, f"{item} cylinder radius", g.cylinder.radius, size)
            _in(where, f"{item} cylinder length", g.cylinder.length, size)
        if g.sphere is not None:
            _in(where, f"{item} sphere radius", g.sphere.radius, size)
        if g.mesh is not None and g.mesh.scale is not None:
            for v in np.asarray(g.mesh.scale, dtype=float).reshape(-1):
                _in(where, f"{item} mesh scale", float(v), Range("a scale", -1e6, 1e6, ""))


def _links(doc: UrdfDocument, where: str) -> None:
    for lk in doc.robot.links:
        name = f"link {lk.name!r}"
        _geometry(where, f"{name} visual", lk.visuals or [])
        _geometry(where, f"{name} collision", lk.collisions or [])
        inertial = lk.inertial
        if inertial is None or not carries_mass(lk):
            continue
        _origin(where, f"{name} inertial", inertial.origin)
        m = float(inertial.mass or 0.0)
        if m != 0.0:  # 0 (a frame) and negative masses: the model checks say what is valid
            _in(where, f"{name} mass", m, MASS)
        if inertial.inertia is not None:
            I = np.asarray(inertial.inertia, dtype=float)
            if np.all(np.isfinite(I)):
                top = float(np.max(np.abs(np.linalg.eigvalsh(0.5 * (I + I.T)))))
                _in(where, f"{name} largest principal moment of inertia", top, INERTIA)


def _joints(doc: UrdfDocument, where: str) -> None:
    springs = doc.springs
    for j in doc.robot.joints:
        name = f"joint {j.name!r}"
        _origin(where, name, j.origin)
        if j.name in springs:
            k = springs[j.name].stiffness
            if math.isfinite(k) and k >= 0:  # negative or non-finite: the model checks
                _in(where, f"{name} springStiffness", k, STIFFNESS)
            _in(where, f"{name} springReference", springs[j.name].reference, POSITION)
        d = None if j.dynamics is None else j.dynamics.damping
        if d is not None and math.isfinite(float(d)) and float(d) >= 0:
            _in(where, f"{name} damping", float(d), DAMPING)
        lim = j.limit
        if lim is None or j.type not in MOVABLE_TYPES:
            continue
        lo, hi = lim.lower, lim.upper
        for word, v in (("lower", lo), ("upper", hi)):
            if v is not None:
                _in(where, f"{name} limit {word}", v, POSITION)
        if j.type != "continuous" and lo is not None and hi is not None and lo > hi:
            raise ModelError(
                f"{where}: {name} has limit lower {_fmt(lo)} > upper {_fmt(hi)}; valid:"
                " lower <= upper"
            )


def check_magnitudes(doc: UrdfDocument, where: str) -> None:
    """Raise :class:`ModelError` for a number of the model outside its physical range
    (module docstring)."""
    _links(doc, where)
    _joints(doc, where)
