"""The model-side settings of a fit: measurement points, gains, mesh package path, a
floating base, a UFF58 channel map — read from the study file and the command line, and
applied to the loaded model."""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..model.document import UrdfDocument
from ..model.points import apply_declarations, gains_from_table, load_points_file, points_from_table
from .setting_checks import check_bool, check_path, check_table, config_error
from .settings import StudySettings


def read_model_keys(doc: Mapping[str, Any], s: StudySettings, where: str, base: Path) -> None:
    """The study keys ``points``, ``gains``, ``points_file``, ``package_path``,
    ``floating_base``, ``uff_map``, ``operating_points`` and ``damping`` into ``s`` (raises
    ``ConfigError`` naming the key)."""
    if "points" in doc:
        s.points = points_from_table(doc["points"], where)
    if "gains" in doc:
        s.gains = gains_from_table(doc["gains"], where)
    if "points_file" in doc:
        s.points_file = check_path(doc["points_file"], base, where, "points_file")
    if "package_path" in doc:
        items = doc["package_path"]
        items = [items] if isinstance(items, str) else items
        if not isinstance(items, list):
            raise config_error(
                where, "package_path", f"{items!r} is not a folder or a list of them"
            )
        s.package_path = [
            check_path(v, base, where, f"package_path[{i}]") for i, v in enumerate(items)
        ]
    if "operating_points" in doc:
        from ..setup.operating_points import from_table

        s.operating_points = from_table(doc["operating_points"], where, base)
    if "damping" in doc:
        from ..setup.damping import damping_from_study

        s.damping, s.damping_start = damping_from_study(doc["damping"], where)
    if "floating_base" in doc:
        s.floating_base = check_bool(doc["floating_base"], where, "floating_base")
    for name, v in check_table(doc.get("uff_map", {}), where, "uff_map").items():
        ok = isinstance(v, list) and len(v) == 2 and all(type(x) is int for x in v)
        if not ok or not -6 <= v[1] <= 6 or v[0] < 0:
            raise config_error(where, f"uff_map.{name}", f"{v!r} is not [NODE, DIRECTION (±1..±6)]")
        s.uff_map[str(name)] = (int(v[0]), int(v[1]))


def uff_map(s: StudySettings, items: Sequence[str]) -> dict[str, tuple[int, int]] | None:
    """The study's ``[uff_map]`` updated by ``--uff-map`` items (None when neither gives one)."""
    from ..validation.datasets import parse_uff_map_item

    out = dict(s.uff_map)
    out.update(parse_uff_map_item(t) for t in items)
    return out or None


def prepare_model(doc: UrdfDocument, s: StudySettings, args: argparse.Namespace) -> None:
    """Apply the package path, a floating base, then the study's points and gains and those
    of its ``points_file`` and of ``--points-file`` (each later one winning) to ``doc``."""
    doc.package_path = [str(p) for p in [*args.package_path, *s.package_path]]
    if args.floating_base if args.floating_base is not None else s.floating_base:
        from ..model.authoring import add_floating_base

        add_floating_base(doc)
    apply_declarations(doc, s.points, s.gains)
    for f in (s.points_file, args.points_file):
        if f is not None:
            apply_declarations(doc, *load_points_file(f))
