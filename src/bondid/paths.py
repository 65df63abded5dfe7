"""Checks of the paths a command is given, before any work: :func:`check_input_file`,
:func:`check_output_path` and :func:`check_path_options`.

An input must be a regular, readable file: a FIFO, a device or a socket would block or
stream forever, a folder is not a file, a symbolic link loop resolves to nothing. An output
path must not be (or lie under) a symbolic link loop. Each failure is a
:class:`~bondid.exceptions.ConfigError` (exit 2) naming the option, the path and what would
be valid. Nothing is opened for longer than the check needs, and nothing is created.
"""

from __future__ import annotations

import argparse
import errno
import os
import stat
from collections.abc import Iterable
from pathlib import Path

from .exceptions import BondidError, ConfigError

#: ``argparse`` destinations that name input files, and their option for messages
INPUT_FILE_OPTIONS = {
    "model": "--model",
    "data": "--data",
    "study": "--study",
    "points_file": "--points-file",
    "fitted": "--fitted",
}
#: ``argparse`` destinations that name output paths
OUTPUT_PATH_OPTIONS = {"out": "--out", "plot": "--plot"}

_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def file_kind(mode: int) -> str:
    """What a ``st_mode`` is, in words ("a regular file", "a FIFO (named pipe)", ...)."""
    if stat.S_ISREG(mode):
        return "a regular file"
    return next((word for test, word in _KINDS if test(mode)), "not a regular file")


def _stat(path: Path, option: str, what: str, error: type[BondidError]) -> os.stat_result:
    """``os.stat`` with its failures as one-line errors of class ``error``."""
    try:
        return os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            raise error(
                f"{option} {path}: a symbolic link to {os.readlink(path)!r}, which does not"
                f" exist; valid: {what}"
            ) from None
        raise error(f"{option} {path}: no such file (cannot read it); check the path") from None
    except OSError as exc:
        raise error(f"{option} {path}: {_reason(exc)}; valid: {what}") from None


def _reason(exc: OSError) -> str:
    if exc.errno == errno.ELOOP:
        return "a loop of symbolic links (it resolves to no file)"
    if exc.errno == errno.ENOTDIR:
        return "a part of the path is a file, not a folder"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if exc.errno == errno.ENAMETOOLONG:
        return "the name is too long"
    return exc.strerror or str(exc)


def check_input_file(
    path: str | os.PathLike[str], option: str, error: type[BondidError] = ConfigError
) -> Path:
    """Refuse an input that is not a regular, readable file (see the module docstring).

    Args:
        path: the file as given.
        option: the option that named it (``--data``), or what it is (``data file``), for
            the message.
        error: the exception class to raise (a reader raises its own: DataError, ModelError).

    Returns:
        ``path`` as a :class:`Path`.

    Raises:
        ConfigError: (or ``error``) naming the option, the path and what would be valid.
    """
    p = Path(path)
    what = "a regular, readable file"
    st = _stat(p, option, what, error)
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{option} {p}: is {file_kind(st.st_mode)}; valid: {what}")
    try:  # O_NONBLOCK: a file replaced by a FIFO since the stat cannot block the open
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise error(f"{option} {p}: cannot be read ({_reason(exc)}); valid: {what}") from None
    os.close(fd)
    return p


def check_output_path(path: str | os.PathLike[str], option: str) -> Path:
    """Refuse an output path that is, or lies under, a symbolic-link loop or a dangling
    link (writing there fails, or lands wherever the link points). A missing path is fine.

    Raises:
        ConfigError: naming the option and the path.
    """
    p = Path(path)
    probe = p
    while True:
        try:
            os.stat(probe)
            break
        except FileNotFoundError:
            if os.path.islink(probe):
                raise ConfigError(
                    f"{option} {p}: {probe} is a symbolic link to {os.readlink(probe)!r},"
                    " which does not exist; valid: a new or existing folder or file"
                ) from None
        except OSError as exc:
            raise ConfigError(
                f"{option} {p}: {_reason(exc)}; valid: a path that resolves to a folder or a new"
                " name"
            ) from None
        if probe.parent == probe:
            break
        probe = probe.parent
    return p


def check_path_options(args: argparse.Namespace) -> None:
    """Check every input file and output path option ``args`` has (see
    :data:`INPUT_FILE_OPTIONS`, :data:`OUTPUT_PATH_OPTIONS`); None values are skipped."""
    for dest, option in INPUT_FILE_OPTIONS.items():
        value = getattr(args, dest, None)
        for item in _items(value):
            check_input_file(item, option)
    for dest, option in OUTPUT_PATH_OPTIONS.items():
        value = getattr(args, dest, None)
        for item in _items(value):
            check_output_path(item, option)


def _items(value: object) -> Iterable[str | os.PathLike[str]]:
    if value is None:
        return ()
    if isinstance(value, list | tuple):
        return [v for v in value if isinstance(v, str | os.PathLike)]
    return [value] if isinstance(value, str | os.PathLike) else ()


def plain_name(name: object) -> bool:
    """Whether ``name`` is a plain file name: a non-empty string, not ``.``/``..``, without
    a path separator, a NUL or a leading dot (a hidden file is never a result)."""
    return (
        isinstance(name, str)
        and name not in ("", ".", "..")
        and not name.startswith(".")
        and "/" not in name
        and "\\" not in name
        and "\0" not in name
        and os.path.basename(name) == name
        and not os.path.isabs(name)
    )
