"""A signal always ends a command: the pool context does not wait for killed workers, forked
workers come up with the signals unblocked, the watchdog ends a run whose clean-up hangs, and
``exit_process`` does not wait for the interpreter's exit joins."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest

from bondid.interrupt import (
    exit_process,
    ignore_in_worker,
    signals_deferred,
    terminate_on_interrupt,
)

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="signals and fork")


def _blocked() -> set[int]:
    return {int(s) for s in signal.pthread_sigmask(signal.SIG_BLOCK, [])}


class _Executor:
    """Records how it is shut down (the part of ProcessPoolExecutor the context uses)."""

    def __init__(self) -> None:
        self._processes: dict = {}
        self.calls: list[dict] = []

    def shutdown(self, **kw: object) -> None:
        self.calls.append(kw)


def test_the_pool_context_waits_only_on_a_normal_exit() -> None:
    ex = _Executor()
    with terminate_on_interrupt(ex):
        pass
    assert ex.calls == [{"wait": True}]
    ex = _Executor()
    with pytest.raises(KeyboardInterrupt), terminate_on_interrupt(ex):
        raise KeyboardInterrupt
    assert ex.calls and all(c.get("wait") is False for c in ex.calls)


def test_workers_forked_inside_the_deferral_have_the_signals_unblocked() -> None:
    """Known answer: a fork inherits the parent's signal mask; blocked there, SIGTERM would
    not stop a worker (nor the executor's own terminate)."""
    with ProcessPoolExecutor(2, initializer=ignore_in_worker) as pool:
        with signals_deferred():
            assert {int(signal.SIGINT), int(signal.SIGTERM)} <= _blocked()
            futs = [pool.submit(_blocked) for _ in range(2)]
        masks = [f.result(timeout=60) for f in futs]
    for m in masks:
        assert int(signal.SIGINT) not in m and int(signal.SIGTERM) not in m


def test_exit_process_raises_systemexit_for_other_codes() -> None:
    for code in (0, 1, 2):
        with pytest.raises(SystemExit) as info:
            exit_process(code)
        assert info.value.code == code


def _script(tmp_path: Path, body: str) -> subprocess.Popen:
    path = tmp_path / "run.py"
    path.write_text(textwrap.dedent(body))
    return subprocess.Popen(
        [sys.executable, str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, cwd=tmp_path, env=dict(os.environ, PYTHONUNBUFFERED="1"),
    )  # fmt: skip


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_exit_process_does_not_wait_for_threads_after_an_interrupt(tmp_path) -> None:
    """A non-daemon thread would hold a normal exit for 60 s; code 130 ends at once."""
    p = _script(
        tmp_path,
        """
        import threading, time
        from bondid.interrupt import exit_process
        threading.Thread(target=time.sleep, args=(60,)).start()
        exit_process(130)
    """,
    )
    _, err = p.communicate(timeout=30)
    assert p.returncode == 130, err


def test_the_watchdog_ends_a_run_whose_clean_up_hangs(tmp_path) -> None:
    """Known answer: a body that, on Ctrl-C, blocks for good in its clean-up. The watchdog
    ends the process with 130 after its grace time, says so with the stacks, stops the
    child process and removes the run's unfinished results."""
    p = _script(
        tmp_path,
        """
        import multiprocessing, threading, time
        from bondid import cli, interrupt
        from bondid.interrupt import exit_process
        from bondid.results import open_results

        interrupt.GRACE_S = 1.0

        def body():
            child = multiprocessing.get_context("fork").Process(target=time.sleep, args=(60,))
            child.start()
            res = open_results("out", "fit", [])
            (res.tmp / "part.txt").write_text("unfinished")
            lock = threading.Lock()
            lock.acquire()
            try:  # (the Ctrl-C is sent once "ready" is read: it lands inside the try)
                print("ready", child.pid, flush=True)
                time.sleep(60)
            except KeyboardInterrupt:
                lock.acquire()  # a clean-up that never ends

        exit_process(cli.run(body))
    """,
    )
    assert p.stdout is not None
    line = p.stdout.readline().split()
    assert line and line[0] == "ready", p.stderr.read() if p.stderr else ""
    child = int(line[1])
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 130, err
    assert "did not stop within" in err and "most recent call first" in err
    t0 = time.monotonic()
    while _alive(child) and time.monotonic() - t0 < 5:
        time.sleep(0.05)
    assert not _alive(child)
    assert not (tmp_path / "out").exists()
    assert not [n for n in os.listdir(tmp_path) if ".bondid-" in n]


def test_a_run_that_stops_in_time_is_not_touched_by_the_watchdog(tmp_path) -> None:
    p = _script(
        tmp_path,
        """
        import time
        from bondid import cli, interrupt
        from bondid.interrupt import exit_process

        interrupt.GRACE_S = 1.0

        def body():
            print("ready", flush=True)
            time.sleep(60)

        code = cli.run(body)
        time.sleep(2.0)  # past the grace time: the watchdog was disarmed by the return
        print("after", code, flush=True)
        exit_process(code)
    """,
    )
    assert p.stdout is not None
    assert p.stdout.readline().strip() == "ready"
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=30)
    assert p.returncode == 130, err
    assert "after 130" in out and "did not stop" not in err


@pytest.mark.parametrize("method", ["fork", "spawn"])
def test_a_pool_worker_ends_when_its_parent_is_killed(tmp_path, method) -> None:
    """Known answer: the parent dies at once (``os._exit``, as under SIGKILL) while its pool
    worker computes; the worker (its initializer :func:`ignore_in_worker`) ends by itself.
    Reference: a process of the same script without the initializer outlives the parent."""
    p = _script(
        tmp_path,
        f"""
        import multiprocessing as mp, os, time
        from concurrent.futures import ProcessPoolExecutor
        from bondid.interrupt import ignore_in_worker

        if __name__ == "__main__":
            ctx = mp.get_context({method!r})
            pool = ProcessPoolExecutor(1, mp_context=ctx, initializer=ignore_in_worker)
            pool.submit(time.sleep, 60)
            plain = ctx.Process(target=time.sleep, args=(60,))
            plain.start()
            while not pool._processes:
                time.sleep(0.01)
            time.sleep(1.0)  # the worker is at work
            with open("pids.txt", "w") as f:  # (a file: the orphans keep the pipes open)
                print(*pool._processes, plain.pid, file=f, flush=True)
            os._exit(0)
    """,
    )
    assert p.wait(timeout=120) == 0
    worker, plain = (int(w) for w in (tmp_path / "pids.txt").read_text().split())
    try:
        t0 = time.monotonic()
        while _alive(worker) and time.monotonic() - t0 < 30:
            time.sleep(0.1)
        assert not _alive(worker)
        assert _alive(plain)
    finally:
        for pid in (worker, plain):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
