"""Worker processes and Ctrl-C: spawned workers start with SIGINT ignored."""

from __future__ import annotations

import signal
from concurrent.futures import ProcessPoolExecutor

from bondid.interrupt import spawn_context


def _sigint_handler_name() -> str:
    h = signal.getsignal(signal.SIGINT)
    return "ignored" if h == signal.SIG_IGN else repr(h)


def test_spawned_workers_ignore_sigint_from_their_start() -> None:
    before = signal.getsignal(signal.SIGINT)
    with ProcessPoolExecutor(1, mp_context=spawn_context()) as ex:  # no initializer
        assert ex.submit(_sigint_handler_name).result(timeout=120) == "ignored"
    assert signal.getsignal(signal.SIGINT) is before  # the parent's handler is back


def test_a_plain_spawned_worker_would_not_ignore_it() -> None:
    """The reference: without :func:`spawn_context` the worker has Python's own handler."""
    import multiprocessing as mp

    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as ex:
        assert ex.submit(_sigint_handler_name).result(timeout=120) != "ignored"
