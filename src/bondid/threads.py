"""Independent NumPy-heavy jobs on threads (the LAPACK/BLAS calls and large array operations
they spend their time in release the GIL, so the cores work side by side).

One pool per process lives across calls: a cost evaluation of a small problem takes about a
millisecond, and starting threads for each call made a diagnosis of 150-frequency data 1.9×
slower than running its jobs in the calling thread (measured on 2 cores). A process
forked after the pool started gets its own pool. Worker processes that already share the cores
among themselves set :data:`THREADS_VAR` to 1.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

T = TypeVar("T")
R = TypeVar("R")

#: environment variable capping bondid's own threads per process (a positive integer)
THREADS_VAR = "BONDID_THREADS"

_lock = threading.Lock()
_pool: tuple[int, int, ThreadPoolExecutor] | None = None  # (pid, workers, pool)


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the platform tells)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # not on Linux
        return max(os.cpu_count() or 1, 1)


def thread_limit() -> int:
    """Threads :func:`thread_map` may use: :func:`available_cores`, capped by
    :data:`THREADS_VAR` when it holds a positive integer (other values are ignored)."""
    cores = available_cores()
    raw = os.environ.get(THREADS_VAR, "")
    try:
        cap = int(raw)
    except ValueError:
        return cores
    return min(cores, cap) if cap >= 1 else cores


def _shared_pool(workers: int) -> ThreadPoolExecutor:
    """This process's pool with ``workers`` threads (a new one after a fork or a resize)."""
    global _pool
    with _lock:
        pid = os.getpid()
        if _pool is None or _pool[0] != pid or _pool[1] != workers:
            if _pool is not None and _pool[0] == pid:
                _pool[2].shutdown(wait=False)
            _pool = (pid, workers, ThreadPoolExecutor(workers, thread_name_prefix="bondid"))
        return _pool[2]


def thread_map(fn: Callable[[T], R], items: Sequence[T], *, parallel: bool = True) -> list[R]:
    """``[fn(x) for x in items]``, on up to :func:`thread_limit` threads; in order.

    ``parallel=False`` (jobs too small to gain from threads), one item, one allowed thread, or
    a call from one of the pool's own threads runs in the calling thread. An exception in a
    job is raised here.
    """
    workers = min(len(items), thread_limit())
    if not parallel or workers <= 1 or threading.current_thread().name.startswith("bondid"):
        return [fn(x) for x in items]
    pool = _shared_pool(thread_limit())
    return list(pool.map(fn, items))
