"""Discover a fleet: one sub-folder per machine under ``DIR``, named by the machine id.

A machine's folder holds its measured FRF files (CSV or UFF58, one per operating point) and,
optionally, its own ``model.urdf`` used instead of the nominal model. Hidden folders (``.x``)
and folders starting with ``_`` are not machines.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

from ..data.io import CSV_SUFFIXES, UFF_SUFFIXES
from ..exceptions import ConfigError

#: a machine's own model, used instead of the nominal one when present
OWN_MODEL = "model.urdf"
DATA_SUFFIXES = CSV_SUFFIXES + UFF_SUFFIXES
_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")


@dataclass(frozen=True)
class Machine:
    """One machine of the fleet: its id, data files (sorted) and model file."""

    id: str
    folder: Path
    data: tuple[Path, ...]
    model: Path
    own_model: bool

    def fingerprint(self) -> str:
        """A short hash of the inputs (paths, sizes, modification times): changed inputs → rerun."""
        h = hashlib.sha256()
        for p in (self.model, *self.data):
            st = p.stat()
            h.update(f"{p.resolve()}|{st.st_size}|{st.st_mtime_ns}\n".encode())
        return h.hexdigest()[:16]


def discover(machines_dir: Path, nominal: Path) -> list[Machine]:
    """The machines under ``machines_dir``, sorted by id.

    A machine folder without data files is still listed (with ``data`` empty), so that it is
    reported as failed with its reason instead of silently left out.

    Raises:
        ConfigError: ``machines_dir`` is not a folder, holds no machine folder, or a folder
            name is not a usable id.
    """
    if not machines_dir.is_dir():
        raise ConfigError(f"--machines {machines_dir}: not a folder (one sub-folder per machine)")
    out = []
    for sub in sorted(machines_dir.iterdir()):
        if not sub.is_dir() or sub.name.startswith((".", "_")):
            continue
        if not _ID.match(sub.name):
            raise ConfigError(
                f"--machines {machines_dir}: folder name {sub.name!r} is not a usable machine id"
                " (letters, digits and _ . + - only, not starting with a symbol)"
            )
        data = tuple(
            sorted(p for p in sub.iterdir() if p.is_file() and p.suffix.lower() in DATA_SUFFIXES)
        )
        own = sub / OWN_MODEL
        out.append(Machine(sub.name, sub, data, own if own.is_file() else nominal, own.is_file()))
    if not out:
        raise ConfigError(
            f"--machines {machines_dir}: no machine folder found; expected one sub-folder per"
            f" machine holding its data files ({', '.join(DATA_SUFFIXES)})"
        )
    return out
