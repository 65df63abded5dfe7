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
   (one atomic step). Into an existing folder the files are swapped all or nothing
   (:mod:`bondid.journal`): the previous run's manifest and files are set aside until the new
   files and, last, the new manifest ``<command>.manifest.json`` are in place. A reader
   checks that the manifest exists and lists every file (:func:`read_manifest`); without it
   the folder holds no complete run of that command.

The previous run's manifest is data, never trusted (:mod:`bondid.manifest`): it is checked
when the folder is opened, and a malformed one, or one naming anything but a plain file name
of the command's results, refuses the run (exit 2) before any work, with nothing touched.

On any failure or interrupt before the commit the staging folder is removed and ``--out`` is
untouched; a SIGKILL leaves at most the hidden staging folder next to ``--out`` (which the
next run cleans) or, during a commit, the undo folder inside it (which the next run into the
folder uses to put the previous run back, :func:`bondid.journal.recover`). A command whose
``--out`` is one file (``bondid.simulate``) stages that file (and any extra file, e.g. its
plot) the same way and moves each into place at the end; no manifest.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import errno
import fnmatch
import json
import os
import re
import secrets
import shutil
import threading
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from . import interrupt, open_runs
from .exceptions import ConfigError
from .interrupt import signals_deferred
from .journal import move, pending, recover, replace_files
from .manifest import (
    MANIFEST_FORMAT,
    manifest_name,
    read_manifest,
    sha256,
    valid_name,
)
from .open_runs import close_all as close_all
from .outcheck import _same, check_out
from .paths import check_output_path

__all__ = [
    "MANIFEST_FORMAT",
    "Results",
    "check_out",
    "close_all",
    "manifest_name",
    "open_results",
    "read_manifest",
]

_AT_FORK: list[bool] = [False]


def _forget_runs_in_child() -> None:
    """In a forked child (a process pool's worker): close the open runs' lock files and
    forget the runs. ``flock`` belongs to the open file, which a fork shares, so a worker that
    outlives its killed parent would otherwise hold the output's lock (seen in CI: the next
    run into the folder was refused while a killed fit's workers were still computing)."""
    for run in open_runs.forget_all():
        if isinstance(run, Results) and run._lock_fd is not None:
            with contextlib.suppress(OSError):
                os.close(run._lock_fd)
            run._lock_fd = None


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
        self._old: dict[str, Any] | None = None
        #: interrupted commits into this folder found at the start, and what became of them
        self.recovered: dict[str, str] = {}
        self.committed = False
        self.thread = threading.get_ident()  # close_all() abandons the runs of its own thread

    # -- lock and stage -----------------------------------------------------------------
    def _lock(self) -> None:
        import fcntl

        path = self.parent / f".{self.out.name}.bondid-lock"
        while True:
            try:  # never through a link: the lock file is truncated and written below
                fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o666)
            except OSError as exc:
                if exc.errno != errno.ELOOP:
                    raise
                raise ConfigError(
                    f"--out {self.out}: {path} is a symbolic link, not bondid's lock file;"
                    " remove it or choose another output path"
                ) from None
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
        """Remove what killed runs into the same ``--out`` left: their staging folders (only
        the lock holder can own one, so any other is stale), and the hidden temporary files
        of :mod:`bondid.atomic` for this command's output names. Only names a run produces
        are matched; a symbolic link is never followed."""
        stale = re.compile(rf"^\.{re.escape(self.out.name)}\.bondid-tmp-\d+-[0-9a-f]{{8}}$")
        for d in self.parent.iterdir():
            if stale.match(d.name) and d.is_dir() and not d.is_symlink():
                shutil.rmtree(d, ignore_errors=True)
        if not self.file and self.out.is_dir():
            for f in self.out.iterdir():
                if f.is_file() and not f.is_symlink() and _atomic_temp(f.name, self.patterns):
                    with contextlib.suppress(OSError):
                        f.unlink()

    def _read_previous(self) -> None:
        """Finish or undo interrupted commits into the folder, then read (and check) the
        previous run's manifest: a malformed one refuses the run (ManifestError)."""
        if self.file or not self.out.is_dir():
            return
        for command in pending(self.out):
            self.recovered[command] = recover(self.out, command)
        self._old = read_manifest(self.out, self.command, verify=False, patterns=self.patterns)

    def open(self) -> Results:
        check_output_path(self.out, "--out")
        self.parent.mkdir(parents=True, exist_ok=True)
        self._lock()
        try:
            self._read_previous()
            self._clean_stale()
            self.tmp.mkdir()
        except BaseException:
            self.close()
            raise
        open_runs.add(self)
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
        """The staged result files (hidden temporary files of a failed write excluded)."""
        extra = set(self._extra)
        return sorted(
            (
                f
                for f in self.tmp.rglob("*")
                if f.is_file() and str(f) not in extra and not f.name.startswith(".")
            ),
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
        interrupt.check()  # an interrupt a library swallowed: the run ends here, uncommitted
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
                move(Path(staged), target)
                written.append(target)
        self.committed = True
        self.close()
        return written

    def _commit_file(self, files: list[Path]) -> list[Path]:
        if len(files) != 1:
            raise RuntimeError(f"{self.out}: staged {len(files)} files for a one-file output")
        move(files[0], self.out)
        return [self.out]

    def _commit_dir(
        self, files: list[Path], warnings: Sequence[str], main: str | None
    ) -> list[Path]:
        names = [f.relative_to(self.tmp).as_posix() for f in files]
        for n in names:
            if not valid_name(n, self.patterns):
                raise RuntimeError(
                    f"{self.out}: bondid.{self.command} staged {n!r}, not one of its result"
                    f" names ({', '.join(self.patterns)})"
                )
        manifest = {
            "format": MANIFEST_FORMAT,
            "command": f"bondid.{self.command}",
            "complete": True,
            "finished": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "files": [
                {"name": n, "bytes": f.stat().st_size, "sha256": sha256(f)}
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
        old = [] if self._old is None else list(self._old["files_by_name"])
        order = sorted(names, key=lambda n: n != main)
        replace_files(
            self.out, self.tmp, self.command, order, mname,
            drop=[n for n in old if n not in names],
            keep=lambda p: any(_same(p, i) for i in self.inputs),
        )  # fmt: skip
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
        open_runs.discard(self)


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
        ManifestError: the folder's previous manifest of this command is malformed or names
            a file the command never writes (nothing was touched).
    """
    ins = [Path(i) for i in inputs]
    check_output_path(out, "--out")
    p = check_out(out, ins, patterns=patterns, file=file)
    return Results(p, command, ins, file=file, patterns=patterns).open()


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
