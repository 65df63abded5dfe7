"""The structural limits of a URDF, checked in one streaming pass before it is parsed into
a tree: :func:`check_structure`.

A tree parser, a deep copy and every recursive walk of the model hold one stack frame per
level: 200,000 nested elements crash the process (a segmentation fault in a deep copy), a
chain of 3,000 links exhausts Python's recursion. The pass here holds no tree and no
recursion: it counts the element depth and the elements (expat), and collects each joint's
parent and child link to measure the longest chain from the root. Limits:
:data:`~bondid.ranges.MAX_XML_DEPTH`, :data:`~bondid.ranges.MAX_XML_ELEMENTS`,
:data:`~bondid.ranges.MAX_CHAIN_DEPTH`. Malformed XML is left to the parser, which names
the line.
"""

from __future__ import annotations

from typing import Any
from xml.parsers import expat

from ..exceptions import ModelError
from ..ranges import MAX_CHAIN_DEPTH, MAX_XML_DEPTH, MAX_XML_ELEMENTS


class _Stop(Exception):
    """Raised from an expat handler to end the pass with a message."""


def check_structure(xml: str, where: str) -> None:
    """Refuse a URDF nested deeper, larger or with a longer link chain than the limits.

    Args:
        xml: the file's text.
        where: the file's name, for messages.

    Raises:
        ModelError: naming the file, what was found and the limit.
    """
    state: dict[str, Any] = {"depth": 0, "count": 0, "joint": None}
    parent_of: dict[str, str] = {}

    def start(name: str, attrs: dict[str, str]) -> None:
        state["depth"] += 1
        state["count"] += 1
        depth = state["depth"]
        if depth > MAX_XML_DEPTH:
            raise _Stop(
                f"XML elements nested more than {MAX_XML_DEPTH} deep (<{name}>); valid: a URDF"
                f" nested at most {MAX_XML_DEPTH} elements deep"
            )
        if state["count"] > MAX_XML_ELEMENTS:
            raise _Stop(f"more than {MAX_XML_ELEMENTS} XML elements; valid: at most that many")
        if depth == 2:
            state["joint"] = {} if name == "joint" else None
        elif depth == 3 and state["joint"] is not None and name in ("parent", "child"):
            state["joint"][name] = attrs.get("link")

    def end(name: str) -> None:
        if state["depth"] == 2 and state["joint"] is not None:
            j = state["joint"]
            if j.get("parent") and j.get("child"):
                parent_of.setdefault(j["child"], j["parent"])
            state["joint"] = None
        state["depth"] -= 1

    parser = expat.ParserCreate()
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(xml, True)
    except _Stop as exc:
        raise ModelError(f"{where}: {exc}") from None
    except expat.ExpatError:
        return  # the tree parser reports malformed XML with its line
    longest = chain_depth(parent_of)
    if longest > MAX_CHAIN_DEPTH:
        raise ModelError(
            f"{where}: a chain of {longest} links from the root; valid: at most"
            f" {MAX_CHAIN_DEPTH} links from the root to any link"
        )


def chain_depth(parent_of: dict[str, str]) -> int:
    """The most joints between a link and its root, following ``parent_of`` (child →
    parent) without recursion; a loop counts its links once (the model checks report it)."""
    depth: dict[str, int] = {}
    for link in parent_of:
        path: list[str] = []
        seen: set[str] = set()
        n = link
        while n in parent_of and n not in depth and n not in seen:
            seen.add(n)
            path.append(n)
            n = parent_of[n]
        base = depth.get(n, 0)
        for k, m in enumerate(reversed(path), start=1):
            depth[m] = base + k
    return max(depth.values(), default=0)
