"""Cases of ``tools/sweep_inputs.py`` that happen to a run: signals, a killed fleet worker,
a full disk, a SIGKILL in the middle of a commit (see ``sweep_sandbox.py``)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sweep_sandbox import ROOT, Argv, Case, Sandbox, diag, fit, modes, sens, with_out

# -- signals ----------------------------------------------------------------------------------


def _after_staging(extra_s: float) -> Callable[[Sandbox, subprocess.Popen[str]], None]:
    """Wait until the run staged its results (it is under way), then ``extra_s``."""

    def wait(box: Sandbox, p: subprocess.Popen[str]) -> None:
        t0 = time.monotonic()
        while p.poll() is None and time.monotonic() - t0 < 300:
            if any(n.startswith(".out.bondid-tmp-") for n in os.listdir(box.root)):
                break
            time.sleep(0.02)
        time.sleep(extra_s)

    return wait


def _after(seconds: float) -> Callable[[Sandbox, subprocess.Popen[str]], None]:
    return lambda box, p: time.sleep(seconds)


def _fleet_argv(b: Sandbox, *extra: str) -> list[str]:
    return [
        "--model",
        str(b.model),
        "--machines",
        str(b.root / "fleet"),
        "--out",
        str(b.out),
        "--free",
        "x_guide_ry.stiffness",
        "--presolve",
        "0",
        "--workers",
        "1",
        *extra,
    ]


def _children_of(pid: int) -> list[int]:
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                ppid = int(Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()[1])
            except OSError:
                continue
            if ppid == pid:
                out.append(int(d))
    return out


def _first_child(box: Sandbox, p: subprocess.Popen[str]) -> None:
    t0 = time.monotonic()
    while p.poll() is None and not _children_of(p.pid) and time.monotonic() - t0 < 300:
        time.sleep(0.02)


def _machine_running(box: Sandbox, p: subprocess.Popen[str]) -> None:
    t0 = time.monotonic()
    while p.poll() is None and time.monotonic() - t0 < 300:
        m = box.out / "machines"
        if m.is_dir() and any(m.iterdir()):
            break
        time.sleep(0.05)
    time.sleep(0.5)


def _kill_worker(box: Sandbox, p: subprocess.Popen[str]) -> None:
    """SIGKILL the worker process fitting the machine (its pid is in the part folder)."""
    t0 = time.monotonic()
    while p.poll() is None and time.monotonic() - t0 < 300:
        m = box.out / "machines"
        parts = list(m.glob(".m*.part-*")) if m.is_dir() else []
        if parts:
            try:
                os.kill(int(parts[0].name.split("-")[-2]), signal.SIGKILL)
            except (ProcessLookupError, ValueError):
                continue
            box.extra["killed"] = parts[0].name
            return
        time.sleep(0.05)


def _worker_killed_ok(box: Sandbox, run: Any) -> list[str]:
    if "killed" not in box.extra:
        return ["wrong_exit"]  # the kill did not happen: the case proved nothing
    st = box.out / "machines" / "m00" / "status.json"
    problems = [] if st.is_file() and '"ok"' in st.read_text() else ["wrong_exit"]
    lost = [ln for ln in run.stderr.splitlines() if "was lost" in ln]
    if len(lost) != 1:  # the worker's loss, said in one line
        problems.append("not_one_line")
    return problems


SIGNALS: list[Case] = [
    Case("sigint_early", "signals", "fit", lambda b: fit(b), "signal", signal.SIGINT, _after(0.6)),
    Case(
        "sigint_fit_running",
        "signals",
        "fit",
        lambda b: fit(b, "--max-iter", "400", "--free", "all"),
        "signal",
        signal.SIGINT,
        _after_staging(2.0),
    ),
    Case(
        "sigterm_fit_running",
        "signals",
        "fit",
        lambda b: fit(b, "--max-iter", "400", "--free", "all"),
        "signal",
        signal.SIGTERM,
        _after_staging(2.0),
    ),
    Case(
        "sigint_sensitivity",
        "signals",
        "sensitivity",
        lambda b: sens(b, "--free", "all"),
        "signal",
        signal.SIGINT,
        _after_staging(1.0),
    ),
    Case(
        "sigint_diagnose_workers",
        "signals",
        "diagnose",
        lambda b: diag(b, "--workers", "2"),
        "signal",
        signal.SIGINT,
        _first_child,
    ),
    Case(
        "sigint_modes", "signals", "modes", lambda b: modes(b), "signal", signal.SIGINT, _after(0.8)
    ),
    Case(
        "sigint_fleet_cluster_start",
        "fleet",
        "fleet",
        lambda b: _fleet_argv(b, "--max-iter", "400"),
        "signal",
        signal.SIGINT,
        _first_child,
    ),
    Case(
        "sigint_fleet_running",
        "fleet",
        "fleet",
        lambda b: _fleet_argv(b, "--max-iter", "400"),
        "signal",
        signal.SIGINT,
        _machine_running,
    ),
    Case(
        "killed_worker",
        "fleet",
        "fleet",
        lambda b: _fleet_argv(b, "--max-iter", "30"),
        "ok",
        None,
        _kill_worker,
        check=_worker_killed_ok,
    ),
]


# -- a full disk ------------------------------------------------------------------------------


class Skip(Exception):
    """The case cannot run here (e.g. no right to mount a file system)."""


def _full_disk(command: str) -> Argv:
    """A 256 kB tmpfs holding a previous complete run and a filler leaving ~24 kB."""

    def argv(b: Sandbox) -> list[str]:
        disk = b.root / "disk"
        disk.mkdir()
        r = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(disk)], capture_output=True
        )
        if r.returncode != 0:
            raise Skip("cannot mount a tmpfs (needs root)")
        out = disk / "out"
        out.mkdir()
        (out / "modes.json").write_text('{"modes": []}\n')
        (out / "fit.json").write_text('{"status": "x", "parameters": []}\n')
        (out / "bode_q0.png").write_bytes(_noise_png())  # a report embeds it: ~40 kB
        b.extra["previous"] = {p.name: p.read_bytes() for p in out.iterdir()}
        st = os.statvfs(disk)
        with open(disk / "filler", "wb", buffering=0) as fh:
            fh.write(b"\0" * max(0, st.f_bavail * st.f_frsize - 24 * 1024))
        if command == "report":
            return [str(out)]
        if command == "simulate":
            return ["--model", str(b.model), "--out", str(disk / "s.csv"), "--freq", "1:4000:5000"]
        make = {"modes": modes, "fit": fit, "sensitivity": sens}[command]
        return with_out(make(b), out)

    return argv


def _noise_png() -> bytes:
    import io

    import numpy as np
    from PIL import Image

    rgb = np.random.default_rng(0).integers(0, 255, (100, 120, 3), dtype=np.uint8)
    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG")
    return buf.getvalue()


def _disk_check(box: Sandbox, run: Any) -> list[str]:
    disk = box.root / "disk"
    try:
        out = disk / "out"
        now = {p.name: p.read_bytes() for p in out.iterdir() if p.name in box.extra["previous"]}
        problems = [] if now == box.extra["previous"] else ["touched"]
        if not any("no space left writing" in ln and "intact" in ln for ln in run.stderr_tail):
            problems.append("not_one_line")
        return problems
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)


DISK: list[Case] = [
    Case(
        f"full_disk-{c}",
        "full disk",
        c,
        _full_disk(c),
        "fail",
        outputs=("disk",),
        check=_disk_check,
    )
    for c in ("modes", "fit", "sensitivity", "simulate", "report")
]


# -- a kill in the middle of a commit ---------------------------------------------------------

KILL_COMMIT = """
import os, sys
from pathlib import Path
from bondid import journal
from bondid.results import open_results
out = Path(sys.argv[1])
real, moved = journal.move, [0]
def move(src, dst):
    real(src, dst)
    moved[0] += 1
    if moved[0] == 1:
        os._exit(9)
