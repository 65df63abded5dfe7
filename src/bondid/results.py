"""A run's results written as one unit: checked early, staged, locked, moved into place.

Every command that writes under ``--out`` goes through :func:`open_results`, *before* any
work:

1. **Check** the target (:func:`check_out`): not an input file, not an existing file where a
   folder is wanted (or a folder where a file is wanted), no ancestor that is a file, writable,
   and no input file inside it under a name the command may write (whatever the input's name).
2. **Lock** it: ``fcntl.flock`` on ``.<name>.bondid-lock`` next to ``--out``; a second run into
   the same ``--out`` is refused with :class:`ConfigError` naming the lock's holder.
3. **Clean** the staging folders that killed runs into the same ``--out`` left behind (only
   the lock holder can own one, so any other is stale) and the hidden temporary files of
   :mod:`bondid.atomic` for this command's output names.
4. **Stage**: the command writes into :attr:`Results.tmp`, a hidden folder
   ``.<name>.bondid-tmp-<pid>-<random>`` next to ``--out`` (same file system).
5. **Commit** (:meth:`Results.commit`): a new ``--out`` folder is the staging folder renamed
   (one atomic step). Into an existing folder, the command's previous manifest is removed
   first, the files are moved in, the previous run's files that this run did not write are
   removed, and the manifest ``<command>.manifest.json`` comes last. A reader checks that the
   manifest exists and lists every file (:func:`read_manifest`); without it the folder holds
   no complete run of that command.

On any failure or interrupt before the commit the staging folder is removed and ``--out`` is
untouched; a SIGKILL leaves at most the hidden staging folder next to ``--out``, which the
next run cleans. A command whose ``--out`` is one file (``bondid.simulate``) stages that file
(and any extra file, e.g. its plot) the same way and moves each into place at the end; no
manifest.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import errno
import fnmatch
import hashlib
import json
import os
import secrets
import shutil
import threading
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from .exceptions import ConfigError, DataError
from .interrupt import signals_deferred
from .outcheck import _same, check_out

__all__ = ["Results", "check_out", "close_all", "open_results", "read_manifest"]

MANIFEST_FORMAT = "bondid-manifest/1"
_OPEN: list[Results] = []
_AT_FORK: list[bool] = [False]


def _forget_runs_in_child() -> None:
    """In a forked child (a process pool's worker): close the open runs' lock files and
    forget the runs. ``flock`` belongs to the open file, which a fork shares, so a worker that
    outlives its killed parent would otherwise hold the output's lock (seen in CI: the next
    run into the folder was refused while a killed fit's workers were still computing)."""
    for run in _OPEN:
        if run._lock_fd is not None:
            with contextlib.suppress(OSError):
                os.close(run._lock_fd)
            run._lock_fd = None
    _OPEN.clear()


def manifest_name(command: str) -> str:
    """``fit`` → ``fit.manifest.json``."""
    return f"{command}.manifest.json"


class Results:
    """A locked, staged output target; see the module docstring. Use :func:`open_results`."""

    def __init__(
        self,
        out: Path,
        command: str,
        inputs: Sequence[Path],
        *,
        file: bool,
        patterns: Sequence[str] = ("*",),
    ):
        self.out, self.command, self.inputs, self.file = out, command, list(inputs), file
        self.patterns = tuple(patterns)
        self.parent = out.absolute().parent
        self._lock_fd: int | None = None
        self.tmp = self.parent / f".{out.name}.bondid-tmp-{os.getpid()}-{secrets.token_hex(4)}"
        self._extra: dict[str, Path] = {}
        self.committed = False
        self.thread = threading.get_ident()  # close_all() abandons the runs of its own thread

    # -- lock and stage -----------------------------------------------------------------
    def _lock(self) -> None:
        import fcntl

        path = self.parent / f".{self.out.name}.bondid-lock"
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno not in (errno.EAGAIN, errno.EACCES):
                    raise
                holder = path.read_text(errors="replace").strip() or "another process"
                raise ConfigError(
                    f"--out {self.out}: another bondid run ({holder}) is writing there now;"
                    " wait for it or choose another output path"
                ) from None
            try:  # the file we locked must still be the one at ``path`` (see release)
                if os.fstat(fd).st_ino == os.stat(path).st_ino:
                    break
            except FileNotFoundError:
                pass
            os.close(fd)
        if not _AT_FORK[0]:
            os.register_at_fork(after_in_child=_forget_runs_in_child)
            _AT_FORK[0] = True
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()} (bondid.{self.command})\n".encode())
        self._lock_fd, self._lock_path = fd, path

    def _clean_stale(self) -> None:
        for d in self.parent.glob(f".{self.out.name}.bondid-tmp-*"):
            shutil.rmtree(d, ignore_errors=True)
        if not self.file and self.out.is_dir():
            for f in self.out.iterdir():
                if f.is_file() and _atomic_temp(f.name, self.patterns):
                    with contextlib.suppress(OSError):
                        f.unlink()

    def open(self) -> Results:
        self.parent.mkdir(parents=True, exist_ok=True)
        self._lock()
        try:
            self._clean_stale()
            self.tmp.mkdir()
        except BaseException:
            self.close()
            raise
        _OPEN.append(self)
        return self

    def path(self, name: str) -> Path:
        """Where to write output ``name`` now (inside the staging folder)."""
        return self.tmp / name

    def stage_extra(self, target: str | os.PathLike[str]) -> Path:
        """A staged path for a file written outside ``--out`` (e.g. ``--plot``), moved to
        ``target`` at the commit."""
        t = Path(target)
        staged = self.tmp / f"extra{len(self._extra)}{t.suffix}"
        self._extra[str(staged)] = t
        return staged

    # -- commit -------------------------------------------------------------------------
    def _files(self) -> list[Path]:
        extra = set(self._extra)
        return sorted(
            (f for f in self.tmp.rglob("*") if f.is_file() and str(f) not in extra),
            key=lambda f: f.as_posix(),
        )

    def commit(self, *, warnings: Sequence[str] = (), main: str | None = None) -> list[Path]:
        """Move the staged files into place (manifest last) and release the lock.

        Args:
            warnings: the run's warnings, recorded in the manifest.
            main: the main result file (moved first among the files, e.g. ``fit.json``).

        Returns:
            The final paths of the files written (manifest excluded).
        """
        files = self._files()
        for f in files:  # last guard: never replace an input
            dest = self.out if self.file else self.out / f.relative_to(self.tmp)
            if any(_same(dest, i) for i in self.inputs):
                raise ConfigError(f"{dest}: refusing to overwrite an input file")
        for target in self._extra.values():
            if any(_same(target, i) for i in self.inputs):
                raise ConfigError(f"{target}: refusing to overwrite an input file")
        with signals_deferred():  # a Ctrl-C now lands after the commit, not in its middle
            if self.file:
                written = self._commit_file(files)
            else:
                written = self._commit_dir(files, warnings, main)
            for staged, target in self._extra.items():
                _move(Path(staged), target)
                written.append(target)
        self.committed = True
        self.close()
        return written

    def _commit_file(self, files: list[Path]) -> list[Path]:
        if len(files) != 1:
            raise RuntimeError(f"{self.out}: staged {len(files)} files for a one-file output")
        _move(files[0], self.out)
        return [self.out]

    def _commit_dir(
        self, files: list[Path], warnings: Sequence[str], main: str | None
    ) -> list[Path]:
        names = [f.relative_to(self.tmp).as_posix() for f in files]
        manifest = {
            "format": MANIFEST_FORMAT,
            "command": f"bondid.{self.command}",
            "complete": True,
            "finished": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "files": [
                {"name": n, "bytes": f.stat().st_size, "sha256": _sha256(f)}
                for n, f in zip(names, files, strict=True)
            ],
            "warnings": list(warnings),
        }
        mname = manifest_name(self.command)
        (self.tmp / mname).write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
        if not self.out.exists():
            with contextlib.suppress(OSError):
                os.rename(self.tmp, self.out)  # the whole run appears in one step
                return [self.out / n for n in names]
        self.out.mkdir(parents=True, exist_ok=True)
        old = read_manifest(self.out, self.command, verify=False)
        with contextlib.suppress(FileNotFoundError):
            (self.out / mname).unlink()  # from here on, no complete run until the new manifest
        order = sorted(names, key=lambda n: n != main)
        for n in order:
            (self.out / n).parent.mkdir(parents=True, exist_ok=True)
            _move(self.tmp / n, self.out / n)
        for n in (old or {}).get("files_by_name", {}):
            stale = self.out / n
            if n not in names and not any(_same(stale, i) for i in self.inputs):
                with contextlib.suppress(OSError):
                    stale.unlink()
        _move(self.tmp / mname, self.out / mname)
        return [self.out / n for n in names]

    # -- clean up -----------------------------------------------------------------------
    def close(self) -> None:
        """Remove the staging folder (if still there) and release the lock."""
        shutil.rmtree(self.tmp, ignore_errors=True)
        if self._lock_fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(self._lock_path)  # unlink while locked: see the inode check
            os.close(self._lock_fd)
            self._lock_fd = None
        if self in _OPEN:
            _OPEN.remove(self)


