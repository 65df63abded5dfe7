"""Independent NumPy-heavy jobs on threads (the LAPACK/BLAS calls and large array operations
they spend their time in release the GIL, so the cores work side by side)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

T = TypeVar("T")
R = TypeVar("R")


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the platform tells)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # not on Linux
        return max(os.cpu_count() or 1, 1)


def thread_map(fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
    """``[fn(x) for x in items]``, on up to :func:`available_cores` threads; in order.

    One item, or one core, runs in the calling thread. The pool lives for one call (threads
    are cheap next to the jobs, and a pool kept across calls would not survive a fork).
    An exception in a job is raised here.
    """
    workers = min(len(items), available_cores())
    if workers <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(fn, items))
