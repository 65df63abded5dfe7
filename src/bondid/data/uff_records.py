"""The UFF type-58 record layout bondid writes, and the reading of records into channels.

Codes are those of UFF data set 58: function types (FRF 4, coherence 6) and the ordinate
specific data types of the quantities (displacement 8, velocity 11, acceleration 12 over force
13); frequency is abscissa type 18. The file-level reader and writer are in
:mod:`bondid.data.uff_format`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import ChannelError, DataError
from ._common import check_coherence, check_frequencies, check_joint_name, has_dc_line
from .quantity import QUANTITIES, convert_quantity

#: UFF 58 function types
FUNC_FRF = 4
FUNC_COHERENCE = 6
#: ordinate specific data type of each quantity's numerator (displacement, velocity, acceleration)
SPEC_OF_QUANTITY = {"receptance": 8, "mobility": 11, "accelerance": 12}
QUANTITY_OF_SPEC = {v: k for k, v in SPEC_OF_QUANTITY.items()}
SPEC_FORCE = 13  # the FRF's denominator: force
SPEC_FREQUENCY = 18  # the abscissa: frequency
OP_PREFIX = "operating_point:"  # starts the ID lines 3-5 that bondid writes
ID_WIDTH = 80  # characters of one ID line

ChannelMap = Mapping[str, tuple[int, int]]


def check_map(channel_map: ChannelMap, where: str) -> dict[str, tuple[int, int]]:
    """``channel_map`` with integer entries, checked: valid names, directions in -6..6, and at
    most two names on one node and axis (a driving point named once as the response, e.g.
    an accelerometer, and once as the reference, e.g. the hammer or shaker there: the first
    given names the response, the second the reference; :func:`role_inverses`)."""
    cmap: dict[str, tuple[int, int]] = {}
    seen: dict[tuple[int, int], list[str]] = {}
    for name, value in channel_map.items():
        check_joint_name(name, f"{where}: channel map", "channel")
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
        names = seen.setdefault((node, abs(direction)), [])
        if len(names) == 2:
            raise ChannelError(
                f"{where}: channel map gives {names[0]!r}, {names[1]!r} and {name!r} the same"
                f" node {node} and axis {abs(direction)}; at most two channel names share one"
                " (the first names the response, the second the reference)"
            )
        names.append(name)
        cmap[name] = (node, direction)
    return cmap


#: per role (``"response"``, ``"reference"``): ``(node, axis) -> (name, signed direction)``
RoleInverses = dict[str, dict[tuple[int, int], tuple[str, int]]]


def role_inverses(cmap: dict[str, tuple[int, int]]) -> RoleInverses:
    """The channel name of a record's response and of its reference by node and axis: the
    first name given for a node and axis for the response, the last for the reference (the
    same one when only one is given; :func:`check_map`)."""
    out: RoleInverses = {"response": {}, "reference": {}}
    for name, (node, d) in cmap.items():
        key = (node, abs(d))
        out["response"].setdefault(key, (name, d))
        out["reference"][key] = (name, d)
    return out


def bondid_ids(rec: dict[str, Any]) -> tuple[str | None, str | None, list[str]]:
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
        str(rec.get(k, ""))[len(OP_PREFIX) :]
        for k in ("id3", "id4", "id5")
        if str(rec.get(k, "")).startswith(OP_PREFIX)
    ]
    return kind, chan, ops


def name_channel(
    rec: dict[str, Any], where: str, inverse: RoleInverses | None
) -> tuple[str, str, float, int, int]:
    """``(out, in, sign, out_node, in_node)`` of a record, via the channel map or ID lines."""
    rn, rd = int(rec["rsp_node"]), int(rec["rsp_dir"])
    fn, fd = int(rec["ref_node"]), int(rec["ref_dir"])
    if inverse is not None:
        names, sign = [], 1.0
        for role, node, d in (("response", rn, rd), ("reference", fn, fd)):
            hit = inverse[role].get((node, abs(d)))
            if hit is None:
                valid = ", ".join(f"{n}=({k[0]}, {dd})" for k, (n, dd) in inverse[role].items())
                raise ChannelError(
                    f"{where}: {role} node {node} direction {d} is not in the channel map; "
                    f"valid: {valid}"
                )
            names.append(hit[0])
            if d != 0 and hit[1] == -d:  # the record's direction opposite the map's
                sign = -sign
        return names[0], names[1], sign, rn, fn
    _, chan, _ = bondid_ids(rec)
    if chan is None:
        raise DataError(
            f"{where} has no bondid channel name (ID line 2 'channel: OUT.IN'); "
            f"pass channel_map={{channel name: (node, direction)}} (--uff-map) to name its"
            " channels"
        )
    out, dot, inp = chan.partition(".")
    if not dot:
        raise ChannelError(f"{where}: ID line 2 channel {chan!r} is not OUT.IN")
    check_joint_name(out, where)
    check_joint_name(inp, where)
    return out, inp, 1.0, rn, fn


@dataclass
class RecordSet:
    """The FRF and coherence records of one file, checked against each other as they come."""

    frf: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)
    coh: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)
    origin: dict[tuple[str, str, bool], int] = field(default_factory=dict)
    nodes: dict[str, int] = field(default_factory=dict)
    quantity: str | None = None
    op_text: list[str] | None = None
    freq: np.ndarray | None = None
    first: int = 0
    #: the first record's grid as written; ``freq`` is it without a leading 0 Hz line
    #: (dropped from every record as it comes, ``dc_dropped`` set: :func:`._common.has_dc_line`)
    written: np.ndarray | None = None
    dc_dropped: bool = False

    def add(
        self,
        rec: dict[str, Any],
        where: str,
        number: int,
        inverse: RoleInverses | None,
    ) -> None:
        """Take record ``number`` (1-based) if it is an FRF or coherence; skip other functions."""
        func = int(rec.get("func_type", 0))
        if func not in (FUNC_FRF, FUNC_COHERENCE):
            return  # spectra, time data, ... are not FRFs
        out, inp, sign, on, inn = name_channel(rec, where, inverse)
        self.nodes.setdefault(out, on)
        self.nodes.setdefault(inp, inn)
        key = (out, inp, func == FUNC_COHERENCE)
        if key in self.origin:
            raise ChannelError(
                f"{where}: channel {out}.{inp} already given by record {self.origin[key]}; "
                f"give each channel once"
            )
        self.origin[key] = number
        keep = self._grid(np.asarray(rec["x"], dtype=float), where, number)
        values = np.asarray(rec["data"])[keep]
        freq = self.freq
        assert freq is not None  # set by the first record's grid
        if func == FUNC_COHERENCE:
            self.coh[(out, inp)] = _coherence_values(values, where)
        else:
            self.frf[(out, inp)] = self._frf_values(rec, sign * values, freq, where)

    def _grid(self, x: np.ndarray, where: str, number: int) -> slice:
        """Check a record's frequency grid (Hz), the first record's (``freq``, checked) or a
        repeat of it; return the slice of its values to keep (all but a leading 0 Hz line)."""
        if self.written is None:
            self.written, self.first, self.dc_dropped = x, number, has_dc_line(x)
            self.freq = x[1:] if self.dc_dropped else x
            check_frequencies(self.freq, where)
        elif x.shape != self.written.shape or not np.array_equal(x, self.written):
            raise DataError(
                f"{where}: frequency grid differs from record {self.first}; "
                f"all records of a file must share one grid"
            )
        return slice(1, None) if self.dc_dropped else slice(None)

    def _frf_values(
        self, rec: dict[str, Any], values: np.ndarray, freq: np.ndarray, where: str
    ) -> np.ndarray:
        """An FRF record's values in the file's quantity (that of its first FRF record)."""
        if not np.iscomplexobj(values):
            raise DataError(
                f"{where}: FRF record holds real values (ordinate data type "
                f"{rec.get('ord_data_type')}); expected complex (5 or 6)"
            )
        kind, _, ops = bondid_ids(rec)
        spec = int(rec.get("ordinate_spec_data_type", 0))
        q = kind if kind in QUANTITIES else QUANTITY_OF_SPEC.get(spec)
        if q is None:
            raise DataError(
                f"{where}: ordinate data type {spec} is not displacement (8), velocity (11) or "
                f"acceleration (12); cannot tell the quantity"
            )
        if self.quantity is None:
            self.quantity, self.op_text = q, ops
        elif ops != self.op_text:
            raise DataError(
                f"{where}: operating point differs from the first FRF record; "
                f"one file holds one operating point"
            )
        if q != self.quantity:
            values = convert_quantity(values, freq, q, self.quantity)
        return values.astype(complex)

    def arrays(self, p: Path) -> tuple[list[str], list[str], np.ndarray, np.ndarray | None]:
        """``(outputs, inputs, H, coherence)``: joints by node number, arrays
        ``(n_out, n_in, n_freq)`` with NaN for absent channels (coherence None if none)."""
        assert self.freq is not None
        orphans = [f"{o}.{i}" for (o, i) in self.coh if (o, i) not in self.frf]
        if orphans:
            raise DataError(f"{p}: coherence without FRF for channels {', '.join(orphans)}")
        outputs = sorted({o for o, _ in self.frf}, key=lambda j: (self.nodes[j], j))
        inputs = sorted({i for _, i in self.frf}, key=lambda j: (self.nodes[j], j))
        H = np.full((len(outputs), len(inputs), self.freq.size), np.nan + 1j * np.nan)
        C = np.full(H.shape, np.nan) if self.coh else None
        for (o, i), v in self.frf.items():
            H[outputs.index(o), inputs.index(i)] = v
        for (o, i), c in self.coh.items():
            assert C is not None
            C[outputs.index(o), inputs.index(i)] = c
        return outputs, inputs, H, C


def _coherence_values(values: np.ndarray, where: str) -> np.ndarray:
    """A coherence record's values, checked real and within 0..1."""
    if np.iscomplexobj(values):
        raise DataError(f"{where}: coherence record holds complex values; expected real")
    check_coherence(values, where)
    return values.astype(float)
