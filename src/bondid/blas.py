"""BLAS threading for the command-line tools.

The linear algebra here is many small products and solves; bondid runs its own threads (one
per data set, :mod:`bondid.threads`) or worker processes over them, and a multi-threaded BLAS
underneath only makes the threads contend (measured: the bundled fit 15.7 s with OpenBLAS's
default threads, 12.2 s single-threaded, on 2 cores). The entry points call
:func:`prefer_single_threaded_blas` before NumPy is first imported; a user's own setting of the
variables wins.
"""

from __future__ import annotations

import os

#: the environment variables the common BLAS builds read their thread count from
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def prefer_single_threaded_blas() -> None:
    """Default every :data:`THREAD_VARS` to 1 (effective only before NumPy is imported)."""
    for var in THREAD_VARS:
        os.environ.setdefault(var, "1")
