"""A hostile or unlucky user's sweep over every command: bad data files, bad models, bad
options, planted manifests, bad output targets, signals, a full disk, a killed fleet
worker, a kill in the middle of a commit (cases: ``tools/sweep_cases.py`` and
``tools/sweep_events.py``).

Each case runs ``python -m bondid.<command>`` as its own process in a fresh sandbox folder
(the inputs, a results folder, and a sibling folder of files that no run may touch), with a
timeout, and is classified:

* traceback — ``Traceback (most recent call last)`` or bondid's "internal error" line;
* segfault — ended by SIGSEGV, SIGBUS or SIGABRT;
* hang — still running at the timeout (then killed);
* accepted — a bad input that exited 0 (silently accepted);
* wrong exit — a bad input not exiting 2, a failure (full disk) not exiting 1, a signal not
  ending in 130/143;
* not one line — a refusal whose stderr is not exactly one line;
* touched — a file created, changed or removed outside ``--out`` (the sandbox is snapshot
  before and after, outputs excluded), or a process of the run still alive after it ended.

Prints one table row per group of cases and the problems found, and with ``--json`` writes
every run. Usage::

    python tools/sweep_inputs.py [--only GROUP ...] [--case NAME ...] [--json FILE]
        [--keep DIR] [--timeout S]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "src") not in sys.path:
    sys.path.insert(0, str(ROOT / "src"))
if str(ROOT / "tools") not in sys.path:
    sys.path.insert(0, str(ROOT / "tools"))

from sweep_cases import CASES  # noqa: E402
from sweep_events import Skip  # noqa: E402
from sweep_sandbox import Case, Sandbox, make_base  # noqa: E402

PROBLEMS = ("traceback", "segfault", "hang", "accepted", "wrong_exit", "not_one_line", "touched")
CRASH_SIGNALS = {signal.SIGSEGV, signal.SIGBUS, signal.SIGABRT}


@dataclass
class Run:
    """One case's outcome."""

    case: str
    group: str
    command: str
    expect: str
    code: int | None
    wall_s: float
    stop_s: float | None
    stderr_tail: list[str]
    problems: list[str] = field(default_factory=list)
    skipped: str | None = None
    stderr: str = field(default="", repr=False)


def snapshot(root: Path, skip: list[Path]) -> dict[str, str]:
    """Every entry under ``root`` except ``skip`` (and what lies under them): path → kind and
    content hash (links by their target)."""
    out: dict[str, str] = {}
    skip_abs = [s.absolute() for s in skip]
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        here = Path(dirpath)
        dirnames[:] = [d for d in dirnames if (here / d).absolute() not in skip_abs]
        for name in [*dirnames, *filenames]:
            p = here / name
            if p.absolute() in skip_abs:
                continue
            rel = str(p.relative_to(root))
            if p.is_symlink():
                out[rel] = f"link {os.readlink(p)}"
            elif p.is_dir():
                out[rel] = "dir"
            elif p.is_file():
                try:
                    out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
                except OSError as exc:
                    out[rel] = f"unreadable {exc.errno}"
            else:
                out[rel] = "special"
    return out


def _group_alive(pgid: int) -> list[int]:
    """Processes of the process group ``pgid`` that are alive (not zombies)."""
    alive = []
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            fields = Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            alive.append(int(d))
    return alive


