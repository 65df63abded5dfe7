"""Real runs in subprocesses, interrupted (SIGINT) and killed (SIGKILL): exit 130 before the
work is done, also with worker processes (gone after), no partial result, inputs unchanged by
hash, outputs complete or absent, a concurrent run into the same ``--out`` refused (issue 16,
points 2 and 7)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from bondid.results import open_results, read_manifest

from .conftest import sha

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="signals and /proc")


@pytest.fixture(scope="module")
def long_data(inputs) -> Path:
    """A data set on which ``--free all`` takes several seconds."""
    from bondid.data.io import write_frf
    from bondid.model.document import UrdfDocument
    from bondid.simulate import log_grid, simulate

    path = inputs["root"] / "long.csv"
    if not path.exists():
        ds = simulate(UrdfDocument.load(inputs["model"]), {}, log_grid(1, 4000, 800), noise=0.02)
        write_frf(ds, path)
    return path


class Run:
    """A command in a subprocess whose stderr lines are collected as they come."""

    def __init__(self, command: str, *argv: object, cwd: Path):
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.p = subprocess.Popen(
            [sys.executable, "-m", f"bondid.{command}", *map(str, argv)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd, env=env,
        )  # fmt: skip
        self.err: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.p.stderr is not None
        for line in self.p.stderr:
            self.err.append(line)

    def wait_for(self, text: str, timeout: float = 60.0) -> None:
        t0 = time.monotonic()
        while not any(text in ln for ln in self.err):
            assert self.p.poll() is None, "".join(self.err)
            assert time.monotonic() - t0 < timeout, "".join(self.err)
            time.sleep(0.05)

    def children(self) -> set[int]:
        out = set()
        for d in Path("/proc").iterdir():
            if d.name.isdigit():
                try:
                    stat = (d / "stat").read_text()
                except OSError:
                    continue
                if int(stat.rsplit(")", 1)[1].split()[1]) == self.p.pid:
                    out.add(int(d.name))
        return out

    def interrupt(self, sig: int = signal.SIGINT) -> tuple[int, float]:
        t0 = time.monotonic()
        self.p.send_signal(sig)
        code = self.p.wait(timeout=30)
        return code, time.monotonic() - t0


def _alive(pids: set[int], grace: float = 2.0) -> set[int]:
    """The processes of ``pids`` still running after ``grace`` s (multiprocessing's resource
    tracker ends by itself once its parent is gone; the workers must be gone already)."""
    t0 = time.monotonic()
    while True:
        alive = set()
        for p in pids:
            try:
                cmd = Path(f"/proc/{p}/cmdline").read_bytes()
                state = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except OSError:
                continue
            if state != "Z" and (b"resource_tracker" not in cmd or time.monotonic() - t0 > grace):
                alive.add(p)
        if not alive or time.monotonic() - t0 > grace:
            return alive
        time.sleep(0.1)


def _no_litter(folder: Path) -> None:
    names = os.listdir(folder)
    assert not [n for n in names if ".bondid-" in n], names


def test_sigint_during_a_fit_and_a_concurrent_run(inputs, long_data, run, tmp_path):
    before = {p: sha(p) for p in (inputs["model"], long_data)}
    out = tmp_path / "out"
    r = Run("fit", "--model", inputs["model"], "--data", long_data, "--free", "all",
            "--max-iter", "300", "--out", out, cwd=tmp_path)  # fmt: skip
    r.wait_for("iteration")
    # a second run into the same --out is refused while the first holds it
    code, _, err = run("fit", "--model", inputs["model"], "--data", inputs["d0"], "--out", out)
    assert code == 2 and "another bondid run" in err
    code, _ = r.interrupt()  # (the time it takes is measured, not asserted: shared CI cores)
    assert code == 130, "".join(r.err)
    assert not any(": done" in ln for ln in r.err)  # stopped, not finished
    assert "interrupted" in "".join(r.err)
    assert not out.exists()
    _no_litter(tmp_path)
    assert {p: sha(p) for p in before} == before


@pytest.mark.parametrize(
    ("command", "n_up", "settle"),
    [("fit", 2, 1.5), ("sensitivity", 2, 0.5), ("diagnose", 2, 1.5), ("diagnose", 1, 0.0)],
)
def test_sigint_stops_worker_processes(command, n_up, settle, inputs, long_data, tmp_path):
    """Workers at work, and (diagnose, spawned) workers still starting up."""
    out = tmp_path / "out"
    if command == "fit":
        argv = ["--model", inputs["model"], "--data", long_data, "--free", "all",
                "--multistart", "2", "--workers", "2", "--max-iter", "300"]  # fmt: skip
    elif command == "sensitivity":
        argv = ["--model", inputs["model"], "--data", long_data, "--free", "all",
                "--workers", "2"]  # fmt: skip
    else:
        argv = ["--model", inputs["model"], "--data", inputs["d0"], inputs["d1"],
                "--points", "60", "--workers", "2", "--effects", "joint_compliance"]  # fmt: skip
    r = Run(command, *argv, "--out", out, cwd=tmp_path)
    t0 = time.monotonic()
    while len(r.children()) < n_up:  # the workers are up (and working)
        assert r.p.poll() is None and time.monotonic() - t0 < 60, "".join(r.err)
        time.sleep(0.05)
    time.sleep(settle)
    workers = r.children()
    code, _ = r.interrupt()  # (the time it takes is measured, not asserted: shared CI cores)
    assert code == 130, "".join(r.err)
    assert not any(": done" in ln for ln in r.err)  # stopped, not finished
    assert not _alive(workers)
    assert not out.exists()
    _no_litter(tmp_path)
    assert "Traceback" not in "".join(r.err)


def test_sigterm_stops_worker_processes_too(inputs, tmp_path):
    """SIGTERM (``kill``, a scheduler's time limit) as Ctrl-C: exit 143, ``terminated``, the
    workers gone (before, the parent died at once and left them computing), nothing
    written."""
    out = tmp_path / "out"
    argv = ["--model", inputs["model"], "--data", inputs["d0"], inputs["d1"],
            "--points", "60", "--workers", "2", "--effects", "joint_compliance"]  # fmt: skip
    r = Run("diagnose", *argv, "--out", out, cwd=tmp_path)
    t0 = time.monotonic()
    while len(r.children()) < 2:
        assert r.p.poll() is None and time.monotonic() - t0 < 60, "".join(r.err)
        time.sleep(0.05)
    time.sleep(1.5)
    workers = r.children()
    code, _ = r.interrupt(signal.SIGTERM)
    assert code == 128 + signal.SIGTERM, "".join(r.err)
    assert "terminated" in "".join(r.err)
    assert not _alive(workers)
    assert not out.exists()
    _no_litter(tmp_path)
    assert "Traceback" not in "".join(r.err)


def _complete_or_absent(out: Path, command: str, inputs: list[Path]) -> str:
    """'absent', 'complete' (manifest verifies, nothing unlisted) or 'incomplete' (no
    manifest: a reader can tell)."""
    if not out.exists():
        return "absent"
    names = set(os.listdir(out))
    assert not [n for n in names if n.startswith(".")], names  # no hidden temp files
    m = read_manifest(out, command)  # raises if a listed file is missing or differs
    if m is None:
        return "incomplete"
    listed = set(m["files_by_name"]) | {f"{command}.manifest.json"}
    assert names - listed <= {Path(i).name for i in inputs}, names - listed
    return "complete"


@pytest.mark.slow
def test_sigkill_never_leaves_a_mixed_or_partial_folder(inputs, tmp_path):
    """Kill runs that rewrite an older complete run at several moments up to their end."""
    model, data = inputs["model"], inputs["d0"]
    before = {p: sha(p) for p in (model, data)}
    out = tmp_path / "out"
    argv = ["--model", model, "--data", data, "--free", "x_guide_ry.stiffness", "--presolve",
            "0", "--quiet", "--out", out]  # fmt: skip
    t0 = time.monotonic()
    r = Run("fit", *argv, "--max-iter", "1", cwd=tmp_path)  # the older run
    assert r.p.wait(timeout=120) in (0, 1), "".join(r.err)
    full = time.monotonic() - t0
    assert _complete_or_absent(out, "fit", [model, data]) == "complete"
    for frac in (0.6, 1.0):
        r = Run("fit", *argv, "--max-iter", "20", cwd=tmp_path)
        time.sleep(frac * full)
        r.p.send_signal(signal.SIGKILL)
        r.p.wait(timeout=30)
        assert _complete_or_absent(out, "fit", [model, data]) in ("complete", "incomplete")
        assert {p: sha(p) for p in before} == before
    # the next run into it cleans what the killed ones left
    open_results(out, "fit", [model, data]).close()
    _no_litter(tmp_path)
    fit = json.loads((out / "fit.json").read_text())
    assert fit["parameters"][0]["name"] == "x_guide_ry.stiffness"


def test_a_forked_worker_that_outlives_a_killed_run_does_not_hold_its_lock(tmp_path):
    """A run takes the output's lock, forks a worker (as a process pool does) and dies
    without releasing (``os._exit``, as under SIGKILL); while the orphaned worker still runs,
    the next run into the same folder gets the lock."""
    out = tmp_path / "out"
    script = (
        "import multiprocessing as mp, os, sys, time\n"
        "from bondid.results import open_results\n"
        "r = open_results(sys.argv[1], 'fit', [])\n"
        "p = mp.get_context('fork').Process(target=time.sleep, args=(60,))\n"
        "p.start()\n"
        "print(p.pid, flush=True)\n"
        "os._exit(0)\n"
    )
    log = tmp_path / "pid.txt"  # a file, not a pipe: the orphan keeps its parent's stdout
    with log.open("w") as f:
        subprocess.run([sys.executable, "-c", script, str(out)], stdout=f, timeout=60,
                       check=True)  # fmt: skip
    orphan = int(log.read_text().split()[0])
    try:
        assert _alive({orphan}, grace=0.0) == {orphan}  # the worker outlived its parent
        open_results(out, "fit", []).close()
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(orphan, signal.SIGKILL)
