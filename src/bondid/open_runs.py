"""The runs of this process whose results are not committed yet, by thread.

A run that stops before its commit (an error, a Ctrl-C, the interrupt watchdog ending a
stuck run) must leave ``--out`` untouched: whoever ends it abandons the run's staged
results (:func:`close_all`), and a message about a full disk names the folder being
written (:func:`open_targets`). The staging and committing itself is
:mod:`bondid.results`; this register holds only which runs are open, so that the signal
handling in :mod:`bondid.interrupt` can reach them without depending on how a run is
written.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Protocol


class OpenRun(Protocol):
    """A run being written (a :class:`bondid.results.Results`)."""

    #: the run's ``--out`` target
    out: Path
    #: the thread that opened it: :func:`close_all` abandons the runs of one thread only
    thread: int

    def close(self) -> None:
        """Abandon what is staged and release the target (and leave the register)."""


_OPEN: list[OpenRun] = []


def add(run: OpenRun) -> None:
    """Register ``run`` as open (until :func:`discard`)."""
    _OPEN.append(run)


def discard(run: OpenRun) -> None:
    """Forget ``run`` (closed or committed); a run not registered is ignored."""
    if run in _OPEN:
        _OPEN.remove(run)


def forget_all() -> list[OpenRun]:
    """Empty the register and return what it held: a forked child (a process pool's worker)
    owns none of its parent's runs."""
    runs = list(_OPEN)
    _OPEN.clear()
    return runs


def open_targets(thread_id: int | None = None) -> list[Path]:
    """The ``--out`` targets of the uncommitted runs of this thread (or of ``thread_id``)."""
    me = threading.get_ident() if thread_id is None else thread_id
    return [r.out for r in _OPEN if r.thread == me]


def close_all(thread_id: int | None = None) -> None:
    """Abandon every uncommitted run of this thread, or of thread ``thread_id``
    (called by :func:`bondid.cli.run`, and by the interrupt watchdog for the run it ends;
    runs in other threads, e.g. Dask workers, are left alone)."""
    me = threading.get_ident() if thread_id is None else thread_id
    for r in list(_OPEN):
        if r.thread == me:
            r.close()
