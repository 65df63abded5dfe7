"""URDF text to yourdfpy's tree and the elements it drops, and back, for
:class:`~.document.UrdfDocument`.

yourdfpy models links, joints and materials; every other top-level element (``<transmission>``,
``<gazebo>``, bondid's measurement points and gains) is kept aside verbatim, and what its
writer drops inside links and joints is recorded (:mod:`.preserve`) so that writing restores
it: a read → write round trip loses nothing of a user's file.
"""

from __future__ import annotations

import contextlib
import copy
import importlib
import io
import xml.etree.ElementTree as ET
from typing import Any

from ..exceptions import ModelError
from ..interrupt import signals_deferred
from .preserve import LostPart, lost_parts, restore
from .structure import check_structure

#: the top-level elements yourdfpy models; every other one is kept aside verbatim
YOURDFPY_TAGS = ("link", "joint", "material")


def parse_urdf(xml: str, where: str) -> tuple[Any, list[ET.Element], list[LostPart]]:
    """URDF text as ``(yourdfpy URDF, the top-level elements it does not model, the parts
    inside links and joints its writer drops)``; ``where`` names the text in errors.

    Raises:
        ModelError: too deep or too long a structure, not well-formed XML, a root other
            than ``<robot>``, or a file yourdfpy cannot read.
    """
    yourdfpy = _import_yourdfpy()

    check_structure(xml, where)  # before any tree: depth and chain limits
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as exc:
        raise ModelError(f"{where}: not well-formed XML ({exc})") from exc
    if root.tag != "robot":
        raise ModelError(f"{where}: root element is <{root.tag}>, expected <robot>")
    extras = [copy.deepcopy(el) for el in root if el.tag not in YOURDFPY_TAGS]
    core = ET.Element("robot", root.attrib)
    core.extend(el for el in root if el.tag in YOURDFPY_TAGS)
    try:
        urdf = yourdfpy.URDF.load(
            io.BytesIO(ET.tostring(_writable(core))),
            build_scene_graph=False,
            load_meshes=False,
            filename_handler=yourdfpy.filename_handler_null,
        )
    except Exception as exc:  # yourdfpy raises assorted errors on bad files
        raise ModelError(f"{where}: yourdfpy could not read the URDF ({exc})") from exc
    try:
        lost = lost_parts(core, ET.fromstring(urdf.write_xml_string()))
    except Exception:  # yourdfpy cannot write it back: writing the text will say so
        lost = []
    return urdf, extras, lost


def urdf_text(urdf: Any, lost: list[LostPart], extras: list[ET.Element]) -> str:
    """The URDF text of yourdfpy's ``urdf`` with the ``lost`` parts restored and the
    ``extras`` appended (pretty-printed, full double precision)."""
    core = ET.fromstring(urdf.write_xml_string())
    restore(core, lost)
    _write_mimics(core, urdf.robot.joints)
    for el in extras:
        core.append(copy.deepcopy(el))
    ET.indent(core, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(core, encoding="unicode") + "\n"


def _write_mimics(core: ET.Element, joints: Any) -> None:
    """Write every joint's ``<mimic>`` from its current values (yourdfpy does not write it,
    and the element kept from the file would hold a multiplier since changed), in place."""
    by_name = {el.get("name"): el for el in core.findall("joint")}
    for j in joints:
        el = by_name.get(j.name)
        if el is None:
            continue
        for old in el.findall("mimic"):
            el.remove(old)
        m = getattr(j, "mimic", None)
        if m is None:
            continue
        attrib = {"joint": str(m.joint)}
        if m.multiplier is not None:
            attrib["multiplier"] = repr(float(m.multiplier))
        if m.offset is not None:
            attrib["offset"] = repr(float(m.offset))
        ET.SubElement(el, "mimic", attrib)


def _import_yourdfpy() -> Any:
    """``import yourdfpy``, interruptible. trimesh (which yourdfpy imports) wraps its own
    imports of SciPy, networkx and others in ``except BaseException``: a Ctrl-C landing
    there is swallowed and the command goes on for seconds. So those are imported first,
    where an interrupt goes through, and the rest of the import runs with the interrupt
    held until it ends (:func:`bondid.interrupt.signals_deferred`, a fraction of a second)."""
    for name in ("scipy.sparse", "scipy.spatial", "scipy.optimize", "networkx"):
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
    with signals_deferred():
        import yourdfpy
    return yourdfpy


def _writable(core: ET.Element) -> ET.Element:
    """A copy of ``core`` without what yourdfpy reads but cannot write back (a ``<texture>``
    without ``filename``); :mod:`.preserve` restores it on writing."""
    out = copy.deepcopy(core)
    for mat in out.iter("material"):
        for tex in mat.findall("texture"):
            if tex.get("filename") is None:
                mat.remove(tex)
    return out
