"""Measurement points and transducer gains: declared in a TOML table, kept in the URDF.

A *point* is a place where a test engineer senses or excites the structure: the
translation or rotation of a frame (a link, or a point fixed to a link — a link on a fixed
joint) along a direction, absolute or relative to another frame. Used as an FRF output it is
a sensor (an accelerometer, a laser vibrometer, a load encoder); used as an input it is a
force (``translation``) or a torque (``rotation``) applied there along the direction (a
hammer, a shaker; with ``relative_to`` an action/reaction pair between the two frames).

A *gain* scales one input or one output channel (``gain.in.<input>``, ``gain.out.<output>``):
a sensor sensitivity, a torque constant, an amplifier gain. ``H_meas = g_out · H · g_in``.

Both are declared in a TOML table (the study file's ``[points]`` / ``[gains]`` tables, or a
file given with ``--points``)::

    [points.tip_acc]            # a name used in channel names (tip_acc.hammer3)
    link = "tip"                # a link (or a Pinocchio frame) of the URDF
    kind = "translation"        # translation (force) | rotation (torque)
    direction = [0, 0, 1]       # any non-zero vector, normalised
    axes = "world"              # world (default) | local (the link's axes at the pose)
    relative_to = "base"        # optional: minus the same motion of another frame

    [gains]
    "gain.in.motor" = 0.35      # any number ≠ 0 (a sign flip is a gain of −1)

A point may have a *second component*: a piezo patch or a shaker that drives more than one
motion (bending and torsion, a force and a moment) in a ratio to be fitted::

    [points.patch1]
    link = "seg0"
    kind = "rotation"
    direction = [0, 1, 0]       # the first component (bending)
    second = {kind = "rotation", direction = [1, 0, 0]}   # the second (torsion)
    mix = 0.0                   # its share: second = mix × first (a parameter, mix.patch1)

As an input the point then applies ``u (d₁ + mix · d₂)`` (each ``d`` a force or a torque
along its direction, per its kind); as an output it senses the same combination.

and stored in the model as two URDF extension elements that other URDF readers ignore
(``<measurement_point …/>``, ``<transducer_gain …/>``), so every command (and every copy of
the model) sees them.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import ConfigError, ModelError

POINT_TAG = "measurement_point"
GAIN_TAG = "transducer_gain"
POINT_KINDS = ("translation", "rotation")
POINT_AXES = ("world", "local")
_POINT_KEYS = ("link", "kind", "direction", "axes", "relative_to", "second", "mix")
_SECOND_KEYS = ("kind", "direction")
#: the name of a point's mix parameter: ``mix.<point>``
MIX_PREFIX = "mix."
GAIN_SIDES = ("in", "out")


@dataclass(frozen=True)
class Point:
    """A sensing / excitation point.

    Attributes:
        name: the channel name (``OUT`` or ``IN`` of ``OUT.IN``).
        link: the frame (URDF link) whose motion is measured / where the load acts.
        kind: ``translation`` (m; a force in N as an input) or ``rotation`` (rad; a torque
            in N·m as an input).
        direction: unit vector ``(3,)``.
        axes: ``world`` (direction in world axes) or ``local`` (in the link's axes at the
            operating point).
        relative_to: another frame whose motion is subtracted, or None (absolute).
        second_kind, second_direction: a second component (same frames and axes), or None.
        mix: the second component's share (``d₁ + mix · d₂``; 0 without one).
    """

    name: str
    link: str
    kind: str = "translation"
    direction: tuple[float, float, float] = (0.0, 0.0, 1.0)
    axes: str = "world"
    relative_to: str | None = None
    second_kind: str | None = None
    second_direction: tuple[float, float, float] | None = None
    mix: float = 0.0

    @property
    def mixed(self) -> bool:
        """Does the point have a second component (and a ``mix.<name>`` parameter)?"""
        return self.second_kind is not None

    def to_element(self) -> ET.Element:
        attrib = {
            "name": self.name,
            "link": self.link,
            "kind": self.kind,
            "direction": " ".join(repr(float(v)) for v in self.direction),
            "axes": self.axes,
        }
        if self.relative_to:
            attrib["relative_to"] = self.relative_to
        if self.second_kind is not None and self.second_direction is not None:
            attrib["second_kind"] = self.second_kind
            attrib["second_direction"] = " ".join(repr(float(v)) for v in self.second_direction)
            attrib["mix"] = repr(float(self.mix))
        return ET.Element(POINT_TAG, attrib)


def _fail(where: str, key: str, msg: str) -> ConfigError:
    return ConfigError(f"{where}: {key}: {msg}")


def _direction(value: Any, where: str, key: str) -> tuple[float, float, float]:
    ok = (
        isinstance(value, list | tuple)
        and len(value) == 3
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    )
    if ok:
        d = np.asarray(value, dtype=float)
        n = float(np.linalg.norm(d))
        if np.all(np.isfinite(d)) and n > 0:
            u = d / n
            return float(u[0]), float(u[1]), float(u[2])
    raise _fail(where, key, f"{value!r} is not a direction; valid: three numbers, not all 0")


def point_from_mapping(name: str, table: Mapping[str, Any], where: str) -> Point:
    """One ``[points.NAME]`` table → :class:`Point` (raises :class:`ConfigError`)."""
    key = f"points.{name}"
    if not isinstance(table, Mapping):
        raise _fail(where, key, "expected a table with link, kind, direction")
    for k in table:
        if k not in _POINT_KEYS:
            raise _fail(where, f"{key}.{k}", f"unknown key; valid: {', '.join(_POINT_KEYS)}")
    if not name or any(c in ".,=:[]" or c.isspace() for c in name):
        raise _fail(where, key, "a point name must be non-empty, without . , = : [ ] or spaces")
    link = table.get("link")
    if not isinstance(link, str) or not link:
        raise _fail(where, f"{key}.link", f"{link!r} is not a link name")
    kind = table.get("kind", "translation")
    if kind not in POINT_KINDS:
        raise _fail(where, f"{key}.kind", f"{kind!r}; valid: {', '.join(POINT_KINDS)}")
    axes = table.get("axes", "world")
    if axes not in POINT_AXES:
        raise _fail(where, f"{key}.axes", f"{axes!r}; valid: {', '.join(POINT_AXES)}")
    rel = table.get("relative_to")
    if rel is not None and (not isinstance(rel, str) or not rel):
        raise _fail(where, f"{key}.relative_to", f"{rel!r} is not a link name")
    direction = _direction(table.get("direction", [0, 0, 1]), where, f"{key}.direction")
    second = _second(table, where, key)
    mix = table.get("mix", 0.0)
    if isinstance(mix, bool) or not isinstance(mix, int | float) or not math.isfinite(mix):
        raise _fail(where, f"{key}.mix", f"{mix!r} is not a finite number")
    if second is None and "mix" in table:
        raise _fail(where, f"{key}.mix", "a mix needs a second component (second = {...})")
    if second is None:
        return Point(name, link, kind, direction, axes, rel)
    return Point(name, link, kind, direction, axes, rel, second[0], second[1], float(mix))


def _second(table: Mapping[str, Any], where: str, key: str) -> tuple[str, Any] | None:
    """A point's ``second = {kind, direction}`` table → (kind, unit direction), or None."""
    sec = table.get("second")
    if sec is None:
        return None
    if not isinstance(sec, Mapping):
        raise _fail(where, f"{key}.second", "expected a table {kind = ..., direction = [...]}")
    for k in sec:
        if k not in _SECOND_KEYS:
            raise _fail(
                where, f"{key}.second.{k}", f"unknown key; valid: {', '.join(_SECOND_KEYS)}"
            )
    kind = sec.get("kind", table.get("kind", "translation"))
    if kind not in POINT_KINDS:
        raise _fail(where, f"{key}.second.kind", f"{kind!r}; valid: {', '.join(POINT_KINDS)}")
    if "direction" not in sec:
        raise _fail(where, f"{key}.second.direction", "missing; give three numbers, not all 0")
    return kind, _direction(sec["direction"], where, f"{key}.second.direction")


