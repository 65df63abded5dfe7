"""Where a diagnosis's refits run: local worker processes, this process, or a Dask cluster
(:func:`open_pool`).

A diagnosis's candidates are independent until the rule compares them, so their screenings
and refits are tasks on a pool. Three pools have the same face (``submit``, ``first_done``,
``cancel``, ``close``, ``kill``):

* :class:`LocalPool` — ``workers`` spawned processes (single-threaded BLAS and one bondid
  thread each: the workers already share the cores), the default;
* in this process (``workers = 1``): a task runs when it is submitted;
* :class:`DaskPool` — the workers of a Dask cluster (``--scheduler tcp://HOST:PORT``, the
  engine of ``bondid.fleet``), so that a user with a cluster gets the answer in the time of
  the slowest candidate. Dask is an optional dependency (``pip install bondid[fleet]``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Future, wait
from typing import Any

from ..blas import THREAD_VARS
from ..exceptions import ConfigError
from ..interrupt import ignore_in_worker, kill_workers, signals_deferred, spawn_context
from ..threads import THREADS_VAR

#: the cancellation level of this process's tasks (a worker's, shared with its parent)
_LEVEL: Any = None


def _init_worker(level: Any) -> None:
    """Pool initializer: the interrupt handling of every worker, and the shared level."""
    global _LEVEL
    ignore_in_worker()
    _LEVEL = level


def cancelled(token: int) -> bool:
    """Has the work of ``token`` been cancelled (:meth:`LocalPool.cancel_level`)? Always False
    for token 0 and where no level is shared (this process, a Dask worker)."""
    return token > 0 and _LEVEL is not None and _LEVEL.value >= token


class LocalPool:
    """Worker processes, or in-process execution with ``workers = 1``.

    Work that is no longer needed once a step is decided is cancelled through one shared
    integer: tasks carry a token (:meth:`token`), and setting the level to a token
    (:meth:`cancel_level`) tells every task of that token or lower to stop at its next
    solver iteration (:func:`cancelled`), so the workers are free for what comes next.
    """

    def __init__(self, workers: int):
        self.workers = max(1, int(workers))
        self.ex: Any = None
        self._tokens = 0
        self._level: Any = None
        if self.workers > 1:
            self._start()

    def token(self) -> int:
        """A new cancellation token (0 without worker processes: nothing runs beside)."""
        if self.ex is None:
            return 0
        self._tokens += 1
        return self._tokens

    def cancel_level(self, token: int) -> None:
        """Stop every running task of ``token`` or lower (module docstring)."""
        if self._level is not None and token > 0:
            self._level.value = max(int(self._level.value), int(token))

    def _start(self) -> None:
        from concurrent.futures import ProcessPoolExecutor

        single = (*THREAD_VARS, THREADS_VAR)
        saved = {k: os.environ.get(k) for k in single}
        for k in single:
            os.environ[k] = "1"
        try:
            # a Ctrl-C while the workers start is delivered when they are up (and then stops
            # them here); the executor's thread, started inside, blocks both signals
            with signals_deferred():
                ctx = spawn_context()
                self._level = ctx.Value("q", 0, lock=False)
                self.ex = ProcessPoolExecutor(
                    self.workers, mp_context=ctx, initializer=_init_worker,
                    initargs=(self._level,),
                )  # fmt: skip
                self.ex.submit(int, 0).result()  # the workers start with this environment
                for _ in range(self.workers - 1):
                    self.ex.submit(time.sleep, 0.0)
        except BaseException:
            kill_workers(self.ex)
            raise
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v

    @property
    def parallel(self) -> bool:
        """Do tasks run beside this process (else at submission)?"""
        return self.ex is not None

    def submit(self, fn: Callable[..., Any], *args: Any) -> Future[Any]:
        if self.ex is not None:
            return self.ex.submit(fn, *args)
        fut: Future[Any] = Future()
        fut.set_result(fn(*args))
        return fut

    def first_done(self, futures: Iterable[Any]) -> Any:
        """One finished future of ``futures`` (waits for the first)."""
        done, _ = wait(list(futures), return_when=FIRST_COMPLETED)
        return next(iter(done))

    def cancel(self, futures: Iterable[Any]) -> None:
        for f in futures:
            f.cancel()

    def close(self) -> None:
        if self.ex is not None:
            self.ex.shutdown(cancel_futures=True)

    def kill(self) -> None:
        """Stop now (Ctrl-C, an error): cancel the queue and terminate the workers."""
        kill_workers(self.ex)
        self.ex = None


class DaskPool:
    """The workers of a Dask cluster (see the module docstring)."""

    def __init__(self, address: str):
        from contextlib import ExitStack

        try:
            from ..cluster.client import open_client
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ConfigError(
                f"--scheduler {address}: Dask is not installed ({exc}); "
                "install it with: pip install 'bondid[fleet]'"
            ) from None
        self._stack = ExitStack()
        try:
            self.client = self._stack.enter_context(open_client(address, 1))
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ConfigError(
                f"--scheduler {address}: Dask is not installed ({exc}); "
                "install it with: pip install 'bondid[fleet]'"
            ) from None
        self.workers = max(1, sum(self.client.nthreads().values()))

    parallel = True

    def token(self) -> int:
        return 0  # a Dask worker cannot see this process's level: cancel() drops queued work

    def cancel_level(self, token: int) -> None:
        return None

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        # pure=False: two equal tasks (e.g. the same start twice) are run, not deduplicated
        return self.client.submit(fn, *args, pure=False)

    def first_done(self, futures: Iterable[Any]) -> Any:
        from dask.distributed import wait as dask_wait

        done, _ = dask_wait(list(futures), return_when="FIRST_COMPLETED")
        return next(iter(done))

    def cancel(self, futures: Iterable[Any]) -> None:
        fs = list(futures)
        if fs:
            self.client.cancel(fs)

    def close(self) -> None:
        self._stack.close()

    def kill(self) -> None:
        self._stack.close()


Pool = LocalPool | DaskPool


def open_pool(workers: int, scheduler: str | None = None) -> Pool:
    """The pool of a diagnosis: the Dask cluster at ``scheduler`` when given, else
    ``workers`` local processes (1: this process)."""
    if scheduler:
        return DaskPool(scheduler)
    return LocalPool(workers)


def as_completed(pool: Pool, futures: Iterable[Any]) -> Iterable[Any]:
    """``futures`` in the order they finish, on any pool."""
    left = list(futures)
    while left:
        f = pool.first_done(left)
        left.remove(f)
        yield f
