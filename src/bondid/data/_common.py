"""Checks shared by the CSV and UFF readers and writers (names, operating points, grids)."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..exceptions import ChannelError, DataError, OperatingPointError
from .measurement import FrfData

FORMAT_VERSION = "1"

# A joint name must survive "OUT.IN.re" columns and "x=0.1 y=0.2" operating points.
_NAME_RE = re.compile(r"^[^\s.,=#\"']+$")
_NAME_RULE = "non-empty, without '.', ',', '=', '#', quotes or whitespace"


def check_joint_name(name: str, where: str, what: str = "joint") -> None:
    """Raise :class:`ChannelError` if ``name`` cannot be written into a channel name."""
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise ChannelError(f"{where}: invalid {what} name {name!r}; names must be {_NAME_RULE}")


def format_operating_point(op: dict[str, float], where: str) -> list[str]:
    """Tokens ``name=value`` (value with full double precision) of an operating point."""
    tokens = []
    for name, value in op.items():
        if not isinstance(name, str) or not _NAME_RE.match(name):
            raise OperatingPointError(
                f"{where}: invalid operating-point joint name {name!r}; names must be {_NAME_RULE}"
            )
        v = float(value)
        if not math.isfinite(v):
            raise OperatingPointError(
                f"{where}: operating point {name}={v!r} is not finite; give a finite value"
            )
        tokens.append(f"{name}={v!r}")
    return tokens


def parse_operating_point(
    text: str, where: str, into: dict[str, float] | None = None
) -> dict[str, float]:
    """Parse ``"x=0.0 y=1e-3"`` (space-separated ``joint=value``) into a dict (m or rad)."""
    op: dict[str, float] = {} if into is None else into
    for token in text.split():
        name, eq, value = token.partition("=")
        if not eq or not _NAME_RE.match(name):
            raise OperatingPointError(
                f"{where}: malformed operating_point token {token!r}; expected joint=value "
                f"separated by spaces, e.g. 'x=0.0 y=0.001'"
            )
        try:
            v = float(value)
        except ValueError:
            raise OperatingPointError(
                f"{where}: operating_point {name}={value!r} is not a number; e.g. {name}=0.0"
            ) from None
        if not math.isfinite(v):
            raise OperatingPointError(
                f"{where}: operating_point {name}={value!r} is not finite; give a finite value"
            )
        if name in op:
            raise OperatingPointError(
                f"{where}: operating_point gives joint {name!r} twice; give each joint once"
            )
        op[name] = v
    return op


def has_dc_line(freq_hz: np.ndarray) -> bool:
    """Does the grid start with a 0 Hz (DC) line before positive frequencies? Analysers
    write one; a readers drops it (an FRF model is evaluated at f > 0, and the DC line of
    an FFT estimate is no measurement of it) and says so in ``FrfData.notes``."""
    f = np.asarray(freq_hz, dtype=float)
    return bool(f.size > 1 and f[0] == 0.0 and np.all(f[1:] > 0))


def dc_note(where: str) -> str:
    """The note of a dropped DC line."""
    return f"{where}: the 0 Hz (DC) line dropped; the model is compared at f > 0 only"


def check_frequencies(freq_hz: np.ndarray, where: str, labels: Sequence[str] | None = None) -> None:
    """Raise :class:`DataError` unless ``freq_hz`` (Hz) is positive and strictly increasing.

    ``labels[k]`` names point ``k`` in the message (e.g. ``"line 7"``); default ``"point k"``.
    """

    def label(k: int) -> str:
        return labels[k] if labels is not None else f"point {k + 1}"

    if freq_hz.size == 0:
        raise DataError(f"{where}: no frequency rows; give at least one frequency")
    bad = np.flatnonzero(~np.isfinite(freq_hz))
    if bad.size:
        k = int(bad[0])
        raise DataError(f"{where}: {label(k)}: frequency {float(freq_hz[k])!r} Hz is not finite")
    bad = np.flatnonzero(~(freq_hz > 0))
    if bad.size:
        k = int(bad[0])
        raise DataError(
            f"{where}: {label(k)}: frequency {float(freq_hz[k])!r} Hz is not positive; "
            f"frequencies must be > 0"
        )
    steps = np.flatnonzero(np.diff(freq_hz) <= 0)
    if steps.size:
        k = int(steps[0]) + 1
        kind = "duplicate" if freq_hz[k] == freq_hz[k - 1] else "unsorted"
        raise DataError(
            f"{where}: {label(k)}: {kind} frequency {float(freq_hz[k])!r} Hz after "
            f"{float(freq_hz[k - 1])!r} Hz; frequencies must be strictly increasing"
        )


def check_coherence(values: np.ndarray, where: str, labels: Sequence[str] | None = None) -> None:
    """Raise :class:`DataError` at the first coherence value (real, ``(n_freq,)``) outside
    0..1; ``labels[k]`` names point ``k`` in the message (default ``"point k"``, 1-based)."""
    bad = np.flatnonzero((values < 0) | (values > 1))
    if bad.size:
        k = int(bad[0])
        at = labels[k] if labels is not None else f"point {k + 1}"
        raise DataError(f"{where}: {at}: coherence {float(values[k])!r} outside 0..1")


def written_channels(data: FrfData, where: str) -> list[tuple[int, int, bool]]:
    """The channels a writer stores: ``(row, column, has_coherence)``, row-major.

    A channel is stored when it is finite at every frequency and skipped when it is NaN at
    every frequency; a partly missing channel (or coherence) cannot be written.
    """
    for name in (*data.outputs, *data.inputs):
        check_joint_name(name, where)
    finite = np.isfinite(data.H)
    coh = data.coherence
    out: list[tuple[int, int, bool]] = []
    for a, o in enumerate(data.outputs):
        for b, i in enumerate(data.inputs):
            if not finite[a, b].any():
                continue
            if not finite[a, b].all():
                raise DataError(
                    f"{where}: channel {o}.{i} is NaN at some frequencies only; "
                    f"drop those frequencies or the whole channel before writing"
                )
            has_coh = False
            if coh is not None:
                c = coh[a, b]
                if np.isfinite(c).all():
                    if np.any((c < 0) | (c > 1)):
                        raise DataError(
                            f"{where}: coherence of channel {o}.{i} lies outside 0..1; "
                            f"valid coherence is in 0..1"
                        )
                    has_coh = True
                elif np.isfinite(c).any():
                    raise DataError(
                        f"{where}: coherence of channel {o}.{i} is NaN at some frequencies "
                        f"only; give it everywhere or nowhere"
                    )
            out.append((a, b, has_coh))
    if not out:
        raise DataError(f"{where}: no channel has data; nothing to write")
    check_frequencies(np.asarray(data.freq_hz, dtype=float), where)
    return out


def read_file_bytes(path: Path) -> bytes:
    """The bytes of ``path``; a missing or unreadable file raises :class:`DataError`."""
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise DataError(f"{path}: no such file; check the path") from None
    except IsADirectoryError:
        raise DataError(f"{path}: is a directory, not a data file") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read the file ({exc.strerror})") from None


def frf_arrays(H: np.ndarray, freq_hz: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray]:
    """``(H complex (n_out, n_in, n_freq), freq_hz float (n_freq,))``; raises
    :class:`DataError` naming ``where`` when the shapes do not match."""
    Hc = np.asarray(H, dtype=complex)
    f = np.asarray(freq_hz, dtype=float)
    if Hc.ndim != 3 or f.ndim != 1 or Hc.shape[2] != f.size:
        raise DataError(
            f"{where}: H has shape {Hc.shape} and freq_hz {f.shape}; "
            f"expected (n_out, n_in, n_freq) and (n_freq,)"
        )
    return Hc, f
