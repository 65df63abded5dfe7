"""The manifest of a run's results, ``<command>.manifest.json``: written last by
:mod:`bondid.results`, read by the next run into the same folder and by every reader of a
results folder.

A manifest found in a folder is *data*, never trusted: it may come from a colleague's share,
a downloaded example, or someone who wants a file deleted. :func:`read_manifest` therefore
checks its shape and that every name it lists is a plain file name (no folder part, no
``..``, not absolute, not hidden) of the names the command writes (:data:`RESULT_PATTERNS`);
anything else is a :class:`~bondid.exceptions.ManifestError` (exit 2) naming the manifest,
the entry and what would be valid, and nothing in the folder is touched. A listed file is
verified through ``lstat``: a symbolic link, a FIFO or a folder under a listed name is never
what a run wrote, and is never opened.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import os
import stat
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .exceptions import ManifestError
from .paths import plain_name

MANIFEST_FORMAT = "bondid-manifest/1"
#: the largest manifest read (a real one lists tens of files: a few kB)
MAX_MANIFEST_BYTES = 4 << 20

#: the names each command writes into its ``--out`` folder (globs); a manifest of that
#: command may list these and nothing else
RESULT_PATTERNS: dict[str, tuple[str, ...]] = {
    "fit": ("fit.json", "fitted.urdf", "convergence.png", "bode_*.png"),
    "sensitivity": (
        "sensitivity.json", "sensitivity_bands.png", "sensitivity_channels.png", "sweep.png",
        "sweep_directions.png",
    ),
    "diagnose": (
        "diagnosis.json", "refit.urdf", "augmented.urdf", "augmented_all.urdf", "final.urdf",
        "residual_map.png", "bode_*.png",
    ),
    "modes": ("modes.json", "modes.html", "mode_*.html"),
    "report": ("report.html",),
    "fleet": ("fleet.json", "fleet.csv", "fleet_strip.png"),
}  # fmt: skip


def manifest_name(command: str) -> str:
    """``fit`` → ``fit.manifest.json``."""
    return f"{command}.manifest.json"


def valid_name(name: object, patterns: Sequence[str]) -> bool:
    """Whether ``name`` is a plain file name matching one of ``patterns``."""
    return plain_name(name) and any(fnmatch.fnmatchcase(str(name), p) for p in patterns)


def _expected(command: str, patterns: Sequence[str]) -> str:
    return f"a plain file name of bondid.{command}'s results ({', '.join(patterns)})"


def sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _read_text(path: Path) -> str:
    """The manifest's text: a regular file (not a link, FIFO or folder) of at most
    :data:`MAX_MANIFEST_BYTES`, UTF-8."""
    st = os.lstat(path)
    if not stat.S_ISREG(st.st_mode):
        raise ManifestError(
            f"{path}: not a regular file (bondid writes its manifests as plain files);"
            " remove it or choose another folder; nothing in the folder was touched"
        )
    if st.st_size > MAX_MANIFEST_BYTES:
        raise ManifestError(
            f"{path}: {st.st_size} bytes, more than a manifest holds ({MAX_MANIFEST_BYTES});"
            " remove it or choose another folder; nothing in the folder was touched"
        )
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0))
    with os.fdopen(fd, "rb") as fh:
        raw = fh.read(MAX_MANIFEST_BYTES + 1)
    return raw.decode("utf-8")


def parse_manifest(
    text: str, where: str | os.PathLike[str], command: str, patterns: Sequence[str] | None = None
) -> dict[str, Any]:
    """Check a manifest's text; returns it as a dict with ``files_by_name`` added.

    Args:
        text: the file's content.
        where: the manifest's path, for messages.
        command: the command whose manifest it is (``fit``).
        patterns: the names it may list (globs; default: any plain file name; a reader
            that knows the command passes :data:`RESULT_PATTERNS`).

    Raises:
        ManifestError: not JSON, the wrong shape, or a name outside ``patterns``.
    """
    pats = tuple(patterns or ("*",))
    tail = "remove it or choose another folder; nothing in the folder was touched"
    try:
        m = json.loads(text)
    except ValueError as exc:
        raise ManifestError(f"{where}: not a JSON manifest ({exc}); {tail}") from None
    if not isinstance(m, dict) or not isinstance(m.get("files"), list):
        raise ManifestError(
            f"{where}: not a bondid manifest (expected an object with a list 'files'); {tail}"
        )
    by_name: dict[str, dict[str, Any]] = {}
    for k, f in enumerate(m["files"], start=1):
        if not isinstance(f, dict):
            raise ManifestError(f"{where}: files entry {k} is not an object; {tail}")
        name = f.get("name")
        if not valid_name(name, pats):
            raise ManifestError(
                f"{where}: files entry {k} names {name!r}; valid: {_expected(command, pats)};"
                f" {tail}"
            )
        size, digest = f.get("bytes"), f.get("sha256")
        if isinstance(size, bool) or not isinstance(size, int) or size < 0:
            raise ManifestError(
                f"{where}: files entry {k} ({name}): 'bytes' is {size!r}; valid: an integer"
                f" >= 0; {tail}"
            )
        if not isinstance(digest, str):
            raise ManifestError(
                f"{where}: files entry {k} ({name}): 'sha256' is {digest!r}; valid: a hex"
                f" string; {tail}"
            )
        if name in by_name:
            raise ManifestError(f"{where}: files entry {k} lists {name} a second time; {tail}")
        by_name[str(name)] = f
    warnings = m.get("warnings", [])
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
        raise ManifestError(f"{where}: 'warnings' is not a list of texts; {tail}")
    m["files_by_name"] = by_name
    return m


def read_manifest(
    folder: str | os.PathLike[str],
    command: str,
    *,
    verify: bool = True,
    patterns: Sequence[str] | None = None,
) -> dict[str, Any] | None:
    """The manifest of ``command``'s last complete run in ``folder`` (None if there is none).

    With ``verify``, every listed file must exist as a regular file with its size and
    SHA-256.

    Raises:
        ManifestError: the manifest is unreadable or malformed (:func:`parse_manifest`), or
            (``verify``) a listed file is missing or differs.
    """
    path = Path(folder) / manifest_name(command)
    if not os.path.lexists(path):
        return None
    try:
        text = _read_text(path)
    except (OSError, UnicodeDecodeError) as exc:
        raise ManifestError(
            f"{path}: unreadable manifest ({exc}); remove it or choose another folder"
        ) from None
    m = parse_manifest(text, path, command, patterns)
    if verify:
        for n, f in m["files_by_name"].items():
            if not listed_file_matches(Path(folder) / n, f):
                raise ManifestError(f"{path}: {n} is missing or differs from the run that wrote it")
    return m


def listed_file_matches(path: Path, entry: dict[str, Any]) -> bool:
    """Whether ``path`` is a regular file (not a link) of the entry's size and SHA-256."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    if not stat.S_ISREG(st.st_mode) or st.st_size != entry.get("bytes"):
        return False
    try:
        return sha256(path) == entry.get("sha256")
    except OSError:
        return False
