"""Reading measured data for a given model: UFF channel maps from its joints, and checks."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence

from ..data.io import check_against_model, read_frf
from ..data.measurement import FrfData
from ..data.uff_format import default_channel_map
from ..exceptions import ConfigError
from ..model.document import UrdfDocument


def model_channel_map(doc: UrdfDocument) -> dict[str, tuple[int, int]]:
    """The spec's default UFF58 map for ``doc``: node i = i-th transmitted joint (1-based),
    direction code from the joint axis; then the measurement points (extension), numbered
    on, direction code from the point's kind and direction."""
    joints = [t.joint for t in doc.transmissions]
    axes = [doc.joint(j).axis if doc.joint(j).axis is not None else (1.0, 0.0, 0.0) for j in joints]
    kinds = [str(doc.joint(j).type) for j in joints]
    points = doc.points
    joints += [p.name for p in points]
    axes += [p.direction for p in points]
    kinds += ["prismatic" if p.kind == "translation" else "revolute" for p in points]
    return default_channel_map(joints, axes, kinds)


def parse_uff_map_item(text: str, where: str = "--uff-map") -> tuple[str, tuple[int, int]]:
    """``NAME=NODE:DIR`` (e.g. ``acc=101:+3``) → ``(name, (node, direction))``; UFF direction
    codes ±1..±3 translation along x/y/z, ±4..±6 rotation about x/y/z."""
    name, eq, value = text.partition("=")
    try:
        node_s, colon, dir_s = value.partition(":")
        if not eq or not colon or not name:
            raise ValueError
        return name.strip(), (int(node_s), int(dir_s))
    except ValueError:
        raise ConfigError(
            f"{where} {text!r}: not NAME=NODE:DIRECTION (e.g. acc=101:+3; direction ±1..±6)"
        ) from None


def load_datasets(
    doc: UrdfDocument,
    paths: Sequence[str | os.PathLike[str]],
    *,
    drop_nan: bool = False,
    channel_map: Mapping[str, tuple[int, int]] | None = None,
) -> list[FrfData]:
    """Read every file (CSV or UFF58) and check its channels and operating point against
    ``doc``; raises the data errors of :mod:`bondid.data` naming the file.

    ``channel_map`` ``{channel name: (node, direction)}`` names the records of UFF58 files
    (joints and measurement points; it replaces the default map of the spec, node i = i-th
    transmitted joint)."""
    from ..linear.affine import model_inputs, model_outputs

    cmap = dict(channel_map) if channel_map else model_channel_map(doc)
    inputs = model_inputs(doc)
    outputs = model_outputs(doc)
    movable = doc.movable_joint_names
    out = []
    for p in paths:
        ds = read_frf(
            p,
            drop_nan=drop_nan,
            channel_map=cmap if str(p).lower().endswith((".uff", ".unv", ".uff58")) else None,
        )
        check_against_model(ds, inputs=inputs, outputs=outputs, joints=movable)
        out.append(ds)
    return out