def points_from_table(table: Any, where: str) -> list[Point]:
    """The ``[points]`` table (NAME → table) → points, in file order."""
    if not isinstance(table, Mapping):
        raise _fail(where, "points", "expected a table of [points.NAME] tables")
    return [point_from_mapping(str(n), t, where) for n, t in table.items()]


def check_gain_name(name: str, where: str) -> tuple[str, str]:
    """``gain.in.X`` / ``gain.out.X`` → (side, channel)."""
    parts = name.split(".", 2)
    if len(parts) != 3 or parts[0] != "gain" or parts[1] not in GAIN_SIDES or not parts[2]:
        raise _fail(where, name, "not a gain name; valid: gain.in.<input>, gain.out.<output>")
    return parts[1], parts[2]


def gains_from_table(table: Any, where: str) -> dict[str, float]:
    """The ``[gains]`` table (``"gain.in.motor" = 0.35``) → name → value."""
    if not isinstance(table, Mapping):
        raise _fail(where, "gains", 'expected a table of "gain.in.X" = VALUE entries')
    out = {}
    for name, value in table.items():
        check_gain_name(str(name), where)
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if not ok or not math.isfinite(float(value)) or float(value) == 0.0:
            raise _fail(where, f"gains.{name}", f"{value!r} is not a finite number ≠ 0")
        out[str(name)] = float(value)
    return out


