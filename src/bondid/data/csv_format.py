"""The bondid CSV format for measured FRFs (conventions §3).

```
# bondid-frf: 1
# quantity: receptance
# operating_point: x=0.0 y=0.0
freq_hz,x.x.re,x.x.im,x.y.re,x.y.im,...[,x.x.coh,...]
```

Optional metadata lines ``# outputs: x y z`` and ``# inputs: x y z`` (written by bondid) fix
the joint order and keep joints whose channels are all missing; without them the order is
that of first appearance in the header. Extension: ``# quantities: acc=accelerance x=receptance``
gives the quantity of single outputs (a mix of accelerometers and encoders); their rows are
converted exactly (factors (jω)ᵏ) to the file's ``# quantity`` on reading. Other ``#`` lines
are comments. Numbers are written
with Python's shortest round-trip ``repr``, so a value read back is bit-identical.
"""

from __future__ import annotations

import csv
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import overload

import numpy as np

from ..atomic import write_text_atomic
from ..exceptions import ChannelError, DataError
from ..frf.quantity import QUANTITIES, convert_quantity
from ._common import (
    FORMAT_VERSION,
    check_coherence,
    check_frequencies,
    check_joint_name,
    dc_note,
    format_operating_point,
    has_dc_line,
    parse_operating_point,
    read_file_bytes,
    written_channels,
)
from .measurement import FrfData

_META_KEYS = ("bondid-frf", "quantity", "operating_point", "outputs", "inputs", "quantities")
_SUFFIXES = ("re", "im", "coh")


def _decode(path: Path) -> str:
    raw = read_file_bytes(path)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(
            f"{path}: not UTF-8 text (byte {exc.start}); save the CSV as UTF-8"
        ) from None


def _read_metadata(path: Path, lines: list[str]) -> tuple[dict[str, tuple[str, int]], int]:
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


