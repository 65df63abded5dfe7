"""Measured FRFs in Universal File Format data set 58, through ``pyuff``.

One type-58 record per channel (function type 4, FRF, complex double precision) and, where
the data carry coherence, one more record per channel of function type 6 (coherence, real).
A record's response node/direction is the output channel (a joint or a measurement point),
its reference node/direction the input channel, as given by a channel map ``{channel name:
(node, direction)}`` (UFF direction codes: ±1..±3 translation along x/y/z, ±4..±6 rotation
about x/y/z, 0 scalar).

Files are written in binary 58 ("58b"): pyuff's ASCII layout keeps only 6 significant
digits of the frequencies (``E13.5``) and 12 of the values (``E20.11``), binary keeps every
bit. bondid also writes, in the ID lines, ``bondid-frf: 1 quantity: ...`` (line 1),
``channel: OUT.IN`` (line 2) and ``operating_point: ...`` (lines 3-5), so its own files read
back without a channel map. Values are taken to be in SI units.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from ..atomic import atomic_path
from ..exceptions import ChannelError, DataError, DependencyError, ModelError
from ._common import (
    FORMAT_VERSION,
    check_joint_name,
    dc_note,
    format_operating_point,
    parse_operating_point,
    written_channels,
)
from .measurement import FrfData
from .uff_records import (
    FUNC_COHERENCE,
    FUNC_FRF,
    ID_WIDTH,
    OP_PREFIX,
    SPEC_FORCE,
    SPEC_FREQUENCY,
    SPEC_OF_QUANTITY,
    ChannelMap,
    RecordSet,
    check_map,
    role_inverses,
)


def _pyuff() -> ModuleType:
    try:
        import pyuff
    except ImportError as exc:  # pragma: no cover - pyuff is a dependency
        raise DependencyError(f"reading/writing UFF files needs pyuff ({exc})") from None
    return pyuff


def default_channel_map(
    joint_names: Sequence[str],
    joint_axes: Sequence[Sequence[float]] | np.ndarray,
    joint_kinds: Sequence[str],
) -> dict[str, tuple[int, int]]:
    """The spec's default channel map: node ``i`` = i-th joint (1-based), direction from its axis.

    Args:
        joint_names: the transmitted joints, in transmission order, length ``n``.
        joint_axes: their axes, shape ``(n, 3)`` (unit vectors in the joint frame).
        joint_kinds: ``"prismatic"`` or ``"revolute"`` (``"continuous"`` counts as revolute).

    Returns:
        ``{joint: (node, direction)}``; direction is ±1..±3 (translation along x/y/z) for a
        prismatic joint and ±4..±6 (rotation about x/y/z) for a revolute one, taken from the
        axis's largest component (the first one on a tie) and its sign.
    """
    axes = np.asarray(joint_axes, dtype=float)
    n = len(joint_names)
    if axes.shape != (n, 3) or len(joint_kinds) != n:
        raise ModelError(
            f"default_channel_map: {n} joints need axes of shape ({n}, 3) and {n} kinds; "
            f"got axes {axes.shape} and {len(joint_kinds)} kinds"
        )
    out: dict[str, tuple[int, int]] = {}
    for k, (name, axis, kind) in enumerate(zip(joint_names, axes, joint_kinds, strict=True)):
        check_joint_name(name, "default_channel_map")
        if kind not in ("prismatic", "revolute", "continuous"):
            raise ModelError(
                f"default_channel_map: joint {name!r} has kind {kind!r}; valid: prismatic, revolute"
            )
        if not np.all(np.isfinite(axis)) or not np.any(axis):
            raise ModelError(f"default_channel_map: joint {name!r} has no valid axis {axis}")
        if name in out:
            raise ModelError(f"default_channel_map: joint {name!r} is listed twice")
        c = int(np.argmax(np.abs(axis)))
        code = c + 1 + (0 if kind == "prismatic" else 3)
        out[name] = (k + 1, code if axis[c] > 0 else -code)
    return out


def _op_lines(data: FrfData, where: str) -> list[str]:
    """``operating_point: ...`` ID lines (at most three of 80 characters)."""
    lines = [OP_PREFIX]
    for token in format_operating_point(data.operating_point, where):
        if len(lines[-1]) + 1 + len(token) <= ID_WIDTH:
            lines[-1] += " " + token
        else:
            lines.append(f"{OP_PREFIX} {token}")
    if len(lines) > 3 or any(len(s) > ID_WIDTH for s in lines):
        raise DataError(
            f"{where}: the operating point does not fit in UFF ID lines 3-5 (3 x 80 characters); "
            f"write CSV instead"
        )
    return lines + ["NONE"] * (3 - len(lines))


def write_uff58(
    data: FrfData,
    path: str | os.PathLike[str],
    *,
    channel_map: ChannelMap | None = None,
    binary: bool = True,
) -> Path:
    """Write ``data`` as UFF type-58 records (one per channel, plus coherence), atomically.

    Args:
        data: the FRFs (``H`` ``(n_out, n_in, n_freq)`` in SI units, ``freq_hz`` in Hz).
        path: the ``.uff``/``.unv`` file to write.
        channel_map: ``{channel name: (node, direction)}`` for every name of a written
            channel (a joint or a measurement point; one node and axis may carry a
            response's and a reference's name); default: node ``k`` = k-th name of
            ``outputs`` then new ``inputs``, direction 0 (scalar).
        binary: write binary 58b (exact, default) or ASCII 58 (6 significant digits of
            frequency, 12 of the values).

    Returns:
        The path written.
    """
    where = str(path)
    chans = written_channels(data, where)
    cmap = _write_map(data, chans, channel_map, where)
    op = _op_lines(data, where)
    common: dict[str, Any] = {
        "type": 58,
        "binary": int(binary),
        "id3": op[0],
        "id4": op[1],
        "id5": op[2],
        "abscissa_spacing": 0,
        "abscissa_spec_data_type": SPEC_FREQUENCY,
        "abscissa_axis_units_lab": "Hz",
        "x": np.asarray(data.freq_hz, dtype=float),
    }
    # every FRF record first, then the coherence records of the channels that have one
    records = [(a, b, False) for a, b, _ in chans] + [(a, b, True) for a, b, c in chans if c]
    dsets = [
        _record(data, a, b, coherence, cmap, where, dict(common, ver_num=k + 1))
        for k, (a, b, coherence) in enumerate(records)
    ]
    pyuff = _pyuff()
    with atomic_path(path) as tmp:
        # mode "add" on the fresh empty file: pyuff's "overwrite" truncates binary records.
        pyuff.UFF(str(tmp)).write_sets(dsets, mode="add")
    return Path(path)


def _write_map(
    data: FrfData,
    chans: list[tuple[int, int, bool]],
    channel_map: ChannelMap | None,
    where: str,
) -> dict[str, tuple[int, int]]:
    """The checked channel map for writing (default: node k = k-th joint, direction 0)."""
    joints = list(dict.fromkeys((*data.outputs, *data.inputs)))
    if channel_map is None:
        return {j: (k + 1, 0) for k, j in enumerate(joints)}
    cmap = check_map(channel_map, where)
    used = {data.outputs[a] for a, _, _ in chans} | {data.inputs[b] for _, b, _ in chans}
    missing = [j for j in joints if j in used and j not in cmap]
    if missing:
        raise ChannelError(
            f"{where}: channel map lacks channel names {', '.join(missing)}; "
            f"it maps {', '.join(cmap) or 'nothing'}"
        )
    return cmap


def _record(
    data: FrfData,
    a: int,
    b: int,
    coherence: bool,
    cmap: dict[str, tuple[int, int]],
    where: str,
    d: dict[str, Any],
) -> dict[str, Any]:
    """Complete ``d`` (the fields all records share) into channel ``(a, b)``'s FRF record,
    or its coherence record when ``coherence``."""
    out, inp = data.outputs[a], data.inputs[b]
    id2 = f"channel: {out}.{inp}"
    if len(id2) > ID_WIDTH:
        raise ChannelError(
            f"{where}: channel name {out}.{inp} is too long for a UFF ID line "
            f"(max {ID_WIDTH - 9} characters)"
        )
    d["id2"] = id2
    d["rsp_node"], d["rsp_dir"] = cmap[out]
    d["ref_node"], d["ref_dir"] = cmap[inp]
    if coherence:
        assert data.coherence is not None
        d.update(
            id1=f"bondid-frf: {FORMAT_VERSION} coherence",
            func_type=FUNC_COHERENCE,
            ordinate_spec_data_type=1,
            orddenom_spec_data_type=0,
            data=np.array(data.coherence[a, b], dtype=float),
        )
    else:
        d.update(
            id1=f"bondid-frf: {FORMAT_VERSION} quantity: {data.quantity}",
            func_type=FUNC_FRF,
            ordinate_spec_data_type=SPEC_OF_QUANTITY[data.quantity],
            orddenom_spec_data_type=SPEC_FORCE,
            data=np.array(data.H[a, b], dtype=complex),
        )
    return d


def read_uff58(
    path: str | os.PathLike[str],
    *,
    channel_map: ChannelMap | None = None,
    drop_nan: bool = False,
) -> FrfData:
    """Read the type-58 FRF (and coherence) records of a UFF file.

    Args:
        path: the ``.uff``/``.unv`` file.
        channel_map: ``{channel name: (node, direction)}`` naming the channels by node and
            direction (a record in the opposite direction is read with its sign flipped);
            needed for files not written by bondid.
        drop_nan: drop frequencies where any record holds NaN instead of raising.

    Returns:
        :class:`FrfData`: ``H`` ``(n_out, n_in, n_freq)`` complex (NaN for absent channels),
        joints ordered by node number, quantity from the ordinate data type (displacement,
        velocity or acceleration over force; mixed records are converted to the first).

    Raises:
        DataError: unreadable file, no FRF records, inconsistent grids, NaN, ...
        ChannelError: a record's node/direction is not in ``channel_map``, duplicate channels.
    """
    p = Path(path)
    uff, types = _open(p)
    inverse = None
    if channel_map is not None:
        inverse = role_inverses(check_map(channel_map, str(p)))
    found = RecordSet()
    for k, t in enumerate(types):
        if t == 58:
            found.add(_read_record(uff, k, p), f"{p}: record {k + 1}", k + 1, inverse)
    if found.freq is None or found.quantity is None:
        raise DataError(f"{p}: no type-58 FRF records (function type 4); nothing to read")
    op = parse_operating_point(" ".join(found.op_text or []), f"{p}: ID lines 3-5")
    outputs, inputs, H, C = found.arrays(p)
    notes = (dc_note(f"{p}: point 1"),) if found.dc_dropped else ()
    freq, H, C = _drop_nan_points(p, found.freq, H, C, drop_nan)
    return FrfData(freq, tuple(outputs), tuple(inputs), H, found.quantity, op, C, str(p), notes)


def _open(p: Path) -> tuple[Any, list[int]]:
    """The pyuff reader of file ``p`` and the type of each of its data sets."""
    if not p.is_file():
        raise DataError(f"{p}: no such file; check the path")
    if p.stat().st_size == 0:
        raise DataError(f"{p}: empty file; expected UFF type-58 records")
    pyuff = _pyuff()
    try:
        uff = pyuff.UFF(str(p))
        types = [int(t) for t in uff.get_set_types()]
    except Exception as exc:
        raise DataError(f"{p}: not a readable UFF file ({exc})") from None
    return uff, types


def _read_record(uff: Any, k: int, p: Path) -> dict[str, Any]:
    """Data set ``k`` (0-based) of the file, a type-58 record."""
    try:
        return dict(uff.read_sets(k))
    except Exception as exc:
        raise DataError(f"{p}: record {k + 1}: cannot read the type-58 record ({exc})") from None


def _drop_nan_points(
    p: Path, freq: np.ndarray, H: np.ndarray, C: np.ndarray | None, drop_nan: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Raise at the first frequency where a present channel holds NaN, or drop every such
    frequency when ``drop_nan``."""
    present = np.isfinite(H).any(axis=2)
    nan = np.isnan(H[present]).any(axis=0)
    if not nan.any():
        return freq, H, C
    if not drop_nan:
        j = int(np.flatnonzero(nan)[0])
        raise DataError(
            f"{p}: NaN at point {j + 1} ({float(freq[j]):.6g} Hz); give a number, or pass"
            " --drop-nan (drop_nan=True in Python) to drop that point"
        )
    keep = ~nan
    if not keep.any():
        raise DataError(f"{p}: every frequency holds a NaN; nothing left after dropping them")
    return freq[keep], H[:, :, keep], None if C is None else C[:, :, keep]
