"""Measured FRFs in Universal File Format data set 58, through ``pyuff``.

One type-58 record per channel (function type 4, FRF, complex double precision) and, where
the data carry coherence, one more record per channel of function type 6 (coherence, real).
A record's response node/direction is the output joint, its reference node/direction the
input joint, as given by a channel map ``{joint: (node, direction)}`` (UFF direction codes:
±1..±3 translation along x/y/z, ±4..±6 rotation about x/y/z, 0 scalar).

Files are written in binary 58 ("58b"): pyuff's ASCII layout keeps only 6 significant
digits of the frequencies (``E13.5``) and 12 of the values (``E20.11``), binary keeps every
bit. bondid also writes, in the ID lines, ``bondid-frf: 1 quantity: ...`` (line 1),
``channel: OUT.IN`` (line 2) and ``operating_point: ...`` (lines 3-5), so its own files read
back without a channel map. Values are taken to be in SI units.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from ..atomic import atomic_path
from ..exceptions import ChannelError, DataError, DependencyError, ModelError
from ..frf.quantity import QUANTITIES, convert_quantity
from ._common import (
    FORMAT_VERSION,
    check_frequencies,
    check_joint_name,
    format_operating_point,
    parse_operating_point,
    written_channels,
)
from .measurement import FrfData

FUNC_FRF = 4
FUNC_COHERENCE = 6
_SPEC_OF_QUANTITY = {"receptance": 8, "mobility": 11, "accelerance": 12}
_QUANTITY_OF_SPEC = {v: k for k, v in _SPEC_OF_QUANTITY.items()}
_SPEC_FORCE = 13
_SPEC_FREQUENCY = 18
_OP_PREFIX = "operating_point:"
_ID_WIDTH = 80

ChannelMap = Mapping[str, tuple[int, int]]


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


def _check_map(channel_map: ChannelMap, where: str) -> dict[str, tuple[int, int]]:
    cmap: dict[str, tuple[int, int]] = {}
    seen: dict[tuple[int, int], str] = {}
    for name, value in channel_map.items():
        check_joint_name(name, f"{where}: channel map")
        try:
            node, direction = (int(v) for v in value)
        except (TypeError, ValueError):
            raise ChannelError(
                f"{where}: channel map entry {name}={value!r}; expected (node, direction) integers"
            ) from None
        if node < 0 or not -6 <= direction <= 6:
            raise ChannelError(
                f"{where}: channel map entry {name}=({node}, {direction}); node must be >= 0 "
                f"and direction in -6..6"
            )
        key = (node, abs(direction))
        if key in seen:
            raise ChannelError(
                f"{where}: channel map gives {seen[key]!r} and {name!r} the same node {node} "
                f"and axis {abs(direction)}; give each joint its own"
            )
        seen[key] = name
        cmap[name] = (node, direction)
    return cmap


def _op_lines(data: FrfData, where: str) -> list[str]:
    """``operating_point: ...`` ID lines (at most three of 80 characters)."""
    lines = [_OP_PREFIX]
    for token in format_operating_point(data.operating_point, where):
        if len(lines[-1]) + 1 + len(token) <= _ID_WIDTH:
            lines[-1] += " " + token
        else:
            lines.append(f"{_OP_PREFIX} {token}")
    if len(lines) > 3 or any(len(s) > _ID_WIDTH for s in lines):
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
        channel_map: ``{joint: (node, direction)}`` for every joint of a written channel;
            default: node ``k`` = k-th joint of ``outputs`` then new ``inputs``, direction 0
            (scalar).
        binary: write binary 58b (exact, default) or ASCII 58 (6 significant digits of
            frequency, 12 of the values).

    Returns:
        The path written.
    """
    where = str(path)
    chans = written_channels(data, where)
    joints = list(dict.fromkeys((*data.outputs, *data.inputs)))
    if channel_map is None:
        cmap = {j: (k + 1, 0) for k, j in enumerate(joints)}
    else:
        cmap = _check_map(channel_map, where)
        used = {data.outputs[a] for a, _, _ in chans} | {data.inputs[b] for _, b, _ in chans}
        missing = [j for j in joints if j in used and j not in cmap]
        if missing:
            raise ChannelError(
                f"{where}: channel map lacks joints {', '.join(missing)}; "
                f"it maps {', '.join(cmap) or 'nothing'}"
            )
    op = _op_lines(data, where)
    freq = np.asarray(data.freq_hz, dtype=float)
    common: dict[str, Any] = {
        "type": 58,
        "binary": int(binary),
        "id3": op[0],
        "id4": op[1],
        "id5": op[2],
        "abscissa_spacing": 0,
        "abscissa_spec_data_type": _SPEC_FREQUENCY,
        "abscissa_axis_units_lab": "Hz",
        "x": freq,
    }
    dsets: list[dict[str, Any]] = []
    for with_coh in (False, True):
        for a, b, has_coh in chans:
            if with_coh and not has_coh:
                continue
            out, inp = data.outputs[a], data.inputs[b]
            id2 = f"channel: {out}.{inp}"
            if len(id2) > _ID_WIDTH:
                raise ChannelError(
                    f"{where}: channel name {out}.{inp} is too long for a UFF ID line "
                    f"(max {_ID_WIDTH - 9} characters)"
                )
            d = dict(common, id2=id2, ver_num=len(dsets) + 1)
            d["rsp_node"], d["rsp_dir"] = cmap[out]
            d["ref_node"], d["ref_dir"] = cmap[inp]
            if with_coh:
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
                    ordinate_spec_data_type=_SPEC_OF_QUANTITY[data.quantity],
                    orddenom_spec_data_type=_SPEC_FORCE,
                    data=np.array(data.H[a, b], dtype=complex),
                )
            dsets.append(d)
    pyuff = _pyuff()
    with atomic_path(path) as tmp:
        # mode "add" on the fresh empty file: pyuff's "overwrite" truncates binary records.
        pyuff.UFF(str(tmp)).write_sets(dsets, mode="add")
    return Path(path)


