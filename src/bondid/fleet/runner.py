"""Submit the machines to Dask and collect their status records as they finish.

Scheduling, transport and retries are Dask's: one task per machine
(``client.submit(..., retries=N)``, collected with ``as_completed``). A worker that dies
mid-machine makes the scheduler run that task again on another worker (up to Dask's
``distributed.scheduler.allowed-failures``); an exception inside the task (an ``OSError``
writing results) is retried ``retries`` times. A task that still fails is recorded as a
failed machine with its reason, and the others go on.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import json
import sys
import time
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..atomic import write_text_atomic
from ..cli import Progress
from ..cluster.client import worker_threads
from .state import STATUS_FAILED, STATUS_JSON, STATUS_OK
from .worker import MachineJob, run_machine


def _eta(elapsed: float, done: int, left: int) -> str:
    if done == 0 or left == 0:
        return "ETA —" if left else "ETA 0 s"
    s = elapsed / done * left
    return f"ETA {s / 60:.1f} min" if s >= 120 else f"ETA {s:.0f} s"


def _task_failed(job: MachineJob, exc: BaseException) -> dict[str, Any]:
    """The status of a machine whose task failed in Dask itself (worker deaths, retries spent);
    written to ``OUT/machines/<id>/status.json`` so the reason stays with the machine."""
    status = {
        **job.status_header(),
        "status": STATUS_FAILED,
        "reason": f"task failed in Dask: {type(exc).__name__}: {exc}",
        "exit_code": 1,
        "fit": None,
        "finished": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
    }
    final = Path(job.machines_dir) / job.machine_id
    write_text_atomic(final / STATUS_JSON, json.dumps(status, indent=2) + "\n")
    return status


#: seconds between the checks for an interrupt and for lost workers while machines run
POLL_S = 0.2


def run_jobs(
    client: Any, jobs: Sequence[MachineJob], *, retries: int, quiet: bool
) -> list[dict[str, Any]]:
    """Run every job on the cluster; returns their status records in completion order.

    Progress (done / failed / running, ETA) goes to stderr through :class:`bondid.cli.Progress`;
    a worker that leaves the cluster while machines run is reported in one line (Dask runs
    its machine again elsewhere). The wait is a poll (:data:`POLL_S`), so a Ctrl-C is seen
    at once even when a library swallowed its ``KeyboardInterrupt``
    (:func:`bondid.interrupt.check`).
    """
    from .. import interrupt
    from ..cluster.client import require_dask

    as_completed = require_dask().as_completed
    run = uuid.uuid4().hex[:8]
    futures = {
        client.submit(
            run_machine, job, key=f"bondid-fleet-{job.machine_id}-{run}", retries=retries,
            pure=False,
        ): job
        for job in jobs
    }  # fmt: skip
    prog = Progress("fleet", len(jobs), quiet=quiet)
    out: list[dict[str, Any]] = []
    n_failed = 0
    t0 = time.perf_counter()
    watch = WorkerWatch(client)
    try:
        pending = as_completed(futures)
        while len(out) < len(jobs):
            interrupt.check()
            batch = pending.next_batch(block=False)
            if not batch:
                watch.poll()
                time.sleep(POLL_S)
                continue
            for fut in batch:
                job = futures[fut]
                try:
                    status = fut.result()
                except Exception as exc:  # KilledWorker, retries exhausted, ...
                    status = _task_failed(job, exc)
                fut.release()
                out.append(status)
                n_failed += status.get("status") != STATUS_OK
                left = len(jobs) - len(out)
                running = min(left, worker_threads(client))
                word = "ok" if status.get("status") == STATUS_OK else "FAILED"
                prog.update(
                    1,
                    f"done, {n_failed} failed, {running} running, "
                    f"{_eta(time.perf_counter() - t0, len(out), left)} ({job.machine_id} {word})",
                )
    except BaseException:
        with contextlib.suppress(Exception):
            client.cancel(list(futures))
        raise
    prog.close(f"{len(out) - n_failed} ok, {n_failed} failed")
    return out


class WorkerWatch:
    """The cluster's workers, checked now and then: one line on stderr for each worker that
    left (killed, crashed, out of memory) instead of Dask's own tracebacks."""

    def __init__(self, client: Any, every_s: float = 1.0):
        self.client, self.every_s = client, every_s
        self.known = self._workers()
        self.last = time.monotonic()

    def _workers(self) -> dict[str, Any]:
        try:
            return dict(self.client.scheduler_info().get("workers", {}))
        except Exception:  # informational only
            return {}

    def poll(self) -> None:
        if time.monotonic() - self.last < self.every_s:
            return
        self.last = time.monotonic()
        now = self._workers()
        if not now and self.known:
            return  # the scheduler did not answer this time
        for addr in sorted(set(self.known) - set(now)):
            pid = self.known[addr].get("pid") if isinstance(self.known[addr], dict) else None
            who = f"{addr} (pid {pid})" if pid else addr
            print(
                f"fleet: Dask worker {who} was lost; its machine runs again on another worker",
                file=sys.stderr,
                flush=True,
            )
        self.known = now
