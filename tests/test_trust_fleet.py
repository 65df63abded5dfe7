"""The fleet: a manifest like every command, no lock left behind, Ctrl-C that leaves no
process behind (also while the cluster starts), worker loss and Dask's tracebacks reported
in one line (issue 61)."""

from __future__ import annotations

import io
import json
import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bondid.manifest import read_manifest

REPO = Path(__file__).resolve().parents[1]
NOMINAL = REPO / "urdf" / "bonder.urdf"
TIMEOUT_S = 600


#: how long a spawned worker's interpreter takes to start (s): the cluster is still starting
WORKER_BOOT_S = 1.0


@pytest.fixture(scope="module")
def one_machine(tmp_path_factory):
    from bondid.fleet.synthetic import make_fleet
    from bondid.model.document import UrdfDocument

    root = tmp_path_factory.mktemp("fleet1")
    make_fleet(UrdfDocument.load(NOMINAL), root / "machines", n_machines=1,
               parameters=["x_guide_ry.stiffness"], freq=(5.0, 3000.0, 40), seed=3)  # fmt: skip
    return root / "machines"


def _argv(machines: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "bondid.fleet", "--model", str(NOMINAL), "--machines",
            str(machines), "--out", str(out), "--free", "x_guide_ry.stiffness", "--max-iter",
            "30", "--presolve", "0", "--workers", "1", *extra]  # fmt: skip


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}


def _children(pid: int) -> set[int]:
    """Every descendant of ``pid`` (from /proc)."""
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                stat = Path(f"/proc/{d}/stat").read_text()
            except OSError:
                continue
            ppid = int(stat.rsplit(")", 1)[1].split()[1])
            kids.setdefault(ppid, []).append(int(d))
    out, todo = set(), [pid]
    while todo:
        for c in kids.get(todo.pop(), []):
            out.add(c)
            todo.append(c)
    return out


def _alive(pids: set[int]) -> set[int]:
    out = set()
    for p in pids:
        try:
            state = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            out.add(p)
    return out


def _no_litter(root: Path) -> None:
    assert not [n for n in os.listdir(root) if ".bondid-" in n], os.listdir(root)


@pytest.mark.slow
def test_a_fleet_run_writes_a_manifest_and_leaves_no_lock(one_machine, tmp_path):
    out = tmp_path / "out"
    r = subprocess.run(_argv(one_machine, out), env=_env(), capture_output=True, text=True,
                       timeout=TIMEOUT_S)  # fmt: skip
    assert r.returncode == 0, r.stderr
    m = read_manifest(out, "fleet")
    assert m is not None and set(m["files_by_name"]) >= {"fleet.json", "fleet.csv"}
    assert not (out / ".fleet.lock").exists()
    _no_litter(tmp_path)
    assert json.loads((out / "fleet.json").read_text())["counts"]["ok"] == 1
    assert "Traceback" not in r.stderr


@pytest.mark.slow
@pytest.mark.parametrize("moment", ["cluster_start", "machines_running"])
def test_ctrl_c_stops_the_fleet_and_every_process(one_machine, tmp_path, moment):
    """SIGINT to the process group (as a terminal's Ctrl-C) while the local cluster starts
    (its first worker process just spawned) or while the machine is fitted."""
    out = tmp_path / "out"
    p = subprocess.Popen(_argv(one_machine, out, "--max-iter", "400"), env=_env(),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)  # fmt: skip
    t0 = time.monotonic()
    seen: set[int] = set()
    while time.monotonic() - t0 < TIMEOUT_S and p.poll() is None:
        seen |= _children(p.pid)
        running = (out / "machines").is_dir() and any((out / "machines").iterdir())
        if (moment == "cluster_start" and seen) or (moment == "machines_running" and running):
            break
        time.sleep(0.02)
    if moment == "cluster_start":
        # past the new worker's interpreter start-up: a SIGINT inside Python's own site
        # import is reported by the interpreter before any code of ours can run
        time.sleep(WORKER_BOOT_S)
    assert p.poll() is None, p.communicate()[1]
    seen |= _children(p.pid)
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert err.strip().splitlines()[-1] == "interrupted" and "Traceback" not in err, err
    deadline = time.monotonic() + 10  # reaped orphans can take a moment to vanish
    while _alive(seen) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(seen)
    assert not (out / "fleet.json").exists() and not (out / ".fleet.lock").exists()
    _no_litter(tmp_path)


def test_a_lost_worker_is_one_line(capsys):
    from bondid.fleet.runner import WorkerWatch

    class Client:
        def __init__(self):
            self.answers = [
                {"workers": {"tcp://a:1": {"pid": 11}, "tcp://b:2": {"pid": 12}}},
                {"workers": {"tcp://b:2": {"pid": 12}, "tcp://c:3": {"pid": 13}}},
            ]

        def scheduler_info(self):
            return self.answers.pop(0) if len(self.answers) > 1 else self.answers[0]

    watch = WorkerWatch(Client(), every_s=0.0)
    watch.poll()
    watch.poll()
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "fleet: Dask worker tcp://a:1 (pid 11) was lost; its machine runs again on another worker"
    ]


def test_dask_tracebacks_are_folded_into_one_line():
    from bondid.cluster.client import one_line_logs

    log = logging.getLogger("distributed.test_trust")
    buf = io.StringIO()
    handler = logging.StreamHandler(buf)
    logging.getLogger("distributed").addHandler(handler)
    try:
        with one_line_logs():
            try:
                raise ConnectionError("Stream is closed\nwhile reading")
            except ConnectionError:
                log.error("Failed to communicate with worker", exc_info=True)
    finally:
        logging.getLogger("distributed").removeHandler(handler)
    lines = buf.getvalue().strip().splitlines()
    assert lines == [
        "Failed to communicate with worker (ConnectionError: Stream is closed while reading)"
    ]
