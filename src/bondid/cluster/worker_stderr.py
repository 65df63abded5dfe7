"""The standard error of a local cluster's worker processes, relayed while the run lasts.

A worker process inherits this process's standard error (file descriptor 2). A worker that
is being spawned when the run stops (a Ctrl-C while the cluster starts, or while a nanny
restarts a worker) can outlive this process by a moment; it then fails in its start-up,
because the data and semaphores its parent was handing it are gone, and prints a traceback
on the user's terminal after the run has already said ``interrupted``. No kill from here
can close that window: the spawn happens in Dask's own threads.

So, while a local cluster runs, descriptor 2 is a pipe that a thread copies to the real
standard error; when the run ends, descriptor 2 is the real one again and whatever a
leftover worker still writes into the pipe is dropped (and, once this process has exited,
the pipe has no reader: the worker's write fails where nobody sees it).
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Iterator

#: bytes read from the pipe at a time
CHUNK = 65536
#: seconds the relay is given to pass on what was written before the run ended
MARK_WAIT_S = 0.2


@contextlib.contextmanager
def relayed_stderr() -> Iterator[None]:
    """Context: descriptor 2 is a pipe relayed to the real standard error; on exit it is
    the real one again and the pipe's later output is dropped. A no-op where descriptor 2
    cannot be duplicated (no standard error at all)."""
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    try:
        real = os.dup(2)
    except OSError:
        yield
        return
    read_end, write_end = os.pipe()
    os.dup2(write_end, 2)
    os.close(write_end)
    mark = b"\0bondid-stderr-end-" + os.urandom(8).hex().encode() + b"\0"
    reached = threading.Event()

    def relay() -> None:
        tail = b""  # the end of the last chunk: the mark may straddle two reads
        try:
            while chunk := os.read(read_end, CHUNK):
                if reached.is_set():
                    continue
                text = tail + chunk
                at = text.find(mark)
                if at >= 0:
                    os.write(real, text[:at])
                    reached.set()
                    continue
                # held back: only what could be the start of the mark (it starts with NUL)
                cut = text.rfind(b"\0", max(0, len(text) - len(mark) + 1))
                cut = len(text) if cut < 0 else cut
                os.write(real, text[:cut])
                tail = text[cut:]
        except OSError:  # the terminal went away: nothing left to relay to
            pass
        finally:
            reached.set()
            os.close(read_end)

    thread = threading.Thread(target=relay, name="bondid-cluster-worker-stderr", daemon=True)
    thread.start()
    try:
        yield
    except BaseException:
        # The run is stopping, and a cluster still starting in Dask's threads may spawn
        # workers after this: descriptor 2 stays the pipe for them, this process's own
        # messages go to the real standard error from here on.
        _end(mark, real, reached)
        with contextlib.suppress(Exception):
            sys.stderr = os.fdopen(real, "w", buffering=1, errors="backslashreplace")
        raise
    _end(mark, real, reached)
    os.dup2(real, 2)
    if reached.wait(MARK_WAIT_S):  # else the relay may still write there: keep it open
        os.close(real)


def _end(mark: bytes, real: int, reached: threading.Event) -> None:
    """Write ``mark`` into the pipe: what came before it (this process's own lines among
    it) is relayed to ``real``, whatever a leftover worker writes after it is not."""
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    with contextlib.suppress(OSError):
        os.write(2, mark)
    reached.wait(MARK_WAIT_S)
