"""One machine of the fleet, run inside a Dask worker: :func:`run_machine`.

The machine is fitted exactly as ``python -m bondid.fit`` would fit it (its ``main(argv)`` is
called in the worker process) into a work-in-progress folder next to ``OUT/machines/<id>``;
with diagnosis, ``python -m bondid.diagnose`` runs the same way into ``diagnosis/``. The
commands' output goes to ``fit.log`` / ``diagnose.log``; ``status.json`` is written last and
the folder is renamed into place, so ``OUT/machines/<id>`` is either complete or absent.

Only deterministic outcomes are recorded as a failed machine (exit code 1 or 2, or an error
raised by the command); an ``OSError`` of our own file handling propagates so Dask retries it.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import io
import json
import os
import shutil
import socket
import sys
import threading
import time
import traceback
import uuid
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..atomic import write_text_atomic
from .state import STATUS_FAILED, STATUS_JSON, STATUS_OK, part_prefix

FIT_LOG, DIAGNOSE_LOG, DIAGNOSIS_DIR = "fit.log", "diagnose.log", "diagnosis"


@dataclass(frozen=True)
class MachineJob:
    """Everything a worker needs for one machine (paths must be visible to the worker)."""

    machine_id: str
    model: str
    data: tuple[str, ...]
    machines_dir: str
    fit_args: tuple[str, ...]
    diagnose_args: tuple[str, ...] | None
    fingerprint: str

    def status_header(self) -> dict[str, Any]:
        """The keys every ``status.json`` of the machine starts with (its id and inputs)."""
        return {
            "machine": self.machine_id,
            "model": self.model,
            "data": list(self.data),
            "fingerprint": self.fingerprint,
        }


class _Tee(io.TextIOBase):
    """A text stream writing to several streams (the log, and a copy of stderr)."""

    def __init__(self, *streams: io.TextIOBase):
        self.streams = streams

    def write(self, s: str) -> int:
        for st in self.streams:
            st.write(s)
        return len(s)

    def isatty(self) -> bool:
        return False


_LOCAL = threading.local()
_INSTALL = threading.Lock()


class _PerThread(io.TextIOBase):
    """Stand-in for ``sys.stdout``/``sys.stderr`` in a worker process: a thread that captures
    writes to its own stream, every other thread to the original one (so the machines of a
    worker with several threads keep their logs apart)."""

    def __init__(self, name: str, original: Any):
        self.name, self.original = name, original

    def _target(self) -> Any:
        return getattr(_LOCAL, self.name, None) or self.original

    def write(self, s: str) -> int:
        return self._target().write(s)

    def flush(self) -> None:
        self._target().flush()

    def isatty(self) -> bool:
        return bool(self._target().isatty())


@contextlib.contextmanager
def _capture(out: io.TextIOBase, err: io.TextIOBase) -> Iterator[None]:
    """Send this thread's ``print`` output to ``out`` and ``err`` for the block."""
    with _INSTALL:
        for name in ("stdout", "stderr"):
            if not isinstance(getattr(sys, name), _PerThread):
                setattr(sys, name, _PerThread(name, getattr(sys, name)))
    _LOCAL.stdout, _LOCAL.stderr = out, err
    try:
        yield
    finally:
        _LOCAL.stdout = _LOCAL.stderr = None


def _run_command(
    main: Callable[[Sequence[str]], int], argv: list[str], log: Path
) -> tuple[int, str | None]:
    """Run a command's ``main(argv)`` with its output captured in ``log``.

    Returns:
        (exit code, reason): the reason is the last error line the command printed (or the
        exception it raised), None on success.
    """
    text, err = io.StringIO(), io.StringIO()
    out, both = _Tee(text), _Tee(text, err)
    raised = None
    try:
        with _capture(out, both):
            code = int(main(argv))
    except SystemExit as exc:  # an argparse error or --help inside the command
        code = exc.code if isinstance(exc.code, int) else 2
    except Exception as exc:  # a bug or unexpected failure of the command: not retried
        text.write(traceback.format_exc())
        code, raised = 1, f"{type(exc).__name__}: {exc}"
    lines = [ln.strip() for ln in err.getvalue().splitlines() if ln.strip()]
    flagged = [ln for ln in lines if ln.startswith(("error", "bad input"))]
    err_line = raised or (flagged or lines or [f"exit code {code}"])[-1]
    write_text_atomic(log, f"$ {' '.join(argv)}\n{text.getvalue()}\n(exit code {code})\n")
    return code, None if code == 0 else err_line


