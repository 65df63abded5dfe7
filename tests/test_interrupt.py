"""Worker processes and Ctrl-C: spawned workers start with SIGINT held (blocked) until their
initializer ignores it; a signal during a start is never lost."""

from __future__ import annotations

import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

import pytest

from bondid.interrupt import ignore_in_worker, spawn_context


def _sigint_state() -> str:
    blocked = signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, [])
    ignored = signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    return "ignored" if ignored else "blocked" if blocked else "handled"


def test_spawned_workers_hold_sigint_from_their_start() -> None:
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # as the CLI has it
    try:
        with ProcessPoolExecutor(1, mp_context=spawn_context()) as ex:  # no initializer
            assert ex.submit(_sigint_state).result(timeout=120) == "blocked"
        with ProcessPoolExecutor(1, mp_context=spawn_context(), initializer=ignore_in_worker) as ex:
            assert ex.submit(_sigint_state).result(timeout=120) == "ignored"
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # untouched
        assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])
    finally:
        signal.signal(signal.SIGINT, previous)


def _ctrl_c_at_start(context: object) -> int:
    """Start a one-worker pool, send SIGINT to the worker while it boots (as a Ctrl-C sent
    to the process group would), and return its answer to ``7 * 6``."""
    with ProcessPoolExecutor(1, mp_context=context, initializer=ignore_in_worker) as ex:
        fut = ex.submit(int.__mul__, 7, 6)
        for pid in list(ex._processes):  # (the worker exists once submit returns)
            os.kill(pid, signal.SIGINT)
        return fut.result(timeout=120)


def test_a_ctrl_c_while_a_worker_boots_does_not_break_the_pool() -> None:
    """Known answer, and the reference: a plain spawned worker dies of the same SIGINT (or
    raises ``KeyboardInterrupt`` in its bootstrap) and the pool is broken."""
    import multiprocessing as mp

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        assert _ctrl_c_at_start(spawn_context()) == 42
        with pytest.raises(BrokenProcessPool):
            _ctrl_c_at_start(mp.get_context("spawn"))
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_process_directed_signal_during_a_start_is_not_lost(monkeypatch) -> None:
    """Known answer for a CI failure: a SIGINT sent to the process while a worker started was
    taken by another thread (the kernel hands a process-directed signal to any thread that
    does not block it) while the parent ignored SIGINT for the child's sake, and discarded;
    the diagnosis went on. Now it is recorded and raised as the start ends."""
    from multiprocessing.context import SpawnProcess

    from bondid import interrupt

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals are handled in the main thread only")
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)  # started here: the signals not blocked
    other.start()
    seen: list[str] = []

    def start(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)  # the main thread blocks it: `other` takes it
        t0 = time.monotonic()  # until the handler has run (never, when the signal is lost)
        while not interrupt.requested() and time.monotonic() - t0 < 10.0:
            time.sleep(0.01)
        seen.append("started")

    monkeypatch.setattr(SpawnProcess, "start", start)
    previous = interrupt.install(grace=120)
    try:
        with pytest.raises(KeyboardInterrupt):
            interrupt._QuietStartProcess().start()
        assert seen == ["started"] and interrupt.requested()
    finally:
        interrupt.restore(previous)
        stop.set()
        other.join()
    assert not interrupt.requested()  # the run's interrupt ends with it (it stopped a later
    # test's solve in this process once)
    interrupt.check()


def test_a_sigint_while_a_worker_starts_reaches_the_handler_after_it(monkeypatch) -> None:
    """Known answer: a SIGINT that arrives while a process starts (the main thread blocks it
    then, for the child's sake) is delivered to the parent's handler once the start is done,
    once. Before, it was dropped (seen in CI: a diagnosis that went on after its Ctrl-C)."""
    import threading
    from multiprocessing.context import SpawnProcess

    from bondid.interrupt import _QuietStartProcess

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals are handled in the main thread only")
    seen: list[str] = []

    def start(self) -> None:  # the signal arrives in the middle of the start, at the main
        # thread (as in the commands, where it is the only thread when the workers start; a
        # process-directed kill would go to a thread of the test runner here)
        signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)
        seen.append("started")

    monkeypatch.setattr(SpawnProcess, "start", start)
    previous = signal.signal(signal.SIGINT, lambda *_: seen.append("handled"))
    try:
        _QuietStartProcess().start()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert seen == ["started", "handled"]
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])  # unblocked again


def test_a_sigint_held_before_the_start_is_not_discarded(monkeypatch) -> None:
    """A SIGINT already pending (blocked) when a start begins stays pending through it (an
    earlier design ignored SIGINT for the start, which discards a pending one) and is
    handled after the start."""
    import threading
    from multiprocessing.context import SpawnProcess

    from bondid.interrupt import _QuietStartProcess, signals_deferred

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals are handled in the main thread only")
    seen: list[str] = []
    monkeypatch.setattr(SpawnProcess, "start", lambda self: seen.append("started"))
    previous = signal.signal(signal.SIGINT, lambda *_: seen.append("handled"))
    try:
        with signals_deferred():
            signal.raise_signal(signal.SIGINT)  # held: blocked here
            _QuietStartProcess().start()
            assert seen == ["started"]
    finally:
        signal.signal(signal.SIGINT, previous)
    assert seen == ["started", "handled"]


def _sleep_long() -> None:
    import time

    time.sleep(60)


def test_a_process_whose_start_is_interrupted_is_stopped_not_orphaned(monkeypatch) -> None:
    """Known answer for a CI failure: the Ctrl-C held during a worker's start is raised as the
    start ends, before the executor records the process, so ``kill_workers`` did not reach
    it; it outlived the run and printed a traceback (its parent's semaphores were gone). Now
    the interrupted start stops its own process, and ``kill_workers`` also stops any such
    process the executor does not know."""
    import threading
    from multiprocessing.context import SpawnProcess

    from bondid.interrupt import _QuietStartProcess, kill_workers

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals are handled in the main thread only")
    real_start = SpawnProcess.start
    started: list[SpawnProcess] = []

    def start(self) -> None:  # really start it, with the Ctrl-C arriving meanwhile
        real_start(self)
        started.append(self)
        signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)

    monkeypatch.setattr(SpawnProcess, "start", start)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            _QuietStartProcess(target=_sleep_long).start()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(started) == 1 and not started[0].is_alive()
    assert started[0].exitcode is not None

    # the fallback: a live quiet-start process that an executor does not record
    monkeypatch.setattr(SpawnProcess, "start", real_start)
    orphan = _QuietStartProcess(target=_sleep_long)
    orphan.start()

    class _Executor:  # the part of ProcessPoolExecutor that kill_workers reads
        def __init__(self) -> None:
            self._processes: dict = {}

        def shutdown(self, **_: object) -> None:
            pass

    kill_workers(_Executor(), timeout=5.0)
    assert not orphan.is_alive()