def _bondid_ids(rec: dict[str, Any]) -> tuple[str | None, str | None, list[str]]:
    """``(quantity or "coherence" or None, "OUT.IN" or None, operating-point lines)``."""
    id1 = str(rec.get("id1", "")).split()
    kind = None
    if len(id1) >= 2 and id1[0] == "bondid-frf:":
        if len(id1) >= 4 and id1[2] == "quantity:":
            kind = id1[3]
        elif len(id1) >= 3 and id1[2] == "coherence":
            kind = "coherence"
    id2 = str(rec.get("id2", ""))
    chan = id2[len("channel:") :].strip() if id2.startswith("channel:") else None
    ops = [
        str(rec.get(k, ""))[len(_OP_PREFIX) :]
        for k in ("id3", "id4", "id5")
        if str(rec.get(k, "")).startswith(_OP_PREFIX)
    ]
    return kind, chan, ops


def _name_channel(
    rec: dict[str, Any], where: str, inverse: dict[tuple[int, int], str] | None
) -> tuple[str, str, float, int, int]:
    """``(out, in, sign, out_node, in_node)`` of a record, via the channel map or ID lines."""
    rn, rd = int(rec["rsp_node"]), int(rec["rsp_dir"])
    fn, fd = int(rec["ref_node"]), int(rec["ref_dir"])
    if inverse is not None:
        names, sign = [], 1.0
        for role, node, d in (("response", rn, rd), ("reference", fn, fd)):
            if (node, d) in inverse:
                names.append(inverse[(node, d)])
            elif (node, -d) in inverse:
                names.append(inverse[(node, -d)])
                sign = -sign
            else:
                valid = ", ".join(f"{j}=({n}, {dd})" for (n, dd), j in inverse.items())
                raise ChannelError(
                    f"{where}: {role} node {node} direction {d} is not in the channel map; "
                    f"valid: {valid}"
                )
        return names[0], names[1], sign, rn, fn
    _, chan, _ = _bondid_ids(rec)
    if chan is None:
        raise DataError(
            f"{where} has no bondid channel name (ID line 2 'channel: OUT.IN'); "
            f"pass channel_map={{joint: (node, direction)}} to name its channels"
        )
    out, dot, inp = chan.partition(".")
    if not dot:
        raise ChannelError(f"{where}: ID line 2 channel {chan!r} is not OUT.IN")
    check_joint_name(out, where)
    check_joint_name(inp, where)
    return out, inp, 1.0, rn, fn