def _fit_summary(fit_json: Path) -> dict[str, Any] | None:
    try:
        fit = json.loads(fit_json.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    keep = ("status", "success", "cost_name", "cost_initial", "cost_final", "iterations", "wall_s")
    params = [
        {k: p.get(k) for k in ("name", "initial", "fitted", "std", "lower", "upper")}
        for p in fit.get("parameters", [])
        if isinstance(p, dict)
    ]
    return {**{k: fit.get(k) for k in keep}, "parameters": params}


def _diag_summary(diag_json: Path) -> dict[str, Any] | None:
    try:
        verdict = json.loads(diag_json.read_text(encoding="utf-8")).get("verdict") or {}
    except (OSError, ValueError, AttributeError):
        return None
    return {k: verdict.get(k) for k in ("effect", "location", "gap_closed")}


def _commit(part: Path, final: Path, machine_id: str) -> None:
    """Move the finished ``part`` folder to ``final`` (replacing an older result)."""
    if final.exists():
        old = final.with_name(f".{machine_id}.old-{uuid.uuid4().hex[:8]}")
        os.rename(final, old)
        os.rename(part, final)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.rename(part, final)


def run_machine(job: MachineJob) -> dict[str, Any]:
    """Fit (and diagnose) one machine; returns its status record (also ``status.json``)."""
    from ..diagnose.cli import main as diagnose_main
    from ..fit.cli import main as fit_main

    t0, started = time.perf_counter(), dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    mdir = Path(job.machines_dir)
    mdir.mkdir(parents=True, exist_ok=True)
    prefix = part_prefix(job.machine_id)
    attempt = 1 + sum(1 for p in mdir.iterdir() if p.name.startswith(prefix))
    where = f"{socket.gethostname()}-{os.getpid()}"
    part = mdir / f"{prefix}{where}-{uuid.uuid4().hex[:8]}"
    part.mkdir()
    status: dict[str, Any] = {
        **job.status_header(),
        "attempt": attempt,
        "worker": where,
        "started": started,
    }
    reason: str | None
    if not job.data:
        code, reason = 2, f"{job.machine_id}: no data files in the machine's folder"
    else:
        argv = ["--model", job.model, "--data", *job.data, "--out", str(part), "--quiet"]
        code, reason = _run_command(fit_main, [*argv, *job.fit_args], part / FIT_LOG)
        reason = None if reason is None else f"fit: {reason}"
    status["fit_exit"] = code
    status["fit"] = _fit_summary(part / "fit.json")
    if job.diagnose_args is not None and code == 0:
        out = part / DIAGNOSIS_DIR
        argv = ["--model", job.model, "--data", *job.data, "--out", str(out), "--quiet"]
        argv += ["--workers", "1", *job.diagnose_args]
        dcode, dreason = _run_command(diagnose_main, argv, part / DIAGNOSE_LOG)
        status["diagnose_exit"] = dcode
        status["diagnosis"] = _diag_summary(out / "diagnosis.json")
        if dreason is not None:
            code, reason = dcode, f"diagnose: {dreason}"
    status["status"] = STATUS_OK if code == 0 else STATUS_FAILED
    status["reason"] = reason
    status["exit_code"] = code
    status["wall_s"] = round(time.perf_counter() - t0, 3)
    status["finished"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    write_text_atomic(part / STATUS_JSON, json.dumps(status, indent=2) + "\n")
    _commit(part, mdir / job.machine_id, job.machine_id)
    return status
