"""Checks that measured FRFs can be measurements of the model: :func:`check_data`.

Errors (:class:`DataError`, exit 2) name the file, the data row (frequency line, 1-based, as
the CSV reader counts them) and the column:

* the same file given twice (same path, or identical content);
* fewer than :data:`MIN_FREQUENCIES` frequencies (one frequency cannot be fitted), a
  frequency above :data:`bondid.ranges.FREQUENCY`;
* a non-finite value, a non-positive magnitude (an exact ``0+0j`` cell);
* a cell more than :data:`CELL_DECADES` decades away from its channel's median magnitude (a
  1e300 or 1e-300 typed into one cell);
* a channel whose median magnitude is more than :data:`SCALE_DECADES` decades away from the
  nominal model's on the same grid (wrong units by many orders, a channel × 1e300). Only
  channels the model itself drives noticeably are compared (the model's channel median at
  least 1e-6 of its largest), so structurally weak cross terms do not trip it.

Warnings (returned): a channel 3–6 decades from the model's scale (units?), fewer than 20
frequencies, coherence below 0.5 almost everywhere in a channel, and what the reader changed
on the way in (``FrfData.notes``: a 0 Hz line dropped).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..data.measurement import FrfData
from ..exceptions import DataError
from ..model.document import UrdfDocument
from ..ranges import FREQUENCY

#: fewest frequencies a data set may have
MIN_FREQUENCIES = 2
#: fewer frequencies than this is suspicious (a warning)
FEW_FREQUENCIES = 20
#: decades between one cell and its channel's median that make the cell impossible
CELL_DECADES = 6.0
#: decades between a channel's median |H| and the nominal model's that make it impossible
SCALE_DECADES = 6.0
#: decades that make it suspicious (a warning)
SCALE_WARN_DECADES = 3.0


def _row(ds: FrfData, k: int) -> str:
    return f"data row {k + 1} (f = {float(ds.freq_hz[k]):.6g} Hz)"


def check_same_files(paths: Sequence[str | os.PathLike[str]]) -> None:
    """Raise :class:`DataError` when a data file is given twice (by path or by content)."""
    seen: dict[str, Path] = {}
    for p in map(Path, paths):
        try:
            key = hashlib.sha256(p.read_bytes()).hexdigest()
        except OSError:
            continue  # the reader names an unreadable file
        if key in seen:
            same = seen[key].resolve() == p.resolve()
            raise DataError(
                f"{p}: {'given twice' if same else f'has the same content as {seen[key]}'};"
                " valid: each measurement once (fitting a file twice only doubles its weight)"
            )
        seen[key] = p


def check_values(ds: FrfData) -> list[str]:
    """Finite, positive magnitudes and no impossible outlier cell; returns warnings."""
    where = ds.source or "<in-memory FRF>"
    n_f = ds.freq_hz.size
    if n_f < MIN_FREQUENCIES:
        raise DataError(
            f"{where}: {n_f} frequency line(s); valid: at least {MIN_FREQUENCIES} (an FRF is"
            " fitted over a band)"
        )
    top = int(np.argmax(ds.freq_hz))
    if ds.freq_hz[top] not in FREQUENCY:
        raise DataError(
            f"{where}: {_row(ds, top)}: frequency {float(ds.freq_hz[top])!r} Hz; valid:"
            f" {FREQUENCY.text()}"
        )
    warnings = list(ds.notes)
    if n_f < FEW_FREQUENCIES:
        warnings.append(f"{where}: only {n_f} frequencies; modes between them are not resolved")
    for a, o in enumerate(ds.outputs):
        for b, i in enumerate(ds.inputs):
            h = ds.H[a, b]
            if np.all(np.isnan(h)):
                continue  # channel absent from the file
            ch = f"{o}.{i}"
            bad = np.flatnonzero(~np.isfinite(h))
            if bad.size:
                raise DataError(
                    f"{where}: {_row(ds, bad[0])}, column {ch}: non-finite value {h[bad[0]]};"
                    " valid: finite numbers"
                )
            mag = np.abs(h)
            bad = np.flatnonzero(~(mag > 0))
            if bad.size:
                raise DataError(
                    f"{where}: {_row(ds, bad[0])}, column {ch}: magnitude 0 (0+0j); a"
                    " measured FRF is never exactly zero; valid: a magnitude > 0 (leave the"
                    " channel out, or drop the row, if it was not measured)"
                )
            dec = np.log10(mag) - np.median(np.log10(mag))
            k = int(np.argmax(np.abs(dec)))
            if abs(dec[k]) > CELL_DECADES:
                raise DataError(
                    f"{where}: {_row(ds, k)}, column {ch}: |H| = {mag[k]:.3g} is"
                    f" {abs(dec[k]):.1f} decades {'above' if dec[k] > 0 else 'below'} the"
                    f" channel's median {10 ** np.median(np.log10(mag)):.3g}; valid: within"
                    f" {CELL_DECADES:g} decades (a typing or unit error?)"
                )
            if ds.coherence is not None:
                c = ds.coherence[a, b]
                if np.all(np.isfinite(c)) and np.mean(c < 0.5) > 0.9:
                    warnings.append(
                        f"{where}: channel {ch}: coherence below 0.5 at"
                        f" {100 * np.mean(c < 0.5):.0f} % of the frequencies (mostly noise)"
                    )
    return warnings


def check_scale(doc: UrdfDocument, ds: FrfData) -> list[str]:
    """Each channel's median |H| against the nominal model's on the same grid; see the
    module docstring. Returns warnings; raises :class:`DataError` beyond the limit."""
    from ..frf.aligned import model_frf

    where = ds.source or "<in-memory FRF>"
    try:
        Hm = model_frf(doc, ds)
    except (np.linalg.LinAlgError, ValueError, KeyError):
        return []  # the model's own checks report a model that cannot be evaluated
    med_model = np.median(np.abs(Hm), axis=2)
    top = float(np.nanmax(med_model)) if np.isfinite(med_model).any() else 0.0
    warnings = []
    for a, o in enumerate(ds.outputs):
        for b, i in enumerate(ds.inputs):
            h = ds.H[a, b]
            if not np.all(np.isfinite(h)) or not top > 0:
                continue
            mm = float(med_model[a, b])
            if not mm >= 1e-6 * top:
                continue
            md = float(np.median(np.abs(h)))
            dec = float(np.log10(md / mm))
            ch = f"{o}.{i}"
            text = (
                f"{where}: column {ch}: median |H| {md:.3g} is {abs(dec):.1f} decades"
                f" {'above' if dec > 0 else 'below'} the model's {mm:.3g} ({ds.quantity})"
            )
            if abs(dec) > SCALE_DECADES:
                raise DataError(
                    f"{text}; valid: within {SCALE_DECADES:g} decades; check the units and the"
                    " quantity line of the file"
                )
            if abs(dec) > SCALE_WARN_DECADES:
                warnings.append(f"{text}; check the units")
    return warnings


def check_data(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    paths: Sequence[str | os.PathLike[str]] = (),
) -> list[str]:
    """Every data check of this module; returns the warnings.

    Args:
        doc: the nominal model (for the scale check).
        datasets: the data as read, one per file.
        paths: the files as given (for the duplicate check).
    """
    check_same_files(paths)
    warnings: list[str] = []
    for ds in datasets:
        warnings += check_values(ds)
        warnings += check_scale(doc, ds)
    return warnings