def read_uff58(
    path: str | os.PathLike[str],
    *,
    channel_map: ChannelMap | None = None,
    drop_nan: bool = False,
) -> FrfData:
    """Read the type-58 FRF (and coherence) records of a UFF file.

    Args:
        path: the ``.uff``/``.unv`` file.
        channel_map: ``{joint: (node, direction)}`` naming the channels by node and
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
    inverse = None
    if channel_map is not None:
        inverse = {v: k for k, v in _check_map(channel_map, str(p)).items()}

    frf: dict[tuple[str, str], np.ndarray] = {}
    coh: dict[tuple[str, str], np.ndarray] = {}
    origin: dict[tuple[str, str, bool], int] = {}
    nodes: dict[str, int] = {}
    quantity: str | None = None
    op_text: list[str] | None = None
    freq: np.ndarray | None = None
    first = 0
    for k, t in enumerate(types):
        if t != 58:
            continue
        where = f"{p}: record {k + 1}"
        try:
            rec = uff.read_sets(k)
        except Exception as exc:
            raise DataError(f"{where}: cannot read the type-58 record ({exc})") from None
        func = int(rec.get("func_type", 0))
        if func not in (FUNC_FRF, FUNC_COHERENCE):
            continue  # spectra, time data, ... are not FRFs
        out, inp, sign, on, inn = _name_channel(rec, where, inverse)
        nodes.setdefault(out, on)
        nodes.setdefault(inp, inn)
        key = (out, inp, func == FUNC_COHERENCE)
        if key in origin:
            raise ChannelError(
                f"{where}: channel {out}.{inp} already given by record {origin[key]}; "
                f"give each channel once"
            )
        origin[key] = k + 1
        x = np.asarray(rec["x"], dtype=float)
        if freq is None:
            freq, first = x, k + 1
            check_frequencies(freq, where)
        elif x.shape != freq.shape or not np.array_equal(x, freq):
            raise DataError(
                f"{where}: frequency grid differs from record {first}; "
                f"all records of a file must share one grid"
            )
        values = np.asarray(rec["data"])
        kind, _, ops = _bondid_ids(rec)
        if func == FUNC_COHERENCE:
            if np.iscomplexobj(values):
                raise DataError(f"{where}: coherence record holds complex values; expected real")
            bad = np.flatnonzero((values < 0) | (values > 1))
            if bad.size:
                raise DataError(
                    f"{where}: point {bad[0] + 1}: coherence {float(values[bad[0]])!r} outside 0..1"
                )
            coh[(out, inp)] = values.astype(float)
            continue
        if not np.iscomplexobj(values):
            raise DataError(
                f"{where}: FRF record holds real values (ordinate data type "
                f"{rec.get('ord_data_type')}); expected complex (5 or 6)"
            )
        spec = int(rec.get("ordinate_spec_data_type", 0))
        q = kind if kind in QUANTITIES else _QUANTITY_OF_SPEC.get(spec)
        if q is None:
            raise DataError(
                f"{where}: ordinate data type {spec} is not displacement (8), velocity (11) or "
                f"acceleration (12); cannot tell the quantity"
            )
        if quantity is None:
            quantity = q
            op_text = ops
        elif ops != op_text:
            raise DataError(
                f"{where}: operating point differs from the first FRF record; "
                f"one file holds one operating point"
            )
        values = sign * values
        if q != quantity:
            values = convert_quantity(values, freq, q, quantity)
        frf[(out, inp)] = values.astype(complex)

    if freq is None or quantity is None:
        raise DataError(f"{p}: no type-58 FRF records (function type 4); nothing to read")
    op = parse_operating_point(" ".join(op_text or []), f"{p}: ID lines 3-5")
    orphans = [f"{o}.{i}" for (o, i) in coh if (o, i) not in frf]
    if orphans:
        raise DataError(f"{p}: coherence without FRF for channels {', '.join(orphans)}")
    outputs = sorted({o for o, _ in frf}, key=lambda j: (nodes[j], j))
    inputs = sorted({i for _, i in frf}, key=lambda j: (nodes[j], j))
    H = np.full((len(outputs), len(inputs), freq.size), np.nan + 1j * np.nan)
    C = np.full(H.shape, np.nan) if coh else None
    for (o, i), v in frf.items():
        H[outputs.index(o), inputs.index(i)] = v
    for (o, i), c in coh.items():
        assert C is not None
        C[outputs.index(o), inputs.index(i)] = c
    present = np.isfinite(H).any(axis=2)
    nan = np.isnan(H[present]).any(axis=0)
    if nan.any():
        if not drop_nan:
            j = int(np.flatnonzero(nan)[0])
            raise DataError(
                f"{p}: NaN at point {j + 1} ({float(freq[j]):.6g} Hz); give a number, or pass"
                " --drop-nan (drop_nan=True in Python) to drop that point"
            )
        keep = ~nan
        freq, H = freq[keep], H[:, :, keep]
        C = None if C is None else C[:, :, keep]
        if freq.size == 0:
            raise DataError(f"{p}: every frequency holds a NaN; nothing left after dropping them")
    return FrfData(freq, tuple(outputs), tuple(inputs), H, quantity, op, C, str(p))