# -- the URDF extension elements ------------------------------------------------------------
def point_from_element(el: ET.Element, where: str) -> Point:
    """A ``<measurement_point>`` element → :class:`Point` (raises :class:`ModelError`)."""
    table: dict[str, Any] = {k: v for k, v in el.attrib.items() if k != "name"}
    try:
        if "direction" in table:
            table["direction"] = [float(v) for v in str(table["direction"]).split()]
        if "second_kind" in table or "second_direction" in table:
            table["second"] = {
                "kind": table.pop("second_kind", None) or table.get("kind", "translation"),
                "direction": [float(v) for v in str(table.pop("second_direction", "")).split()],
            }
        if "mix" in table:
            table["mix"] = float(table["mix"])
        return point_from_mapping(el.get("name", ""), table, where)
    except (ConfigError, ValueError) as exc:
        raise ModelError(f"{where}: <{POINT_TAG} name={el.get('name')!r}>: {exc}") from None


def gain_from_element(el: ET.Element, where: str) -> tuple[str, float]:
    """A ``<transducer_gain name="gain.in.X" value="…"/>`` element → (name, value)."""
    name = el.get("name", "")
    try:
        return name, gains_from_table({name: float(el.get("value", ""))}, where)[name]
    except (ConfigError, ValueError) as exc:
        raise ModelError(f"{where}: <{GAIN_TAG} name={name!r}>: {exc}") from None


def load_points_file(path: Any) -> tuple[list[Point], dict[str, float]]:
    """A TOML file with ``[points]`` and/or ``[gains]`` tables (``--points FILE``)."""
    import tomllib
    from pathlib import Path

    p = Path(path)
    where = str(p)
    try:
        doc = tomllib.loads(p.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise ConfigError(f"{where}: cannot read the points file ({exc.strerror})") from None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"{where}: not valid UTF-8 TOML ({exc})") from None
    for key in doc:
        if key not in ("points", "gains"):
            raise _fail(where, key, "unknown key; valid: [points], [gains]")
    return (
        points_from_table(doc.get("points", {}), where),
        gains_from_table(doc.get("gains", {}), where),
    )


def apply_declarations(doc: Any, points: list[Point], gains: Mapping[str, float]) -> None:
    """Put declared points and gains into the model (a :class:`UrdfDocument`), replacing
    those of the same name that the URDF already had; checks the links exist."""
    links = set(doc.link_names)
    where = doc.source or "<URDF>"
    for pt in points:
        for frame in (pt.link, pt.relative_to):
            if frame is not None and frame not in links:
                raise ModelError(
                    f"{where}: point {pt.name!r} names link {frame!r}, which the model lacks;"
                    f" links: {', '.join(sorted(links))}"
                )
        doc.set_point(pt)
    for name, value in gains.items():
        doc.set_gain(name, value)


def channel_unit(doc: Any, name: str) -> str:
    """``m`` or ``rad``: the displacement unit of a channel name (a joint or a point)."""
    for p in doc.points:
        if p.name == name:
            return "m" if p.kind == "translation" else "rad"
    return "m" if doc.joint(name).type == "prismatic" else "rad"


def plot_units(doc: Any, names: Any) -> dict[str, Any]:
    """Plot units per channel name: ``m`` / ``rad``, or a (response, excitation) pair where a
    transducer gain makes the file's unit another one (written ``u(NAME)``)."""
    gains = doc.gains
    out: dict[str, Any] = {}
    for name in names:
        base = channel_unit(doc, name)
        force = "N" if base == "m" else "N·m"
        g_out, g_in = f"gain.out.{name}" in gains, f"gain.in.{name}" in gains
        if g_out or g_in:
            out[name] = (f"u({name})" if g_out else base, f"u({name})" if g_in else force)
        else:
            out[name] = base
    return out
