"""The lines of a bondid CSV file before its data rows (:mod:`.csv_format`).

The ``#`` metadata lines (format version, quantity, operating point, the joint order of
``# outputs:`` / ``# inputs:`` and the per-output ``# quantities:``) and the header row of
``OUT.IN.re``, ``OUT.IN.im`` and ``OUT.IN.coh`` columns. Every error names the file and the
line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import ChannelError, DataError
from ._common import FORMAT_VERSION, check_joint_name, parse_operating_point
from .quantity import QUANTITIES, convert_quantity

_META_KEYS = ("bondid-frf", "quantity", "operating_point", "outputs", "inputs", "quantities")
_SUFFIXES = ("re", "im", "coh")


def read_metadata(path: Path, lines: list[str]) -> tuple[dict[str, tuple[str, int]], int]:
    """Metadata ``key -> (value, line number)`` and the index of the header line."""
    meta: dict[str, tuple[str, int]] = {}
    for n, line in enumerate(lines):
        s = line.strip()
        if not s:
            continue
        if not s.startswith("#"):
            return meta, n
        key, colon, value = s[1:].partition(":")
        key = key.strip().lower()
        if colon and key in _META_KEYS:
            if key in meta:
                raise DataError(
                    f"{path}: line {n + 1}: metadata '{key}' given twice "
                    f"(first on line {meta[key][1]}); give it once"
                )
            meta[key] = (value.strip(), n + 1)
    if not meta and not any(line.strip() for line in lines):
        raise DataError(f"{path}: empty file; expected '# bondid-frf: 1' and a header row")
    raise DataError(
        f"{path}: no header row; expected a line starting 'freq_hz,' after the '#' lines"
    )


def parse_header(
    path: Path, cells: list[str], lineno: int
) -> tuple[list[tuple[str, str, str]], list[str], list[str]]:
    """Columns ``(out, in, suffix)`` after ``freq_hz``, and outputs/inputs by first use."""
    where = f"{path}: line {lineno} (header)"
    if not cells or cells[0] != "freq_hz":
        first = cells[0] if cells else ""
        raise DataError(f"{where}: first column is {first!r}; it must be 'freq_hz'")
    columns: list[tuple[str, str, str]] = []
    seen: set[tuple[str, str, str]] = set()
    outputs: list[str] = []
    inputs: list[str] = []
    for j, name in enumerate(cells[1:], start=2):
        chan, dot, suffix = name.rpartition(".")
        if not dot or suffix not in _SUFFIXES:
            raise DataError(
                f"{where}: column {j} {name!r}: expected OUT.IN.re, OUT.IN.im or OUT.IN.coh"
            )
        out, dot2, inp = chan.partition(".")
        if not dot2:
            raise ChannelError(
                f"{where}: column {j} {name!r}: channel {chan!r} is not OUT.IN (e.g. x.y.{suffix})"
            )
        check_joint_name(out, f"{where}: column {j} {name!r}")
        check_joint_name(inp, f"{where}: column {j} {name!r}")
        key = (out, inp, suffix)
        if key in seen:
            raise DataError(f"{where}: column {j} {name!r} appears twice; give each column once")
        seen.add(key)
        columns.append(key)
        if out not in outputs:
            outputs.append(out)
        if inp not in inputs:
            inputs.append(inp)
    if not columns:
        raise DataError(f"{where}: no channel columns after 'freq_hz'; expected e.g. x.x.re,x.x.im")
    for out, inp, suffix in columns:
        need = {"re": ("im",), "im": ("re",), "coh": ("re", "im")}[suffix]
        for other in need:
            if (out, inp, other) not in seen:
                raise DataError(
                    f"{where}: column '{out}.{inp}.{suffix}' has no matching "
                    f"'{out}.{inp}.{other}'; give .re and .im (and optionally .coh) together"
                )
    return columns, outputs, inputs


def joint_order(
    path: Path, meta: dict[str, tuple[str, int]], key: str, used: list[str]
) -> list[str]:
    """Joint order from ``# outputs:``/``# inputs:`` if given, else first use in the header."""
    if key not in meta:
        return used
    text, lineno = meta[key]
    names = text.split()
    where = f"{path}: line {lineno}"
    for name in names:
        check_joint_name(name, where)
    if len(set(names)) != len(names):
        raise DataError(f"{where}: '{key}' lists a joint twice; list each joint once")
    missing = [n for n in used if n not in names]
    if missing:
        raise ChannelError(
            f"{where}: '{key}' lacks {', '.join(missing)} used in the header; "
            f"list every joint of the header"
        )
    return names


def file_metadata(path: Path, meta: dict[str, tuple[str, int]]) -> tuple[str, dict[str, float]]:
    """The file's quantity and operating point, after checking its format version."""
    if "bondid-frf" not in meta:
        raise DataError(
            f"{path}: missing '# bondid-frf: {FORMAT_VERSION}' line before the header row"
        )
    version, vline = meta["bondid-frf"]
    if version != FORMAT_VERSION:
        raise DataError(
            f"{path}: line {vline}: unsupported format version {version!r}; valid: {FORMAT_VERSION}"
        )
    quantity = "receptance"
    if "quantity" in meta:
        quantity, qline = meta["quantity"]
        if quantity not in QUANTITIES:
            raise DataError(
                f"{path}: line {qline}: unknown quantity {quantity!r}; "
                f"valid: {', '.join(QUANTITIES)}"
            )
    op: dict[str, float] = {}
    if "operating_point" in meta:
        text, oline = meta["operating_point"]
        op = parse_operating_point(text, f"{path}: line {oline}")
    return quantity, op


def convert_outputs(
    path: Path, entry: tuple[str, int], outputs: list[str], quantity: str, freq: np.ndarray,
    H: np.ndarray,
) -> None:  # fmt: skip
    """Convert, in place, the rows of ``H`` ``(n_out, n_in, n_freq)`` named by ``# quantities:
    OUT=QUANTITY …`` to the file's quantity (frequencies ``freq`` ``(n_freq,)`` in Hz)."""
    text, lineno = entry
    where = f"{path}: line {lineno}"
    for item in text.split():
        out, eq, q = item.partition("=")
        if not eq or q not in QUANTITIES:
            raise DataError(
                f"{where}: 'quantities' item {item!r} is not OUTPUT=QUANTITY; valid quantities:"
                f" {', '.join(QUANTITIES)}"
            )
        if out not in outputs:
            raise ChannelError(
                f"{where}: 'quantities' names output {out!r}, which has no channel; outputs:"
                f" {', '.join(outputs)}"
            )
        a = outputs.index(out)
        H[a] = convert_quantity(H[a], freq, q, quantity)
