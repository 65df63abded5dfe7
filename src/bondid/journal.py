"""Replace a run's files in an existing results folder all or nothing: :func:`replace_files`
and :func:`recover`.

A new ``--out`` folder appears in one rename (:mod:`bondid.results`). Into an existing
folder (which may hold the user's own files and other commands' results) the new files are
moved in one by one, so a SIGKILL in the middle would otherwise leave new files beside old
ones. The previous run's files are therefore set aside, not deleted, until the new manifest
is in place:

1. ``OUT/.bondid-undo-<command>/journal.json`` records the new names, the names that existed
   before and the SHA-256 of the new manifest (written and synced before anything moves);
2. the old manifest, then every old file the new run replaces or drops, move into that
   folder (from here on the folder holds no complete run of the command);
3. the new files move in (the main result first), and the new manifest last: the commit
   point;
4. the undo folder is removed.

An error inside (a full disk writing the journal, an interrupt is deferred) undoes the steps
at once; a SIGKILL leaves the undo folder, and the next run into the folder (which holds its
lock) calls :func:`recover`: if the new manifest is in place the commit had finished and the
undo folder goes, otherwise every file set aside is put back and the new ones removed, so the
folder holds the previous run again. Every name involved was checked as a plain file name of
the command's results before (:mod:`bondid.manifest`); nothing outside ``OUT`` is touched.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import secrets
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

from .manifest import sha256
from .paths import plain_name

JOURNAL = "journal.json"
UNDO_PREFIX = ".bondid-undo-"
_UNDO = re.compile(r"^\.bondid-undo-([a-z_]+)$")


def undo_dir(out: Path, command: str) -> Path:
    """The undo folder of ``command``'s commit into ``out``."""
    return out / f"{UNDO_PREFIX}{command}"


def pending(out: Path) -> list[str]:
    """The commands whose commit into ``out`` was interrupted (undo folder still there)."""
    try:
        entries = list(os.scandir(out))
    except OSError:
        return []
    return sorted(
        m.group(1)
        for e in entries
        if (m := _UNDO.match(e.name)) and e.is_dir(follow_symlinks=False)
    )


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _write_journal(undo: Path, record: dict[str, object]) -> None:
    path = undo / JOURNAL
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(json.dumps(record) + "\n")
        fh.flush()
        os.fsync(fh.fileno())
    _fsync_dir(undo)


def move(src: Path, dst: Path) -> None:
    """``os.replace``, or copy + replace across file systems (the copy's temporary file is
    removed if the copy fails)."""
    try:
        os.replace(src, dst)
    except OSError as exc:
        if exc.errno != errno.EXDEV:
            raise
        tmp = dst.with_name(f".{dst.name}.{secrets.token_hex(4)}")
        try:
            shutil.copy2(src, tmp)
            os.replace(tmp, dst)
        except BaseException:
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise
        src.unlink()


def replace_files(
    out: Path,
    staged: Path,
    command: str,
    names: Sequence[str],
    manifest: str,
    drop: Sequence[str],
    keep: Callable[[Path], bool] = lambda p: False,
) -> None:
    """Move ``names`` and then ``manifest`` from ``staged`` into ``out``, setting aside the
    files they replace and the names in ``drop`` (the previous run's files this run did not
    write), all or nothing (module docstring).

    Args:
        out: the existing results folder (locked by the caller).
        staged: the staging folder holding ``names`` and ``manifest``.
        command: the command (names the undo folder).
        names: the new files, in the order to move them (plain names).
        manifest: the new manifest's name (moved last).
        drop: plain names of old files to remove (a missing one is skipped).
        keep: files never to move or remove (the run's inputs).
    """
    for n in (*names, manifest, *drop):
        if not plain_name(n):
            raise RuntimeError(f"{out}: refusing to commit the file name {n!r}")
    undo = undo_dir(out, command)
    todo = list(dict.fromkeys([manifest, *names, *drop]))
    existing = [n for n in todo if os.path.lexists(out / n) and not keep(out / n)]
    undo.mkdir()
    try:
        _write_journal(
            undo,
            {
                "new": [*names, manifest],
                "existing": existing,
                "manifest": manifest,
                "manifest_sha256": sha256(staged / manifest),
            },
        )
        for n in existing:  # the old manifest first
            os.replace(out / n, undo / n)
        for n in names:
            move(staged / n, out / n)
        move(staged / manifest, out / manifest)
    except BaseException:
        recover(out, command)
        raise
    shutil.rmtree(undo, ignore_errors=True)


def recover(out: Path, command: str) -> str:
    """Finish or undo an interrupted :func:`replace_files` of ``command`` into ``out``.

    Returns:
        ``"done"`` (the commit had reached its manifest: the set-aside files are dropped),
        ``"undone"`` (the previous files are back) or ``"none"`` (no undo folder).
    """
    undo = undo_dir(out, command)
    if not undo.is_dir() or undo.is_symlink():
        return "none"
    try:
        record = json.loads((undo / JOURNAL).read_text(encoding="utf-8"))
        new = [n for n in record["new"] if plain_name(n)]
        existing = {n for n in record["existing"] if plain_name(n)}
        mname, digest = str(record["manifest"]), str(record["manifest_sha256"])
    except (OSError, ValueError, KeyError, TypeError):
        new, existing, mname, digest = [], set(), "", ""  # put back what was set aside
    committed = False
    if plain_name(mname) and (out / mname).is_file() and not (out / mname).is_symlink():
        with contextlib.suppress(OSError):
            committed = sha256(out / mname) == digest
    if committed:
        shutil.rmtree(undo, ignore_errors=True)
        return "done"
    for n in new:  # a new file that replaced nothing: remove it
        if n not in existing and os.path.lexists(out / n):
            with contextlib.suppress(OSError):
                (out / n).unlink()
    for entry in os.scandir(undo):
        if entry.name != JOURNAL and plain_name(entry.name):
            os.replace(entry.path, out / entry.name)
    shutil.rmtree(undo, ignore_errors=True)
    return "undone"
