"""Read and write measured FRF files by suffix, and check them against a model."""

from __future__ import annotations

import os
from collections.abc import Collection
from pathlib import Path

from ..exceptions import ChannelError, DataError, OperatingPointError
from .measurement import FrfData
from .uff_format import ChannelMap

CSV_SUFFIXES = (".csv",)
UFF_SUFFIXES = (".uff", ".unv", ".uff58")


def _kind(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix in CSV_SUFFIXES:
        return "csv"
    if suffix in UFF_SUFFIXES:
        return "uff"
    raise DataError(
        f"{path}: unknown data file suffix {path.suffix!r}; "
        f"valid: {', '.join(CSV_SUFFIXES + UFF_SUFFIXES)}"
    )


def read_frf(
    path: str | os.PathLike[str],
    *,
    drop_nan: bool = False,
    channel_map: ChannelMap | None = None,
) -> FrfData:
    """Read a measured-FRF file: bondid CSV (``.csv``) or UFF 58 (``.uff``, ``.unv``, ``.uff58``).

    Args:
        path: the data file.
        drop_nan: drop frequency rows holding NaN instead of raising :class:`DataError`.
        channel_map: for UFF files, ``{joint: (node, direction)}``; needed for files that
            bondid did not write. Ignored for CSV.

    Returns:
        :class:`FrfData` (``H`` ``(n_out, n_in, n_freq)``, ``freq_hz`` in Hz).

    Raises:
        DataError: missing file, unknown suffix or malformed content (names the file).
    """
    from ..paths import check_input_file

    p = Path(path)
    kind = _kind(p)
    check_input_file(p, "data file", DataError)  # a FIFO would block, a folder is no file
    if kind == "csv":
        from .csv_format import read_csv

        return read_csv(p, drop_nan=drop_nan)
    from .uff_format import read_uff58

    return read_uff58(p, channel_map=channel_map, drop_nan=drop_nan)


def write_frf(
    data: FrfData,
    path: str | os.PathLike[str],
    *,
    channel_map: ChannelMap | None = None,
) -> Path:
    """Write ``data`` as CSV or UFF 58, chosen by the suffix of ``path``, atomically.

    Args:
        data: the FRFs to write.
        path: ``.csv``, ``.uff``, ``.unv`` or ``.uff58``.
        channel_map: for UFF files, ``{joint: (node, direction)}`` (see
            :func:`~bondid.data.uff_format.default_channel_map`). Ignored for CSV.

    Returns:
        The path written.
    """
    p = Path(path)
    if _kind(p) == "csv":
        from .csv_format import write_csv

        return write_csv(data, p)
    from .uff_format import write_uff58

    return write_uff58(data, p, channel_map=channel_map)


def check_against_model(
    data: FrfData,
    *,
    inputs: Collection[str],
    outputs: Collection[str],
    joints: Collection[str],
) -> None:
    """Check that ``data`` fits a model's channels and joints.

    Args:
        data: measured FRFs.
        inputs: the model's input names (transmitted joints, then measurement points;
            :func:`bondid.linear.affine.model_inputs`).
        outputs: the names a model output may have (movable joints and measurement points;
            :func:`bondid.linear.affine.model_outputs`).
        joints: every joint name of the model (for the operating point).

    Raises:
        ChannelError: a present channel's OUT is not a model output or its IN not an input.
        OperatingPointError: the operating point names a joint the model lacks.
    """
    where = data.source or "<in-memory FRF>"
    for chan in data.channels:
        out, _, inp = chan.partition(".")
        if out not in outputs:
            raise ChannelError(
                f"{where}: channel {chan!r}: {out!r} is not a model output; "
                f"valid outputs: {', '.join(outputs) or 'none'}"
            )
        if inp not in inputs:
            raise ChannelError(
                f"{where}: channel {chan!r}: {inp!r} is not a model input; "
                f"valid inputs: {', '.join(inputs) or 'none'}"
            )
    for name in data.operating_point:
        if name not in joints:
            raise OperatingPointError(
                f"{where}: operating point names joint {name!r}, which the model lacks; "
                f"valid joints: {', '.join(joints) or 'none'}"
            )


def states_operating_point(path: str | os.PathLike[str]) -> bool:
    """True when the data file states an operating point: a CSV ``# operating_point`` line
    (empty = the neutral pose, stated), or a UFF58 ID line ``operating_point:``. False for a
    file without one (or that cannot be read)."""
    p = Path(path)
    try:
        with p.open("r", encoding="utf-8", errors="replace") as fh:
            if _kind(p) == "csv":
                for line in fh:
                    if not line.startswith("#"):
                        return False
                    if line[1:].strip().startswith("operating_point"):
                        return True
                return False
            return any("operating_point:" in line for line in fh)
    except (OSError, DataError):
        return False
