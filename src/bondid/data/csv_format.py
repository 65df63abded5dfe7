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

:func:`read_csv` reads the lines before the data with :mod:`.csv_header` and the data rows
with :mod:`.csv_rows`.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

from ..atomic import write_text_atomic
from ..exceptions import DataError
from ._common import (
    FORMAT_VERSION,
    check_frequencies,
    dc_note,
    format_operating_point,
    has_dc_line,
    read_file_bytes,
    written_channels,
)
from .csv_header import convert_outputs, file_metadata, joint_order, parse_header, read_metadata
from .csv_rows import LineLabels, channel_arrays, data_rows, finite_rows, parse_rows, plain_rows
from .measurement import FrfData


def _decode(path: Path) -> str:
    raw = read_file_bytes(path)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(
            f"{path}: not UTF-8 text (byte {exc.start}); save the CSV as UTF-8"
        ) from None


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
    meta, h = read_metadata(p, lines)
    quantity, op = file_metadata(p, meta)
    header = [c.strip() for c in next(csv.reader(lines[h : h + 1]))]
    columns, used_out, used_in = parse_header(p, header, h + 1)
    outputs = joint_order(p, meta, "outputs", used_out)
    inputs = joint_order(p, meta, "inputs", used_in)
    fast = plain_rows(lines, h + 1, len(header))
    if fast is not None:
        values, linenos = fast
    else:  # cell by cell, to name the line and column of what is wrong
        rows, linenos = data_rows(p, list(csv.reader(lines[h + 1 :])), h + 2)
        values = parse_rows(p, rows, linenos, header)
    values, linenos = finite_rows(p, values, linenos, header, drop_nan)
    notes: tuple[str, ...] = ()
    if has_dc_line(values[:, 0]):
        notes = (dc_note(f"{p}: line {linenos[0]}"),)
        values, linenos = values[1:], linenos[1:]
    freq = values[:, 0].copy()
    check_frequencies(freq, str(p), LineLabels(linenos))
    H, coh = channel_arrays(p, values, columns, (outputs, inputs), linenos, header)
    if "quantities" in meta:
        convert_outputs(p, meta["quantities"], outputs, quantity, freq, H)
    return FrfData(freq, tuple(outputs), tuple(inputs), H, quantity, op, coh, str(p), notes)


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
