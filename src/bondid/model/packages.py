"""Mesh files as URDFs name them: ``package://``, ``file://`` and relative paths.

A ``package://PKG/REST`` URI is looked up, in this order, in

1. the package path given by the user (``--package-path DIR``, repeatable, or
   ``UrdfDocument.package_path``),
2. ``ROS_PACKAGE_PATH`` (``os.pathsep``-separated),
3. the folders above the URDF file (a URDF in ``PKG/urdf/robot.urdf`` names its own package),
4. example-robot-data's own install folders (its ``robots`` folder and the folder holding
   ``example-robot-data``), when it is installed.

Each search folder may be a package itself (its name is ``PKG``) or hold packages
(``DIR/PKG``). A relative path is relative to the URDF's folder. Nothing is cached and no
environment is changed.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..exceptions import ModelError


def _erd_roots() -> list[Path]:
    try:
        import example_robot_data as erd

        robots = Path(erd.getModelPath("ur_description/urdf/ur5_robot.urdf"))
    except Exception:  # not installed, or an unusual layout: nothing to add
        return []
    return [robots, robots.parent.parent] if robots.is_dir() else []


def search_roots(doc: Any, extra: Sequence[str | os.PathLike[str]] = ()) -> list[Path]:
    """The folders searched for ``package://`` URIs of ``doc``, in order."""
    roots = [Path(p) for p in (*extra, *getattr(doc, "package_path", []))]
    env = os.environ.get("ROS_PACKAGE_PATH", "")
    roots += [Path(p) for p in env.split(os.pathsep) if p]
    if doc.source:
        here = Path(doc.source).resolve().parent
        roots += [here, *here.parents]
    return roots + _erd_roots()


def _urdf_dir(doc: Any) -> Path:
    return Path(doc.source).resolve().parent if doc.source else Path.cwd()


def resolve_mesh(filename: str, urdf_dir: Path, roots: Sequence[Path]) -> str:
    """The file a mesh ``filename`` names; raises :class:`ModelError` saying where it looked."""
    if filename.startswith("file://"):
        return filename[len("file://") :]
    if not filename.startswith("package://"):
        p = Path(filename)
        return os.path.normpath(p if p.is_absolute() else urdf_dir / p)
    pkg, _, rest = filename[len("package://") :].partition("/")
    for root in roots:
        for cand in (root / rest if root.name == pkg else None, root / pkg / rest):
            if cand is not None and cand.is_file():
                return str(cand)
    raise ModelError(
        f"mesh {filename!r}: package {pkg!r} not found; give its parent folder with"
        " --package-path DIR (or ROS_PACKAGE_PATH); searched: "
        + ", ".join(str(r) for r in roots[:8])
        + (" …" if len(roots) > 8 else "")
    )


def mesh_resolver(doc: Any, extra: Sequence[str | os.PathLike[str]] = ()) -> Callable[[str], str]:
    """``resolve(filename) -> path`` for the meshes of ``doc`` (see the module docstring)."""
    roots = search_roots(doc, extra)
    base = _urdf_dir(doc)

    def resolve(filename: str) -> str:
        try:
            return resolve_mesh(filename, base, roots)
        except ModelError as exc:
            raise ModelError(f"{doc.source or '<URDF>'}: {exc}") from None

    return resolve


def text_with_resolved_meshes(doc: Any, extra: Sequence[str | os.PathLike[str]] = ()) -> str:
    """``doc``'s URDF text with every mesh filename replaced by the absolute path of its file
    (for readers that know no package path, e.g. Pinocchio's geometry from a string).

    Raises:
        ModelError: a mesh is not found (the message says where it was looked for).
    """
    return _resolved_text(doc, extra, strict=True)[0]


def with_absolute_meshes(doc: Any) -> tuple[Any, dict[str, str]]:
    """A copy of ``doc`` (same source and package path) whose mesh filenames are the absolute
    paths of their files, so that its text, read anywhere (a worker process, another folder),
    still finds them; and ``{absolute path: filename as written}`` for
    :func:`restore_mesh_names`. A mesh that is not found keeps its name (what needs it says so
    later). ``doc`` itself and ``{}`` when nothing changes."""
    from .document import UrdfDocument

    text, names = _resolved_text(doc, (), strict=False)
    if not names:
        return doc, {}
    out = UrdfDocument.from_string(text, source=doc.source)
    out.package_path = list(getattr(doc, "package_path", []))
    return out, names


def restore_mesh_names(text: str, names: dict[str, str]) -> str:
    """URDF ``text`` with the absolute mesh paths of :func:`with_absolute_meshes` (``names``)
    put back as the user wrote them (``package://…``, relative)."""
    from xml.sax.saxutils import quoteattr

    for path, name in names.items():
        text = text.replace(f"filename={quoteattr(path)}", f"filename={quoteattr(name)}")
    return text


def _resolved_text(
    doc: Any, extra: Sequence[str | os.PathLike[str]], strict: bool
) -> tuple[str, dict[str, str]]:
    """``doc``'s text with its mesh filenames resolved, and ``{absolute: as written}`` of
    those changed; ``strict``: raise on a mesh not found (else it is left as written)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(doc.to_string())
    resolve = mesh_resolver(doc, extra)
    names: dict[str, str] = {}
    for mesh in root.iter("mesh"):
        name = mesh.get("filename")
        if not name:
            continue
        try:
            path = os.path.abspath(resolve(name))
        except ModelError:
            if strict:
                raise
            continue
        if path != name:
            mesh.set("filename", path)
            names[path] = name
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n", names
