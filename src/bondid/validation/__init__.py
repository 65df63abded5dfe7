"""One validation layer, used by every command before any work.

* :func:`load_model` — read the URDF and check it can be a machine (:mod:`.model`).
* :func:`check_inputs` — the data (:mod:`.data`) and the operating points
  (:mod:`.operating_point`) for the model.
* :func:`check_selection` — the channels and bands a command is told to use, against the
  data (:mod:`.selection`).

Errors are :class:`~bondid.exceptions.ModelError` / :class:`~bondid.exceptions.DataError`
(exit 2) naming the file, the item and what would be valid; suspicious but possible inputs
give warnings, which every command prints and stores under ``warnings`` in its JSON.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence

from ..data.measurement import FrfData
from ..model.document import UrdfDocument
from .data import check_data
from .model import check_model
from .operating_point import check_operating_point
from .selection import check_selection

__all__ = [
    "check_data",
    "check_inputs",
    "check_model",
    "check_operating_point",
    "check_selection",
    "load_model",
]


def load_model(
    path: str | os.PathLike[str], prepare: Callable[[UrdfDocument], None] | None = None
) -> tuple[UrdfDocument, list[str]]:
    """Read and check a URDF; returns the document and the model's warnings.

    ``prepare`` edits the document before the checks (the command's model options: package
    path, floating base, measurement points and gains), so the checks see the model used.
    """
    doc = UrdfDocument.load(path)
    if prepare is not None:
        prepare(doc)
    return doc, check_model(doc)


def check_inputs(
    doc: UrdfDocument,
    datasets: Sequence[FrfData] = (),
    paths: Sequence[str | os.PathLike[str]] = (),
    operating_points: Mapping[str, Mapping[str, float]] | None = None,
) -> list[str]:
    """Data and operating-point checks; returns the warnings.

    Args:
        doc: the (checked) model.
        datasets: measured data, one per file in ``paths``; each one's operating point is
            checked too.
        paths: the data files as given.
        operating_points: more operating points by origin (e.g. ``{"--q": {...}}``).
    """
    warnings = check_data(doc, datasets, paths)
    for ds in datasets:
        f_min = float(ds.freq_hz.min()) if ds.freq_hz.size else None  # positive (FrfData)
        warnings += check_operating_point(doc, ds.operating_point, str(ds.source or "data"),
                                          f_min)  # fmt: skip
    for what, op in (operating_points or {}).items():
        warnings += check_operating_point(doc, op, what)
    return warnings
