"""Checks of an output target (``--out``) before any work: :func:`check_out`.

Used by :mod:`bondid.results` (which every command goes through); see its docstring.
"""

from __future__ import annotations

import contextlib
import fnmatch
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from .exceptions import ConfigError


def _same(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except (OSError, RuntimeError):  # (RuntimeError: a loop of symbolic links)
        return False


def _existing_ancestor(path: Path) -> Path:
    p = path.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_out(
    out: str | os.PathLike[str],
    inputs: Iterable[str | os.PathLike[str]],
    *,
    patterns: Sequence[str] = (),
    file: bool = False,
    option: str = "--out",
) -> Path:
    """Refuse an output target that cannot or must not be written (see the module doc).

    Args:
        out: the ``--out`` folder (or file when ``file``).
        inputs: every input file of the run.
        patterns: names (globs) the command may write inside the folder, e.g. ``bode_*.png``.
        file: ``out`` is one file, not a folder.
        option: the option's name for messages.

    Raises:
        ConfigError: naming ``out`` and what would be valid.
    """
    p = Path(out)
    ins = [Path(i) for i in inputs]
    for i in ins:
        if _same(p, i):
            raise ConfigError(
                f"{option} {p}: is an input file; refusing to overwrite it; choose another path"
            )
    anc = _existing_ancestor(p)
    if anc != p.absolute() and not anc.is_dir():
        raise ConfigError(f"{option} {p}: {anc} is a file, so nothing can be created under it")
    if p.exists():
        if file and p.is_dir():
            raise ConfigError(f"{option} {p}: is a folder; give a file name (.csv or .uff)")
        if not file and not p.is_dir():
            raise ConfigError(f"{option} {p}: is an existing file; give a folder (new or existing)")
    where = p if p.exists() else anc
    parent = p.absolute().parent if p.exists() else anc
    for d in {where, parent}:
        if d.is_dir() and not _writable(d):
            raise ConfigError(f"{option} {p}: the folder {d} is not writable; choose another")
    if not file:
        for i in ins:
            if (
                i.exists()
                and _same(i.absolute().parent, p)
                and any(fnmatch.fnmatchcase(i.name, pat) for pat in patterns)
            ):
                raise ConfigError(
                    f"{option} {p}: this run writes {i.name} there, and {i} is one of its"
                    " inputs; choose another output folder (inputs are never overwritten)"
                )
    return p


def _writable(folder: Path) -> bool:
    """Whether a file can be created in ``folder`` (tried: permission bits do not tell for
    root, read-only mounts or /proc)."""
    import tempfile

    try:
        fd, name = tempfile.mkstemp(prefix=".bondid-probe-", dir=folder)
    except OSError:
        return False
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)
    return True
