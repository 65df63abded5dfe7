"""The data rows of a bondid CSV file (:mod:`.csv_format`): numbers, one row a frequency.

A file of plain numbers is read by NumPy's parser at once; otherwise cell by cell, so that an
error names the line and the column of what is wrong. Each row's file line number is kept for
those messages.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import overload

import numpy as np

from ..exceptions import DataError
from ._common import check_coherence


def parse_rows(
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


class LineLabels(Sequence[str]):
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


def plain_rows(lines: list[str], start: int, ncol: int) -> tuple[np.ndarray, list[int]] | None:
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


def data_rows(
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


def finite_rows(
    path: Path, values: np.ndarray, linenos: list[int], header: list[str], drop_nan: bool
) -> tuple[np.ndarray, list[int]]:
    """The rows of ``values`` ``(n_rows, n_columns)`` without NaN (dropped if ``drop_nan``,
    else an error) and their line numbers; infinities are errors."""
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


def channel_arrays(
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
            check_coherence(col, str(path), LineLabels(linenos, f", column {header[j]!r}"))
            assert coh is not None
            coh[a, b] = col
    return H, coh
