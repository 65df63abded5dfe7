"""The Dask client of a fleet run: a local cluster of worker processes, or the user's cluster.

``dask.distributed`` is imported here, lazily. Worker processes started by a Dask nanny get
single-threaded BLAS from Dask's own ``distributed.nanny.pre-spawn-environ`` setting (the
``*_NUM_THREADS`` variables = 1); the command also sets them before NumPy is imported
(:mod:`bondid.blas`), so local workers inherit them either way.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterator
from typing import Any

from ..exceptions import ConfigError

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
            f"bondid.fleet needs Dask (dask[distributed]), which is not installed: {INSTALL_HINT}"
        ) from None
    return dask.distributed


@contextlib.contextmanager
def open_client(address: str | None, workers: int) -> Iterator[Any]:
    """A connected ``dask.distributed.Client`` (closed, with any local cluster, on exit).

    Args:
        address: ``tcp://HOST:PORT`` of an existing scheduler, or None for a local cluster.
        workers: worker processes of the local cluster (one thread each).

    Raises:
        ConfigError: the scheduler cannot be reached (names the address).
    """
    distributed = require_dask()
    Client, LocalCluster = distributed.Client, distributed.LocalCluster

    if address is not None:
        try:
            client = Client(address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConfigError(
                f"--scheduler {address}: cannot connect to a Dask scheduler there ({exc});"
                " give tcp://HOST:PORT of a running scheduler"
            ) from None
        with client:
            yield client
        return
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    with cluster, Client(cluster) as client:
        yield client


def worker_threads(client: Any) -> int:
    """Threads over all workers the scheduler knows now (at least 1)."""
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # informational only (progress display)
        return 1
