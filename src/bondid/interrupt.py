"""Ctrl-C that stops a run: a recorded interrupt, checks for it, and worker clean-up.

CasADi calls back into Python during an IPOPT solve; a ``KeyboardInterrupt`` raised inside such
a callback is caught by CasADi (it prints a warning and the solve carries on). So the command
line installs :func:`install`, whose SIGINT handler *records* the interrupt before raising;
the fit's per-iteration callback asks :func:`requested` and stops IPOPT, and the code after a
solve calls :func:`check`, which raises ``KeyboardInterrupt`` again. Worker processes ignore
SIGINT (:func:`ignore_in_worker`, a pool initializer) and are terminated by the parent
(:func:`kill_workers`, :func:`terminate_on_interrupt`), so a single Ctrl-C suffices and ends
the run within a second or two.

SIGTERM (``kill``, a batch scheduler's time limit) is handled the same way: without it the
process would die at once and leave its worker processes running as orphans (seen: a killed
``bondid.diagnose`` left two workers computing for minutes). :func:`signal_number` tells which
of the two arrived, so the command line exits 130 or 143 as shells report them.

A last resort guards the promise that one signal ends the run: once one arrived, a watchdog
thread waits :data:`GRACE_S` seconds for :func:`restore`; if the run is still going (a clean-up
stuck in a lock or in a pool's shutdown), it writes the stacks of all threads to stderr, stops
the worker processes and abandons the run's unfinished results, and ends the process with the
signal's exit code. :func:`exit_process` ends a command-line process without the interpreter's
own exit joins (threads, child processes) after an interrupt.

Nothing happens on import; :func:`install` changes the process's SIGINT and SIGTERM handlers
(and starts the watchdog thread, idle until a signal) and returns the previous ones for
:func:`restore`.
"""

from __future__ import annotations

import contextlib
import faulthandler
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from multiprocessing.context import SpawnContext, SpawnProcess
from typing import Any

from .open_runs import close_all

_FLAG = threading.Event()
#: the signals :func:`install` handles, and the last one that arrived
_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_LAST = [int(signal.SIGINT)]


#: the process that installed the handlers: a forked worker inherits them, and there the
#: signal must do what it does by default (its parent terminates it with SIGTERM)
_OWNER = [0]

#: seconds a run may take to stop after its first SIGINT/SIGTERM before the watchdog ends it
#: (a normal stop takes a second or two: workers get 1 s to end on SIGTERM, 1 s on SIGKILL)
GRACE_S = 15.0


class _Watchdog:
    """One run's watchdog: a daemon thread, woken by the first signal or by :meth:`disarm`."""

    def __init__(self, grace: float):
        self.grace = grace
        self.wake = threading.Event()
        self.disarmed = threading.Event()
        self.thread_id = threading.get_ident()
        threading.Thread(target=self._watch, name="bondid-interrupt-watchdog", daemon=True).start()

    def disarm(self) -> None:
        self.disarmed.set()
        self.wake.set()

    def _watch(self) -> None:
        self.wake.wait()
        if self.disarmed.wait(self.grace):
            return
        code = 128 + _LAST[0]
        with contextlib.suppress(Exception):
            print(
                f"bondid: the run did not stop within {self.grace:g} s of the signal; it is"
                " ended now (stacks of its threads follow; please report them)",
                file=sys.stderr,
                flush=True,
            )
            faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        _stop(multiprocessing.active_children())
        with contextlib.suppress(Exception):
            close_all(self.thread_id)
        exit_process(code)


_WATCHDOG: list[_Watchdog | None] = [None]

#: depth of :func:`signals_deferred` blocks in the main thread, and whether a signal that
#: arrived inside one is waiting to be raised as it ends
_DEFER = [0]
_HELD = [False]


def _handler(signum: int, frame: Any) -> None:
    if os.getpid() != _OWNER[0]:
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    if not _FLAG.is_set():
        _LAST[0] = int(signum)
    _FLAG.set()
    dog = _WATCHDOG[0]
    if dog is not None:
        dog.wake.set()
    if _DEFER[0] > 0:  # inside signals_deferred: raised when the block ends
        _HELD[0] = True
        return
    raise KeyboardInterrupt


def stop_quietly_until_run() -> None:
    """For a command-line process, first thing (before its heavy imports): a SIGINT or
    SIGTERM that arrives before :func:`install` ends the process at once with
    ``interrupted`` / ``terminated`` and exit code 130 / 143, as a run would (nothing is
    written yet), instead of a ``KeyboardInterrupt`` traceback from inside an import."""

    def early(signum: int, frame: Any) -> None:
        word = b"terminated\n" if signum == signal.SIGTERM else b"interrupted\n"
        with contextlib.suppress(OSError):
            os.write(2, word)
        os._exit(128 + int(signum))

    for sig in _SIGNALS:
        signal.signal(sig, early)