def _parse_header(
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


def _joint_order(
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


def _parse_rows(
    path: Path, rows: list[list[str]], linenos: list[int], header: list[str]
) -> np.ndarray:
    """Numbers of the data rows, shape ``(n_rows, n_columns)``; empty cells become NaN."""
    ncol = len(header)
    values = np.empty((len(rows), ncol))
    for k, cells in enumerate(rows):
        if len(cells) != ncol:
            raise DataError(
                f"{path}: line {linenos[k]} (data row {k + 1}): {len(cells)} cells, "
                f"the header has {ncol} columns"
            )
        try:
            values[k] = [float(c) for c in cells]
        except ValueError:
            for j, c in enumerate(cells):
                if not c.strip():
                    values[k, j] = np.nan
                    continue
                try:
                    values[k, j] = float(c)
                except ValueError:
                    raise DataError(
                        f"{path}: line {linenos[k]} (data row {k + 1}), column {header[j]!r}: "
                        f"non-numeric value {c.strip()!r}; expected a number"
                    ) from None
    return values


def read_csv(path: str | os.PathLike[str], *, drop_nan: bool = False) -> FrfData:
    """Read a bondid CSV file of measured FRFs.

    Args:
        path: the ``.csv`` file.
        drop_nan: drop frequency rows that hold a NaN (or empty) cell instead of raising.

    Returns:
        :class:`FrfData` with ``freq_hz`` ``(n_freq,)`` in Hz, ``H`` ``(n_out, n_in,
        n_freq)`` complex in SI units of the file's quantity (NaN for absent channels), and
        ``coherence`` ``(n_out, n_in, n_freq)`` (NaN where a channel has none) or None.

    Raises:
        DataError: malformed file, with the file, line and column in the message.
        ChannelError: malformed channel names in the header.
        OperatingPointError: malformed ``# operating_point`` line.
    """
    p = Path(path)
    lines = _decode(p).splitlines()
    meta, h = _read_metadata(p, lines)
    quantity, op = _file_metadata(p, meta)
    header = [c.strip() for c in next(csv.reader(lines[h : h + 1]))]
    columns, used_out, used_in = _parse_header(p, header, h + 1)
    outputs = _joint_order(p, meta, "outputs", used_out)
    inputs = _joint_order(p, meta, "inputs", used_in)
    fast = _plain_rows(lines, h + 1, len(header))
    if fast is not None:
        values, linenos = fast
    else:  # cell by cell, to name the line and column of what is wrong
        rows, linenos = _data_rows(p, list(csv.reader(lines[h + 1 :])), h + 2)
        values = _parse_rows(p, rows, linenos, header)
    values, linenos = _finite_rows(p, values, linenos, header, drop_nan)
    notes: tuple[str, ...] = ()
    if has_dc_line(values[:, 0]):
        notes = (dc_note(f"{p}: line {linenos[0]}"),)
        values, linenos = values[1:], linenos[1:]
    freq = values[:, 0].copy()
    check_frequencies(freq, str(p), _LineLabels(linenos))
    H, coh = _channel_arrays(p, values, columns, (outputs, inputs), linenos, header)
    if "quantities" in meta:
        _convert_outputs(p, meta["quantities"], outputs, quantity, freq, H)
    return FrfData(freq, tuple(outputs), tuple(inputs), H, quantity, op, coh, str(p), notes)


def _file_metadata(path: Path, meta: dict[str, tuple[str, int]]) -> tuple[str, dict[str, float]]:
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


class _LineLabels(Sequence[str]):
    """``"line N<suffix>"`` of each data row, made only for the row a message names."""

    def __init__(self, linenos: list[int], suffix: str = ""):
        self.linenos, self.suffix = linenos, suffix

    def __len__(self) -> int:
        return len(self.linenos)

    @overload
    def __getitem__(self, k: int) -> str: ...
    @overload
    def __getitem__(self, k: slice) -> list[str]: ...
    def __getitem__(self, k: int | slice) -> str | list[str]:
        if isinstance(k, slice):
            return [f"line {n}{self.suffix}" for n in self.linenos[k]]
        return f"line {self.linenos[k]}{self.suffix}"


def _plain_rows(lines: list[str], start: int, ncol: int) -> tuple[np.ndarray, list[int]] | None:
    """The numbers of the data rows ``lines[start:]`` and their line numbers (1-based), read
    by NumPy's parser when every non-blank row holds ``ncol`` plain numbers; None otherwise
    (the cell-by-cell reading then names what is wrong). The parser holds no Python object
    per cell: a file of 100 000 lines × 28 columns took a tenth of the time and memory."""
    body = lines[start:]
    linenos = [k for k, line in enumerate(body, start=start + 1) if line.strip()]
    if not linenos:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            values = np.loadtxt(body, delimiter=",", dtype=float, comments=None, ndmin=2)
    except (ValueError, UserWarning):
        return None
    if values.shape != (len(linenos), ncol):
        return None
    return values, linenos


def _data_rows(
    path: Path, parsed: list[list[str]], first_lineno: int
) -> tuple[list[list[str]], list[int]]:
    """The non-blank rows after the header and their line numbers (1-based)."""
    rows, linenos = [], []
    for k, cells in enumerate(parsed, start=first_lineno):
        if cells and any(c.strip() for c in cells):
            rows.append(cells)
            linenos.append(k)
    if not rows:
        raise DataError(f"{path}: no data rows after the header; expected one row per frequency")
    return rows, linenos


def _finite_rows(
    path: Path, values: np.ndarray, linenos: list[int], header: list[str], drop_nan: bool
) -> tuple[np.ndarray, list[int]]:
    """The rows without NaN (dropped if ``drop_nan``, else an error); infinities are errors."""
    nan = np.isnan(values)
    if drop_nan:
        keep = ~nan.any(axis=1)
        values, linenos = values[keep], [n for n, kp in zip(linenos, keep, strict=True) if kp]
        if not linenos:
            raise DataError(f"{path}: every data row holds a NaN; nothing left after dropping them")
    elif nan.any():
        k, j = np.argwhere(nan)[0]
        raise DataError(
            f"{path}: line {linenos[k]} (data row {k + 1}), column {header[j]!r}: NaN or empty "
            f"value; give a number, or pass --drop-nan (drop_nan=True in Python) to drop the"
            " rows that hold one"
        )
    inf = np.isinf(values)
    if inf.any():
        k, j = np.argwhere(inf)[0]
        raise DataError(
            f"{path}: line {linenos[k]}, column {header[j]!r}: infinite value; "
            f"expected a finite number"
        )
    return values, linenos


def _channel_arrays(
    path: Path,
    values: np.ndarray,
    columns: list[tuple[str, str, str]],
    joints: tuple[list[str], list[str]],
    linenos: list[int],
    header: list[str],
) -> tuple[np.ndarray, np.ndarray | None]:
    """``H`` and coherence ``(n_out, n_in, n_freq)`` from the columns (NaN where absent;
    coherence None when the file has none), coherence checked within 0..1."""
    outputs, inputs = joints
    H = np.full((len(outputs), len(inputs), values.shape[0]), np.nan + 1j * np.nan)
    has_coh = any(s == "coh" for _, _, s in columns)
    coh = np.full(H.shape, np.nan) if has_coh else None
    for j, (out, inp, suffix) in enumerate(columns, start=1):
        a, b = outputs.index(out), inputs.index(inp)
        col = values[:, j]
        if suffix == "re":
            H[a, b].real = col
        elif suffix == "im":
            H[a, b].imag = col
        else:
            check_coherence(col, str(path), _LineLabels(linenos, f", column {header[j]!r}"))
            assert coh is not None
            coh[a, b] = col
    return H, coh


def _convert_outputs(
    path: Path, entry: tuple[str, int], outputs: list[str], quantity: str, freq: np.ndarray,
    H: np.ndarray,
) -> None:  # fmt: skip
    """Convert the rows named by ``# quantities: OUT=QUANTITY …`` to the file's quantity."""
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


def write_csv(data: FrfData, path: str | os.PathLike[str]) -> Path:
    """Write ``data`` as a bondid CSV file, atomically, with full double precision.

    Only channels with data at every frequency are written (channels NaN everywhere are
    left out); coherence columns follow the FRF columns for channels that have one.

    Args:
        data: the FRFs (``H`` ``(n_out, n_in, n_freq)``, ``freq_hz`` in Hz).
        path: the ``.csv`` file to write.

    Returns:
        The path written.

    Raises:
        ChannelError: a joint name contains '.', ',', '=', whitespace, ...
        DataError: a channel is NaN at some frequencies only, or coherence is out of 0..1.
        OperatingPointError: an operating-point name or value cannot be written.
    """
    where = str(path)
    chans = written_channels(data, where)
    op = format_operating_point(data.operating_point, where)
    names = ["freq_hz"]
    cols = [np.asarray(data.freq_hz, dtype=float)]
    for a, b, _ in chans:
        chan = f"{data.outputs[a]}.{data.inputs[b]}"
        names += [f"{chan}.re", f"{chan}.im"]
        cols += [data.H[a, b].real, data.H[a, b].imag]
    for a, b, has_coh in chans:
        if has_coh:
            assert data.coherence is not None
            names.append(f"{data.outputs[a]}.{data.inputs[b]}.coh")
            cols.append(data.coherence[a, b])
    table = np.column_stack(cols).tolist()
    out = [
        f"# bondid-frf: {FORMAT_VERSION}",
        f"# quantity: {data.quantity}",
        ("# operating_point: " + " ".join(op)).rstrip(),
        "# outputs: " + " ".join(data.outputs),
        "# inputs: " + " ".join(data.inputs),
        ",".join(names),
    ]
    out += [",".join(map(repr, row)) for row in table]
    return write_text_atomic(path, "\n".join(out) + "\n")
