"""Keep the parts of a URDF that yourdfpy parses but does not write back.

yourdfpy's writer drops some elements inside ``<link>`` and ``<joint>`` (``<mimic>``,
``<safety_controller>``, ``<calibration>``, any unknown element) and unknown attributes.
:func:`lost_parts` compares the user's element tree with yourdfpy's rewrite of it once, at
reading; :func:`restore` puts those parts back into every later rewrite, by path (links and
joints by name, deeper elements by tag and position among same-tag siblings). Only parts
yourdfpy never wrote are restored, so values bondid edits are never overwritten.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from dataclasses import dataclass

Key = tuple[str, str]


@dataclass(frozen=True)
class LostPart:
    """A child element (``element``) or an attribute (``attribute``, ``value``) at ``path``."""

    path: tuple[Key, ...]
    element: ET.Element | None = None
    attribute: str | None = None
    value: str | None = None


def _keys(parent: ET.Element, top: bool) -> list[tuple[Key, ET.Element]]:
    out: list[tuple[Key, ET.Element]] = []
    seen: dict[str, int] = {}
    for el in parent:
        if not isinstance(el.tag, str):
            continue  # comments, processing instructions
        if top and el.get("name") is not None:
            out.append(((el.tag, "name=" + str(el.get("name"))), el))
            continue
        n = seen.get(el.tag, 0)
        seen[el.tag] = n + 1
        out.append(((el.tag, str(n)), el))
    return out


def _walk(orig: ET.Element, written: ET.Element, path: tuple[Key, ...], out: list[LostPart]):
    for name, value in orig.attrib.items():
        if name not in written.attrib:
            out.append(LostPart(path, attribute=name, value=value))
    have = dict(_keys(written, not path))
    for key, child in _keys(orig, not path):
        if key in have:
            _walk(child, have[key], (*path, key), out)
        else:
            out.append(LostPart(path, element=copy.deepcopy(child)))


def lost_parts(original: ET.Element, written: ET.Element) -> list[LostPart]:
    """What ``written`` (yourdfpy's rewrite) lacks of ``original`` (both ``<robot>``)."""
    out: list[LostPart] = []
    _walk(original, written, (), out)
    return out


def _find(root: ET.Element, path: tuple[Key, ...]) -> ET.Element | None:
    el: ET.Element | None = root
    for i, key in enumerate(path):
        assert el is not None
        el = dict(_keys(el, i == 0)).get(key)
        if el is None:
            return None  # the element was removed or renamed since reading
    return el


def restore(root: ET.Element, parts: list[LostPart]) -> None:
    """Put ``parts`` back into ``root`` (a fresh rewrite), in place."""
    for part in parts:
        el = _find(root, part.path)
        if el is None:
            continue
        if part.element is not None:
            el.append(copy.deepcopy(part.element))
        elif part.attribute is not None and part.attribute not in el.attrib:
            el.set(part.attribute, str(part.value))
