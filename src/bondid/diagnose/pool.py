"""Worker processes of a diagnosis (:class:`WorkerPool`), or in-process execution."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

from ..blas import THREAD_VARS
from ..interrupt import ignore_in_worker, kill_workers, signals_deferred, spawn_context
from ..threads import THREADS_VAR


class WorkerPool:
    """Worker processes (spawned with single-threaded BLAS and one bondid thread each: the
    workers already share the cores) or in-process execution."""

    def __init__(self, workers: int):
        self.workers = workers
        self.ex = None
        if workers > 1:
            from concurrent.futures import ProcessPoolExecutor

            single = (*THREAD_VARS, THREADS_VAR)
            saved = {k: os.environ.get(k) for k in single}
            for k in single:
                os.environ[k] = "1"
            try:
                # a Ctrl-C while the workers start is delivered when they are up (and then
                # stops them here); the executor's thread, started inside, blocks both signals
                with signals_deferred():
                    self.ex = ProcessPoolExecutor(
                        workers, mp_context=spawn_context(), initializer=ignore_in_worker
                    )
                    self.ex.submit(int, 0).result()  # start the workers with this environment
                    for _ in range(workers - 1):
                        self.ex.submit(time.sleep, 0.0)
            except BaseException:  # Ctrl-C while the workers start: stop them now
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
        """Do jobs run in worker processes (else here, at submission)?"""
        return self.ex is not None

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        if self.ex is not None:
            return self.ex.submit(fn, *args)
        from concurrent.futures import Future

        fut: Future[Any] = Future()
        fut.set_result(fn(*args))
        return fut

    def close(self) -> None:
        if self.ex is not None:
            self.ex.shutdown(cancel_futures=True)

    def kill(self) -> None:
        """Stop now (Ctrl-C, an error): cancel the queue and terminate the workers."""
        kill_workers(self.ex)
        self.ex = None
