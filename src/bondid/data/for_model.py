"""Reading measured data for a given model: UFF channel maps from its joints, and checks."""

from __future__ import annotations

import os
from collections.abc import Sequence

from ..model.document import UrdfDocument
from .io import check_against_model, read_frf
from .measurement import FrfData
from .uff_format import default_channel_map


def model_channel_map(doc: UrdfDocument) -> dict[str, tuple[int, int]]:
    """The spec's default UFF58 map for ``doc``: node i = i-th transmitted joint (1-based),
    direction code from the joint axis."""
    joints = [t.joint for t in doc.transmissions]
    axes = [doc.joint(j).axis if doc.joint(j).axis is not None else (1.0, 0.0, 0.0) for j in joints]
    kinds = [str(doc.joint(j).type) for j in joints]
    return default_channel_map(joints, axes, kinds)


def load_datasets(
    doc: UrdfDocument, paths: Sequence[str | os.PathLike[str]], *, drop_nan: bool = False
) -> list[FrfData]:
    """Read every file (CSV or UFF58) and check its channels and operating point against
    ``doc``; raises the data errors of :mod:`bondid.data` naming the file."""
    from ..linear.affine import model_inputs, model_outputs

    cmap = model_channel_map(doc)
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
