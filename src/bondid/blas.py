"""BLAS threading for the command-line tools.

The linear algebra here is many small products and solves; bondid runs its own threads (one
per data set, :mod:`bondid.threads`) or worker processes over them, and a multi-threaded BLAS
underneath only makes the threads contend (measured: the bundled fit 15.7 s with OpenBLAS's
default threads, 12.2 s single-threaded, on 2 cores). The entry points call
:func:`prefer_single_threaded_blas`; a user's own setting of the variables wins.

The limit of this process goes through threadpoolctl (it reaches the BLAS and OpenMP
libraries already loaded, whatever the import order); the environment variables set alongside
reach the libraries loaded later and the worker processes started from here.
"""

from __future__ import annotations

import os

#: the environment variables the common BLAS builds read their thread count from
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def prefer_single_threaded_blas() -> None:
    """One BLAS thread, unless the user set one of :data:`THREAD_VARS`: the variables
    default to 1 (libraries loaded later, child processes) and threadpoolctl limits the
    libraries already loaded."""
    if any(os.environ.get(v) for v in THREAD_VARS):
        return
    for var in THREAD_VARS:
        os.environ.setdefault(var, "1")
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1)
