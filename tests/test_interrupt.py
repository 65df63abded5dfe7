"""Worker processes and Ctrl-C: spawned workers start with SIGINT ignored."""

from __future__ import annotations

import signal
from concurrent.futures import ProcessPoolExecutor

from bondid.interrupt import spawn_context


def _sigint_handler_name() -> str:
    h = signal.getsignal(signal.SIGINT)
    return "ignored" if h == signal.SIG_IGN else repr(h)


def test_spawned_workers_ignore_sigint_from_their_start() -> None:
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # as the CLI has it
    try:
        with ProcessPoolExecutor(1, mp_context=spawn_context()) as ex:  # no initializer
            assert ex.submit(_sigint_handler_name).result(timeout=120) == "ignored"
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # it is back
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_plain_spawned_worker_would_not_ignore_it() -> None:
    """The reference: without :func:`spawn_context` the worker has Python's own handler
    (when the parent handles SIGINT itself: a parent started in the background with SIGINT
    ignored passes that on to every child, which is why the test sets the handler)."""
    import multiprocessing as mp

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as ex:
            assert ex.submit(_sigint_handler_name).result(timeout=120) != "ignored"
    finally:
        signal.signal(signal.SIGINT, previous)
