"""The fleet's relay of its workers' standard error: this process's own lines arrive whole
and in order; what a worker left behind by a stopped run writes afterwards never reaches the
user's terminal. Each case runs in its own interpreter (descriptor 2 is process-wide)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

#: seconds a late child waits before writing: well after its parent's run has ended
LATE_S = 0.5


def _run(body: str) -> subprocess.CompletedProcess[str]:
    script = textwrap.dedent(
        f"""
        import os, subprocess, sys, time
        from bondid.cluster.worker_stderr import relayed_stderr
        LATE = [sys.executable, "-c",
                "import sys, time; time.sleep({LATE_S}); sys.stderr.write('late worker\\\\n')"]
        """
    ) + textwrap.dedent(body)
    env = dict(os.environ, PYTHONPATH=str(SRC))
    return subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=60
    )


def test_own_lines_relayed_in_order_and_descriptor_restored() -> None:
    proc = _run(
        """
        before = os.fstat(2)
        with relayed_stderr():
            print("first", file=sys.stderr, flush=True)
            os.write(2, b"second\\n")
            subprocess.run([sys.executable, "-c", "import sys; sys.stderr.write('worker\\\\n')"])
            print("third", file=sys.stderr, flush=True)
        after = os.fstat(2)
        assert (before.st_dev, before.st_ino) == (after.st_dev, after.st_ino)
        print("after", file=sys.stderr, flush=True)
        """
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == ["first", "second", "worker", "third", "after"]


def test_a_worker_left_behind_by_an_interrupt_is_not_heard() -> None:
    proc = _run(
        """
        try:
            with relayed_stderr():
                print("started", file=sys.stderr, flush=True)
                late = subprocess.Popen(LATE)
                raise KeyboardInterrupt
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr, flush=True)
        late.wait()
        """
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == ["started", "interrupted"]


def test_a_worker_spawned_after_the_interrupt_is_not_heard() -> None:
    # A cluster still starting in another thread spawns workers after the run has stopped.
    proc = _run(
        """
        try:
            with relayed_stderr():
                raise KeyboardInterrupt
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr, flush=True)
        subprocess.run(LATE)
        print("still mine", file=sys.stderr, flush=True)
        """
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == ["interrupted", "still mine"]
