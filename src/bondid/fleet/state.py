"""A machine's result folder and its ``status.json`` (written last: the folder is complete).

Layout under ``OUT/machines/``: ``<id>/`` is a complete result (moved into place in one
rename); ``.<id>.part-<host>-<pid>-<token>/`` is work in progress (or the remains of a worker
that died); ``.<id>.old-<token>/`` is a previous result being replaced.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

STATUS_JSON = "status.json"
STATUS_OK, STATUS_FAILED = "ok", "failed"


def part_prefix(machine_id: str) -> str:
    """File-name prefix of a machine's work-in-progress folders."""
    return f".{machine_id}.part-"


def read_status(machine_dir: Path) -> dict[str, Any] | None:
    """The ``status.json`` of a machine's result folder, or None when absent or unreadable."""
    try:
        data = json.loads((machine_dir / STATUS_JSON).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return data if isinstance(data, dict) else None


def skip_reason(status: dict[str, Any] | None, fingerprint: str) -> str | None:
    """Why a machine need not run again (None: it must run).

    A machine is skipped when its previous result succeeded with the same inputs and
    settings (same fingerprint). Failed machines run again: their data may have been fixed.
    """
    if status is None or status.get("status") != STATUS_OK:
        return None
    if status.get("fingerprint") != fingerprint:
        return None
    return "done"


def clean_stale(machines_dir: Path) -> int:
    """Remove work-in-progress and replaced folders left by an earlier run; returns the count.

    Call only when no fleet worker writes into ``machines_dir`` (at the start of a run, which
    holds the lock of ``--out``).
    """
    n = 0
    if not machines_dir.is_dir():
        return 0
    for p in machines_dir.iterdir():
        if not (p.name.startswith(".") and (".part-" in p.name or ".old-" in p.name)):
            continue
        if p.is_dir():  # a work folder, or the staging folder of a killed fit in it
            shutil.rmtree(p, ignore_errors=True)
        else:  # the lock file a killed fit leaves next to its --out
            p.unlink(missing_ok=True)
        n += 1
    return n
