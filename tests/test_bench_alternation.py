"""The speed benchmark's A B A B alternation: every command runs once per pair, in turn."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from bench_diagnose import alternate  # noqa: E402


def _appender(log: Path, tag: str) -> list[str]:
    code = f"open({str(log)!r}, 'a').write({tag!r})"
    return [sys.executable, "-c", code]


def test_pairs_run_in_turn_and_give_a_finite_ratio(tmp_path: Path) -> None:
    log = tmp_path / "order.txt"
    t = alternate(_appender(log, "A"), _appender(log, "B"), runs=3, timeout=60)
    assert log.read_text() == "ABABAB"
    assert t["a_s"] > 0.0 and t["b_s"] > 0.0
    assert 0.0 < t["ratio"] < float("inf")


def test_a_command_past_its_timeout_is_stopped(tmp_path: Path) -> None:
    log = tmp_path / "order.txt"
    # A writes its mark only after a sleep far past the timeout: stopped, it never writes it
    code = f"import time; time.sleep(30); open({str(log)!r}, 'a').write('A')"
    slow = [sys.executable, "-c", code]
    alternate(slow, _appender(log, "B"), runs=1, timeout=1)
    assert log.read_text() == "B"