def run_case(case: Case, base: Path, work: Path, timeout: float) -> Run:
    """Run one case in a fresh sandbox under ``work`` and classify it."""
    box = Sandbox.create(base, work / case.name)
    try:
        argv = case.argv(box)
    except Skip as exc:
        return Run(
            case.name, case.group, case.command, case.expect, None, 0.0, None, [], skipped=str(exc)
        )
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "OPENBLAS_NUM_THREADS": "1"}
    env.pop("BONDID_TRACEBACK", None)
    skip = [box.root / o for o in case.outputs]
    before = snapshot(box.root, skip)
    cmd = case.runner(box) if case.runner else [sys.executable, "-m", f"bondid.{case.command}"]
    t0 = time.monotonic()
    p = subprocess.Popen(
        [*cmd, *argv],
        cwd=box.root,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    stop_s = None
    hung = False
    try:
        case.wait_for(box, p)  # (a case without a signal may act itself: kill a worker)
        if case.signal is not None:
            if p.poll() is None:
                ts = time.monotonic()
                os.killpg(p.pid, case.signal)
                out, err = p.communicate(timeout=timeout)
                stop_s = time.monotonic() - ts
            else:
                out, err = p.communicate()
        else:
            out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        hung = True
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
    wall = time.monotonic() - t0
    deadline = time.monotonic() + 5
    while _group_alive(p.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    leftover = _group_alive(p.pid)
    if leftover:
        os.killpg(p.pid, signal.SIGKILL)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    r = Run(
        case.name,
        case.group,
        case.command,
        case.expect,
        p.returncode,
        round(wall, 2),
        None if stop_s is None else round(stop_s, 3),
        lines[-3:],
    )
    r.stderr = err
    _classify(r, case, box, out, err, lines, hung, leftover, before, skip)
    return r


def _classify(
    r: Run,
    case: Case,
    box: Sandbox,
    out: str,
    err: str,
    lines: list[str],
    hung: bool,
    leftover: list[int],
    before: dict[str, str],
    skip: list[Path],
) -> None:
    code = r.code
    if hung:
        r.problems.append("hang")
    if "Traceback (most recent call last)" in err or "error: internal error" in err:
        r.problems.append("traceback")
    if code is not None and code < 0 and -code in CRASH_SIGNALS:
        r.problems.append("segfault")
    if not hung and case.expect == "bad":
        if code == 0:
            r.problems.append("accepted")
        elif code != 2:
            r.problems.append("wrong_exit")
        if len(lines) != 1:
            r.problems.append("not_one_line")
    elif not hung and case.expect == "fail":
        if code != 1:
            r.problems.append("accepted" if code == 0 else "wrong_exit")
        if len(lines) != 1:
            r.problems.append("not_one_line")
    elif not hung and case.expect == "signal":
        want = 128 + int(case.signal or 0)
        if code != want:
            r.problems.append("wrong_exit")
        if not lines or lines[-1] not in ("interrupted", "terminated"):
            r.problems.append("not_one_line")
    elif not hung and case.expect == "ok" and code not in (0, 1):
        r.problems.append("wrong_exit")
    if leftover:
        r.problems.append("touched")
        r.stderr_tail.append(f"(processes left: {leftover})")
    for problem in case.check(box, r) if case.check else []:
        r.problems.append(problem)
    after = snapshot(box.root, skip)  # (after the check: it may run the next command)
    changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    if changed:
        r.problems.append("touched")
        r.stderr_tail.append(f"(changed outside --out: {changed[:5]})")
    r.problems = sorted(set(r.problems))


def table(runs: list[Run]) -> str:
    """The summary table: one row per group, then the total."""
    groups = sorted({r.group for r in runs}, key=lambda g: [r.group for r in runs].index(g))
    head = ["group", "runs", *PROBLEMS, "clean", "skipped"]
    rows = []
    for g in [*groups, "total"]:
        sel = runs if g == "total" else [r for r in runs if r.group == g]
        counts = [sum(p in r.problems for r in sel) for p in PROBLEMS]
        done = [r for r in sel if r.skipped is None]
        rows.append(
            [g, len(done), *counts, sum(not r.problems for r in done), len(sel) - len(done)]
        )
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows, strict=True)]
    fmt = "  ".join(f"{{:<{w}}}" if i == 0 else f"{{:>{w}}}" for i, w in enumerate(widths))
    return "\n".join(fmt.format(*row) for row in [head, *rows])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="+", default=None, help="groups to run")
    ap.add_argument("--case", nargs="+", default=None, help="case names to run")
    ap.add_argument("--json", type=Path, default=None, help="write every run here")
    ap.add_argument("--keep", type=Path, default=None, help="keep the sandboxes here")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds before a hang")
    args = ap.parse_args(argv)
    cases = [
        c
        for c in CASES
        if (args.only is None or c.group in args.only)
        and (args.case is None or c.name in args.case)
    ]
    work = args.keep or Path(tempfile.mkdtemp(prefix="bondid-sweep-"))
    work.mkdir(parents=True, exist_ok=True)
    base = make_base(work / "_base")
    runs: list[Run] = []
    try:
        for k, case in enumerate(cases, start=1):
            r = run_case(case, base, work, args.timeout)
            runs.append(r)
            mark = "ok" if not r.problems else " ".join(r.problems)
            if r.skipped:
                mark = f"skipped ({r.skipped})"
            stop = "" if r.stop_s is None else f", stopped in {r.stop_s:.2f} s"
            print(
                f"[{k}/{len(cases)}] {case.group}/{case.name} ({case.command}): exit {r.code}"
                f" in {r.wall_s:.1f} s{stop}: {mark}",
                flush=True,
            )
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    print()
    print(table(runs))
    bad = [r for r in runs if r.problems]
    for r in bad:
        print(f"\n{r.group}/{r.case}: {', '.join(r.problems)} (exit {r.code})")
        for ln in r.stderr_tail:
            print(f"    {ln[:300]}")
    stops = [r.stop_s for r in runs if r.stop_s is not None]
    if stops:
        print(f"\nsignals: {len(stops)} runs stopped in {min(stops):.2f}–{max(stops):.2f} s")
    if args.json is not None:
        rows = [{k: v for k, v in asdict(r).items() if k != "stderr"} for r in runs]
        args.json.write_text(json.dumps(rows, indent=1) + "\n")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