def open_results(
    out: str | os.PathLike[str],
    command: str,
    inputs: Iterable[str | os.PathLike[str]],
    *,
    patterns: Sequence[str] = ("*",),
    file: bool = False,
) -> Results:
    """Check, lock and stage ``out`` for one run of ``bondid.<command>`` (module docstring).

    Raises:
        ConfigError: an unusable ``--out`` or a concurrent run into it.
    """
    ins = [Path(i) for i in inputs]
    p = check_out(out, ins, patterns=patterns, file=file)
    return Results(p, command, ins, file=file, patterns=patterns).open()


def close_all(thread_id: int | None = None) -> None:
    """Abandon every uncommitted :class:`Results` of this thread, or of thread ``thread_id``
    (called by :func:`bondid.cli.run`, and by the interrupt watchdog for the run it ends;
    runs in other threads, e.g. Dask workers, are left alone)."""
    me = threading.get_ident() if thread_id is None else thread_id
    for r in list(_OPEN):
        if r.thread == me:
            r.close()


def read_manifest(
    folder: str | os.PathLike[str], command: str, *, verify: bool = True
) -> dict[str, Any] | None:
    """The manifest of ``command``'s last complete run in ``folder`` (None if there is none).

    With ``verify``, every listed file must exist with its size and SHA-256.

    Raises:
        DataError: the manifest is unreadable, or (``verify``) a listed file is missing or
            differs.
    """
    path = Path(folder) / manifest_name(command)
    if not path.exists():
        return None
    try:
        m = json.loads(path.read_text(encoding="utf-8"))
        by_name = {f["name"]: f for f in m["files"]}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DataError(f"{path}: unreadable manifest ({exc})") from exc
    m["files_by_name"] = by_name
    if verify:
        for n, f in by_name.items():
            p = Path(folder) / n
            if (
                not p.is_file()
                or p.stat().st_size != f.get("bytes")
                or _sha256(p) != f.get("sha256")
            ):
                raise DataError(f"{path}: {n} is missing or differs from the run that wrote it")
    return m


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _atomic_temp(name: str, patterns: Sequence[str]) -> bool:
    """A hidden temporary file of :func:`bondid.atomic.atomic_path` for one of this command's
    output names: ``.<output name>.<8 random characters>[suffix]``."""
    if not name.startswith("."):
        return False
    stem, _, rest = name[1:].rpartition(".")
    if not stem:
        return False
    head, _, rand = stem.rpartition(".")
    cand = [(stem, rest), (head, rand)]  # ``.fit.json.abcd1234`` or ``.fit.json.abcd1234.json``
    return any(
        len(r) == 8
        and r.replace("_", "a").isalnum()
        and any(fnmatch.fnmatchcase(b, pat) for pat in patterns)
        for b, r in cand
        if b
    )


def _move(src: Path, dst: Path) -> None:
    """``os.replace``, or copy + replace across file systems."""
    try:
        os.replace(src, dst)
    except OSError as exc:
        if exc.errno != errno.EXDEV:
            raise
        tmp = dst.with_name(f".{dst.name}.{secrets.token_hex(4)}")
        shutil.copy2(src, tmp)
        os.replace(tmp, dst)
        src.unlink()