journal.move = move
res = open_results(out, "fit", [], patterns=("fit.json", "bode_*.png"))
res.path("fit.json").write_text('{"status": "new", "parameters": []}')
res.path("bode_q1.png").write_bytes(b"")
res.commit(main="fit.json")
"""


def _kill_commit_check(box: Sandbox, run: Any) -> list[str]:
    """The half-replaced folder: refused by a report elsewhere, restored by one into it."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    problems = [] if run.code == 9 else ["wrong_exit"]
    r = subprocess.run(
        [sys.executable, "-m", "bondid.report", str(box.out), "--out", str(box.root / "elsewhere")],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    if r.returncode != 2:
        problems.append("accepted" if r.returncode == 0 else "wrong_exit")
    if len(lines) != 1 or "Traceback" in r.stderr:
        problems.append("not_one_line")
    r = subprocess.run(
        [sys.executable, "-m", "bondid.report", str(box.out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    fit = (box.out / "fit.json").read_text()
    if r.returncode != 0 or '"Solve_Succeeded"' not in fit or (box.out / "bode_q1.png").exists():
        problems.append("wrong_exit")
    return problems


def _kill_commit_argv(b: Sandbox) -> list[str]:
    shutil.copytree(b.root / "results", b.out)
    return [str(b.out)]


KILLS: list[Case] = [
    Case(
        "sigkill_in_commit",
        "kill in commit",
        "fit",
        _kill_commit_argv,
        "killed",
        outputs=("out", "elsewhere"),
        check=_kill_commit_check,
        runner=lambda b: [sys.executable, "-c", KILL_COMMIT],
    ),
]
