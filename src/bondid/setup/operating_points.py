"""Operating points of data files given outside the files: ``--operating-point
FILE=x=0.1,y=0.3`` (repeatable) and a study file's ``[operating_points]`` table.

They are for files that state none (a UFF58 file from another tool, a CSV without the
``# operating_point`` line); given for a file that states one, the given one wins and a
warning says so. The joints are checked against the model like a file's own.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..data.measurement import FrfData
from ..exceptions import ConfigError
from ..model.document import UrdfDocument

OPTION = "--operating-point"


def add_operating_point_arg(p: Any) -> None:
    """``--operating-point FILE=JOINT=VALUE,...`` (repeatable)."""
    p.add_argument(
        OPTION, action="append", default=[], metavar="FILE=JOINT=V,...",
        help="the operating point of a data file that states none, e.g."
        " --operating-point pose_a.uff=x=0.1,y=0.3 (m or rad; joints not named are at 0);"
        " repeatable",
    )  # fmt: skip


def parse_option(text: str) -> tuple[str, dict[str, float]]:
    """``"FILE=x=0.1,y=0.3"`` → ``("FILE", {"x": 0.1, "y": 0.3})``; ``"FILE="`` = neutral.

    Raises:
        ConfigError: not FILE=JOINT=VALUE,...; OperatingPointError: a bad JOINT=VALUE.
    """
    from ..linear.operating_point import parse_operating_point

    file, sep, rest = text.partition("=")
    if not sep or not file:
        raise ConfigError(
            f"{OPTION} {text!r}: not FILE=JOINT=VALUE,... (e.g. pose_a.uff=x=0.1,y=0.3)"
        )
    return file, parse_operating_point(rest, f"{OPTION} {text!r}")


def from_table(table: Any, where: str, base: Path) -> dict[str, dict[str, float]]:
    """A study's ``[operating_points]``: ``"file" = {x = 0.1}`` or ``"file" = "x=0.1 y=0.3"``
    (file paths relative to the study file)."""
    from ..linear.operating_point import parse_operating_point

    if not isinstance(table, Mapping):
        raise ConfigError(f"{where}: operating_points: not a table of file = operating point")
    out: dict[str, dict[str, float]] = {}
    for file, op in table.items():
        key = f"{where}: operating_points.{file}"
        if isinstance(op, str):
            value = parse_operating_point(op, key)
        elif isinstance(op, Mapping) and all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in op.values()
        ):
            value = {str(k): float(v) for k, v in op.items()}
        else:
            raise ConfigError(f"{key}: {op!r} is not {{joint = value, ...}} or 'x=0.1 y=0.3'")
        out[str(base / file)] = value
    return out


def _matches(source: str, file: str) -> bool:
    """True when ``file`` (as given) names the data file ``source``."""
    if source == file:
        return True
    try:
        return Path(source).resolve() == Path(file).resolve()
    except OSError:
        return False


def apply_operating_points(
    datasets: Sequence[FrfData], given: Mapping[str, Mapping[str, float]]
) -> list[str]:
    """Set the operating point of each data set named in ``given`` (in place); returns the
    warnings (a file's own operating point replaced).

    Raises:
        ConfigError: a FILE of ``given`` is none of the data files.
    """
    warnings = []
    for file, op in given.items():
        hits = [ds for ds in datasets if ds.source and _matches(ds.source, file)]
        if not hits:
            valid = ", ".join(str(ds.source) for ds in datasets)
            raise ConfigError(f"{OPTION} {file}: not one of the data files; valid: {valid}")
        for ds in hits:
            if ds.operating_point and dict(ds.operating_point) != dict(op):
                warnings.append(
                    f"{ds.source}: its operating point {_text(ds.operating_point)} replaced by"
                    f" {_text(op)} from {OPTION}"
                )
            ds.operating_point = dict(op)
    return warnings


def _text(op: Mapping[str, float]) -> str:
    return " ".join(f"{k}={v:g}" for k, v in op.items()) or "neutral"


def operating_points_of(args: argparse.Namespace) -> dict[str, dict[str, float]]:
    """The ``--operating-point`` items of ``args`` (a later one for the same file wins)."""
    return dict(parse_option(t) for t in getattr(args, "operating_point", None) or [])


def given_operating_points(
    doc: UrdfDocument, datasets: Sequence[FrfData], given: Mapping[str, Mapping[str, float]]
) -> list[str]:
    """Apply ``given`` (:func:`apply_operating_points`), check its joints against ``doc``,
    and warn about files that still have no operating point while the model depends on the
    pose (:func:`bondid.validation.pose.pose_warnings`); returns the warnings."""
    from ..data.io import check_against_model
    from ..linear.affine import model_inputs, model_outputs
    from ..validation.pose import pose_warnings

    warnings = apply_operating_points(datasets, given)
    inputs, outputs = model_inputs(doc), model_outputs(doc)
    for ds in datasets:
        check_against_model(ds, inputs=inputs, outputs=outputs, joints=doc.movable_joint_names)
    named = {id(ds) for ds in datasets for f in given if ds.source and _matches(ds.source, f)}
    return warnings + pose_warnings(doc, [ds for ds in datasets if id(ds) not in named])
