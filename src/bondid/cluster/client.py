"""The Dask client of a fleet or a diagnosis: a local cluster of worker processes, or the
user's cluster.

``dask.distributed`` is imported here, lazily. Worker processes started by a Dask nanny get
single-threaded BLAS from Dask's own ``distributed.nanny.pre-spawn-environ`` setting (the
``*_NUM_THREADS`` variables = 1); the command also sets them before NumPy is imported
(:mod:`bondid.blas`), so local workers inherit them either way.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import signal
import threading
import warnings
from collections.abc import Iterator
from multiprocessing import resource_tracker
from typing import Any

from .. import interrupt
from ..exceptions import ConfigError
from .worker_stderr import relayed_stderr

#: environment variable naming the scheduler of an existing cluster (Dask's own name)
SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"
CONNECT_TIMEOUT_S = 20


def scheduler_address(option: str | None) -> str | None:
    """``--scheduler`` if given, else ``$DASK_SCHEDULER_ADDRESS``, else None (local cluster)."""
    return option or os.environ.get(SCHEDULER_ENV) or None


#: what to install when Dask is missing (it is the optional extra ``bondid[fleet]``)
INSTALL_HINT = "pip install 'bondid[fleet]'"


def require_dask() -> Any:
    """The ``dask.distributed`` module.

    Raises:
        DependencyError: Dask is not installed (one line saying what to install).
    """
    from ..exceptions import DependencyError

    try:
        import dask.distributed
    except ImportError:
        raise DependencyError(
            "bondid.fleet and --scheduler need Dask (dask[distributed]), which is not installed:"
            f" {INSTALL_HINT}"
        ) from None
    return dask.distributed


@contextlib.contextmanager
def open_client(address: str | None, workers: int) -> Iterator[Any]:
    """A connected ``dask.distributed.Client`` (closed, with any local cluster, on exit).

    Dask's log records go to stderr one line each (:func:`one_line_logs`). On an interrupt
    (or any error) the local cluster's worker processes are killed at once, before the
    cluster is closed, so that a Ctrl-C ends the run within a second and leaves no process
    behind; the same when the interrupt lands while the cluster starts.

    Args:
        address: ``tcp://HOST:PORT`` of an existing scheduler, or None for a local cluster.
        workers: worker processes of the local cluster (one thread each).

    Raises:
        ConfigError: the scheduler cannot be reached (names the address).
    """
    Client = require_dask().Client

    interrupt.check()  # a Ctrl-C that a library swallowed in its import (trimesh does)
    with one_line_logs():
        if address is not None:
            try:
                client = Client(address, timeout=CONNECT_TIMEOUT_S)
            except (OSError, TimeoutError, ValueError) as exc:
                raise ConfigError(
                    f"--scheduler {address}: cannot connect to a Dask scheduler there ({exc});"
                    " give tcp://HOST:PORT of a running scheduler"
                ) from None
            with client:
                interrupt.check()
                yield client
            return
        with relayed_stderr():
            yield from _local_client(Client, workers)


def _local_client(Client: Any, workers: int) -> Iterator[Any]:
    """The body of :func:`open_client` for a local cluster (a generator of one client)."""
    before = set(multiprocessing.active_children())
    cluster = None
    try:
        cluster = _local_cluster(workers)
        interrupt.check()  # a Ctrl-C that a library swallowed while the cluster started
        with Client(cluster) as client:
            yield client
    except BaseException:
        _kill_new_children(before)
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=CLOSE_TIMEOUT_S)
        raise
    cluster.close()


#: seconds a local cluster may take to close after its workers were killed
CLOSE_TIMEOUT_S = 1


#: seconds between the checks for an interrupt while the local cluster starts
START_POLL_S = 0.1


def _local_cluster(workers: int) -> Any:
    """Start a local cluster in a helper thread with SIGINT blocked, while this thread
    waits in short polls for it (or for an interrupt).

    The cluster's event-loop thread, and the worker processes it spawns, inherit the
    blocked SIGINT: a Ctrl-C, which the terminal sends to the whole process group, then
    never reaches a worker in the middle of its start-up (it would print a traceback there);
    this process stops them (:func:`_kill_new_children`). And the Ctrl-C is seen here within
    :data:`START_POLL_S`, not when the cluster is up seconds later.
    """
    LocalCluster = require_dask().LocalCluster

    box: dict[str, Any] = {}
    # The first semaphore of the cluster starts multiprocessing's resource tracker, and that
    # start ends by UNBLOCKING SIGINT in the calling thread instead of restoring its mask:
    # done in the cluster's event-loop thread, it would undo the mask for every worker
    # spawned from there. Started here, in a thread that does not block SIGINT anyway.
    resource_tracker.ensure_running()

    def start() -> None:
        try:
            box["cluster"] = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
        except BaseException as exc:  # handed to the waiting thread
            box["error"] = exc

    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        t = threading.Thread(target=start, name="bondid-cluster-start", daemon=True)
        t.start()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
    try:
        with warnings.catch_warnings():  # the scheduler's port taken by another cluster
            warnings.filterwarnings("ignore", message="Port .* is already in use")
            while t.is_alive():
                interrupt.check()
                t.join(START_POLL_S)
    except BaseException:
        _close_when_started(t, box)
        raise
    if "error" in box:
        raise box["error"]
    return box["cluster"]


def _close_when_started(t: threading.Thread, box: dict[str, Any]) -> None:
    """After an interrupt during the start: close the cluster once its start returns (in
    the background: this process is stopping), its worker processes being killed."""

    def close() -> None:
        t.join()
        cluster = box.get("cluster")
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=CLOSE_TIMEOUT_S)

    threading.Thread(target=close, name="bondid-cluster-close", daemon=True).start()


def _kill_new_children(before: set[Any]) -> None:
    """SIGKILL the processes this process started since ``before`` (the local cluster's
    workers; a machine cut short is run again by the next fleet run) and reap them."""
    procs = [p for p in multiprocessing.active_children() if p not in before]
    for p in procs:
        with contextlib.suppress(Exception):
            p.kill()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(CLOSE_TIMEOUT_S)


class _OneLine(logging.Filter):
    """A log record of Dask with its traceback folded into one line."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and record.exc_info[1] is not None:
            exc = record.exc_info[1]
            text = " ".join(f"{record.getMessage()} ({type(exc).__name__}: {exc})".split())
            record.msg, record.args = text, None
            record.exc_info = record.exc_text = None
        elif "\n" in str(record.msg):
            record.msg, record.args = " ".join(record.getMessage().split()), None
        record.stack_info = None
        return True


@contextlib.contextmanager
def one_line_logs() -> Iterator[None]:
    """Context: every handler of Dask's loggers (and the root logger's) writes a record in
    one line, a traceback folded into it (a worker killed mid-task makes Dask log a
    ``CommClosedError`` with its whole traceback)."""
    flt = _OneLine()
    handlers = set()
    for name in ("", "distributed", "dask"):
        handlers |= set(logging.getLogger(name).handlers)
    for h in handlers:
        h.addFilter(flt)
    try:
        yield
    finally:
        for h in handlers:
            h.removeFilter(flt)


def worker_threads(client: Any) -> int:
    """Threads over all workers the scheduler knows now (at least 1)."""
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # informational only (progress display)
        return 1