def install(grace: float | None = None) -> Any:
    """Record every SIGINT and SIGTERM (then raise ``KeyboardInterrupt`` as Python does on
    SIGINT) and arm the watchdog (``grace`` s, default :data:`GRACE_S`, see the module);
    returns the previous handlers. Does nothing outside the main thread (returns None)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    _FLAG.clear()
    _LAST[0] = int(signal.SIGINT)
    _OWNER[0] = os.getpid()
    if _WATCHDOG[0] is not None:
        _WATCHDOG[0].disarm()
    _WATCHDOG[0] = _Watchdog(GRACE_S if grace is None else grace)
    return {sig: signal.signal(sig, _handler) for sig in _SIGNALS}


def restore(previous: Any) -> None:
    """Put back the handlers :func:`install` returned (None: leave them), disarm the
    watchdog and forget the run's interrupt (:func:`check` and :func:`requested` then see
    none: code that runs later in the same process is not stopped by it)."""
    if previous is not None and threading.current_thread() is threading.main_thread():
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        _FLAG.clear()
        _HELD[0] = False
        dog, _WATCHDOG[0] = _WATCHDOG[0], None
        if dog is not None:
            dog.disarm()


def exit_process(code: int) -> None:
    """End a command-line process with ``code``. After an interrupt (codes 130 and 143) the
    streams are flushed and the process ends at once (``os._exit``): the run has already
    stopped its workers and abandoned its results, and the interpreter's exit would
    otherwise join threads and child processes that a stop cut short (a hang seen once in
    CI). Other codes exit normally (``SystemExit``)."""
    if code in (128 + signal.SIGINT, 128 + signal.SIGTERM):
        _release_semaphores()
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(code)
    raise SystemExit(code)


def _release_semaphores() -> None:
    """Unlink the named semaphores this process created for spawned processes (a Dask
    cluster's, a pool's), as the interpreter's exit would: after ``os._exit`` the resource
    tracker otherwise unlinks them itself and warns of "leaked semaphore objects"."""
    with contextlib.suppress(Exception):
        from multiprocessing import synchronize, util

        registry = getattr(util, "_finalizer_registry", {})
        for key, fin in list(registry.items()):
            if getattr(fin, "_callback", None) is getattr(synchronize.SemLock, "_cleanup", 0):
                fin()
                registry.pop(key, None)


def requested() -> bool:
    """True once a SIGINT or SIGTERM arrived since :func:`install`."""
    return _FLAG.is_set()


def signal_number() -> int:
    """The signal that stopped the run (SIGINT when none was recorded: a plain
    ``KeyboardInterrupt``)."""
    return _LAST[0] if _FLAG.is_set() else int(signal.SIGINT)


def check() -> None:
    """Raise ``KeyboardInterrupt`` if an interrupt was recorded (e.g. one CasADi swallowed)."""
    if _FLAG.is_set():
        raise KeyboardInterrupt


def ignore_in_worker(*_: Any) -> None:
    """Pool initializer: the worker ignores SIGINT (its parent stops it) and dies quietly on
    SIGTERM (a forked worker would otherwise keep the parent's handler), both unblocked (a
    worker started inside :func:`signals_deferred`, forked or spawned, inherits the block;
    a SIGINT held since then is discarded, a SIGTERM held since then ends it now).

    And the worker ends once its parent is gone (:func:`_end_with_parent`): a parent killed
    with SIGKILL cannot stop its workers, which went on computing as orphans (seen in CI:
    a killed fit's worker still there a quarter of an hour later)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, set(_SIGNALS))
    _end_with_parent()


#: seconds between a worker's checks that its parent still runs
PARENT_POLL_S = 1.0
_WATCHED = [0]  # the process whose parent watcher runs (a fork copies the list)


def _end_with_parent() -> None:
    """Start (once per process) a daemon thread that ends this process (``os._exit``, exit
    code 143 as for SIGTERM) within :data:`PARENT_POLL_S` of its parent's end, seen as a
    change of ``os.getppid()`` (the orphan is adopted by another process)."""
    if _WATCHED[0] == os.getpid():
        return
    _WATCHED[0] = os.getpid()
    parent = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent:
                os._exit(128 + int(signal.SIGTERM))

    threading.Thread(target=watch, name="bondid-parent-watch", daemon=True).start()


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Context: a SIGINT or SIGTERM that arrives inside is raised (``KeyboardInterrupt``) when
    the block ends: never lost, never raised in the middle (e.g. between a worker's start
    and the executor's record of it, or inside a commit of results).

    Two layers. The handler :func:`install` puts in place records a signal that arrives
    inside and returns; the block's end raises it. This holds whichever thread the kernel
    hands a process-directed signal to (Python runs the handler in the main thread anyway).
    And both signals are blocked in this thread for the block (any thread): a process
    started here inherits the mask, so a spawned worker starts with them held until its
    initializer (:func:`ignore_in_worker`) ignores SIGINT and unblocks them (no
    ``KeyboardInterrupt`` in its bootstrap). Threads started inside inherit the block for
    good, which is harmless: signals are handled in the main thread only."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, set(_SIGNALS))
    main = threading.current_thread() is threading.main_thread()
    if main:
        _DEFER[0] += 1
    held = False
    try:
        yield
    finally:
        if main:
            _DEFER[0] -= 1
            if _DEFER[0] == 0:
                held, _HELD[0] = _HELD[0], False
        # (a signal pending at the OS level is handled now, by a handler that raises)
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
    if held:
        raise KeyboardInterrupt


def _ensure_resource_tracker() -> None:
    """Start ``multiprocessing``'s resource tracker now if it is not running: starting it
    unblocks SIGINT and SIGTERM in the calling thread (measured), which inside a
    :func:`signals_deferred` block would let a worker start with them unblocked."""
    with contextlib.suppress(Exception):
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()


class _QuietStartProcess(SpawnProcess):
    """A spawned process that starts with SIGINT and SIGTERM blocked (see
    :func:`spawn_context`)."""

    def start(self) -> None:
        _ensure_resource_tracker()
        try:
            with signals_deferred():
                super().start()
        except BaseException:
            # a signal during the start, raised as it ends (here, or at the end of an outer
            # block): the executor has not recorded this process, so nobody else stops it
            _stop([self])
            raise


class _QuietStartContext(SpawnContext):
    Process = _QuietStartProcess


def spawn_context() -> SpawnContext:
    """A ``multiprocessing`` "spawn" context whose processes start with SIGINT and SIGTERM
    blocked.

    :func:`ignore_in_worker` runs only once a spawned worker has imported what it needs; a
    Ctrl-C that reaches the process group while a worker is still starting up would otherwise
    raise ``KeyboardInterrupt`` in its bootstrap and print a traceback (seen under load). A
    signal mask survives ``fork`` and ``exec`` and Python's start-up leaves it alone
    (measured), so the parent starts each process inside :func:`signals_deferred`: the
    worker holds a SIGINT until its initializer ignores it (discarding it), and a SIGTERM
    from the parent until the initializer unblocks it (then it ends; a worker that never
    gets there is killed one second later, :func:`kill_workers`).

    (Before, the parent *ignored* SIGINT while it started a process, as an ignored signal
    also survives ``exec``. A process-directed SIGINT that arrived in that moment was taken
    by another thread of the parent, which did not block it, and discarded: a diagnosis
    went on after its Ctrl-C, seen in CI.)
    """
    return _QuietStartContext()


def kill_workers(executor: Any, timeout: float = 1.0) -> None:
    """Cancel pending work and terminate the worker processes of a ``ProcessPoolExecutor``
    now (SIGTERM, then SIGKILL after ``timeout`` s) instead of waiting for running tasks."""
    if executor is None:
        return
    procs = list((getattr(executor, "_processes", None) or {}).values())
    with contextlib.suppress(Exception):
        executor.shutdown(wait=False, cancel_futures=True)
    known = {p.pid for p in procs}
    # a worker whose start was interrupted is not (yet) in the executor's table
    procs += [
        c
        for c in multiprocessing.active_children()
        if isinstance(c, _QuietStartProcess) and c.pid not in known
    ]
    _stop(procs, timeout)


def _stop(procs: list[Any], timeout: float = 1.0) -> None:
    """Terminate ``procs`` (SIGTERM, then SIGKILL after ``timeout`` s) and reap them."""
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(timeout)
            if p.is_alive():
                p.kill()
                p.join(timeout)


@contextlib.contextmanager
def terminate_on_interrupt(executor: Any) -> Iterator[Any]:
    """Context owning a ``ProcessPoolExecutor``: on any exception (Ctrl-C included) its
    workers are killed at once and nothing waits for them (no ``shutdown(wait=True)``, which
    can block for good on a pool whose workers were killed); on a normal exit it is shut down
    as ``with executor:`` would. Submit inside :func:`signals_deferred` so that a worker
    cannot be started but not yet recorded when a Ctrl-C lands."""
    try:
        yield executor
    except BaseException:
        kill_workers(executor)
        raise
    executor.shutdown(wait=True)
