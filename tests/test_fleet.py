"""``python -m bondid.fleet`` on a real ``dask.distributed`` cluster started here (scheduler and
two worker processes on localhost), with a synthetic fleet of the reference bonder."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bondid.fleet.aggregate import aggregate
from bondid.fleet.cli import main as fleet_main
from bondid.model.document import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = ROOT / "urdf" / "bonder.urdf"
FREE = ["y_guide_rx.stiffness", "x_guide_ry.stiffness"]
N_GOOD = 7
SPREAD = 0.08  # ±8 % across the fleet
FAULT = ("m03", "y_guide_rx.stiffness", 0.6)  # 40 % softer y-guide
#: fitted vs true value of a good machine (2 % noise, 160 frequencies)
FIT_REL_TOL = 0.03
RUN_TIMEOUT_S = 300
#: the outlier's deviation from the fleet median, fitted vs true (median of 7 noisy values)
DEV_ABS_TOL = 0.05


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("dask.distributed")
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as c,
        distributed.Client(c) as client,
    ):
        yield c, client


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    from bondid.fleet.synthetic import make_fleet

    root = tmp_path_factory.mktemp("fleet")
    machines = root / "machines"
    truth = make_fleet(
        UrdfDocument.load(NOMINAL), machines, n_machines=N_GOOD, parameters=FREE,
        spread=SPREAD, faults={FAULT[0]: {FAULT[1]: FAULT[2]}}, freq=(1.0, 4000.0, 160),
        noise=0.02, seed=7,
    )  # fmt: skip
    (machines / "bad").mkdir()
    (machines / "bad" / "q0.csv").write_text("freq_hz,x.x.re\n1,2\n", encoding="utf-8")
    return root, machines, truth


def _argv(machines: Path, out: Path, address: str, *extra: str) -> list[str]:
    return [
        "--model", str(NOMINAL), "--machines", str(machines), "--out", str(out),
        "--scheduler", address, "--free", *FREE, "--max-iter", "40", *extra,
    ]  # fmt: skip


def _kill_a_busy_worker(proc, out: Path, worker_pids: set[int]) -> str | None:
    """Kill the worker process of the first good machine seen in progress; returns it
    if it was still in progress after the kill (None if the race was lost)."""
    machines_dir = out / "machines"
    deadline = time.monotonic() + RUN_TIMEOUT_S
    while time.monotonic() < deadline and proc.poll() is None:
        parts = list(machines_dir.glob(".m*.part-*")) if machines_dir.is_dir() else []
        for part in parts:
            pid = int(part.name.split("-")[-2])
            if pid in worker_pids:
                os.kill(pid, signal.SIGKILL)
                return part.name[1:].split(".part-")[0] if part.exists() else None
        time.sleep(0.05)
    return None


@pytest.fixture(scope="module")
def first_run(cluster, fleet, tmp_path_factory):
    """The whole fleet, one worker killed while it fits a machine."""
    c, client = cluster
    _, machines, _ = fleet
    out = tmp_path_factory.mktemp("out") / "fleet_out"
    pids = set(client.run(os.getpid).values())
    cmd = [sys.executable, "-m", "bondid.fleet", *_argv(machines, out, c.scheduler_address)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = _kill_a_busy_worker(proc, out, pids)
    stdout, stderr = proc.communicate(timeout=RUN_TIMEOUT_S)
    return out, proc.returncode, stdout, stderr, killed


def _status(out: Path, mid: str) -> dict:
    return json.loads((out / "machines" / mid / "status.json").read_text())


@pytest.mark.slow
def test_fleet_fits_every_machine_and_flags_only_the_planted_outlier(first_run, fleet):
    out, code, stdout, stderr, _ = first_run
    _, _, truth = fleet
    assert code == 1, stderr  # the machine with bad data failed
    doc = json.loads((out / "fleet.json").read_text())
    assert doc["counts"] == {"machines": N_GOOD + 1, "ok": N_GOOD, "failed": 1}
    found = [(o["machine"], o["parameter"]) for o in doc["outliers"]]
    assert found == [FAULT[:2]]
    (o,) = doc["outliers"]
    assert o["reason"] == (
        f"{FAULT[1]} {abs(100 * o['deviation_rel']):.0f} % below the fleet median"
        f" ({o['robust_z']:.1f} robust std)"
    )
    median_truth = sorted(v[FAULT[1]] for v in truth.values())[N_GOOD // 2]
    true_dev = truth[FAULT[0]][FAULT[1]] / median_truth - 1
    assert o["deviation_rel"] == pytest.approx(true_dev, abs=DEV_ABS_TOL)
    for mid, values in truth.items():
        fit = _status(out, mid)["fit"]
        fitted = {p["name"]: p["fitted"] for p in fit["parameters"]}
        for name, true in values.items():
            assert fitted[name] == pytest.approx(true, rel=FIT_REL_TOL), (mid, name)
    with open(out / "fleet.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == N_GOOD * len(FREE) + 1
    assert {r["machine"] for r in rows if r["outlier"] == "yes"} == {FAULT[0]}
    assert (out / "fleet_strip.png").stat().st_size > 0
    assert "outlier: m03: y_guide_rx.stiffness" in stdout
    assert "fleet:" in stderr and "running" in stderr and "ETA" in stderr


def test_bad_data_fails_that_machine_with_its_reason(first_run):
    out, _, stdout, _, _ = first_run
    st = _status(out, "bad")
    assert st["status"] == "failed" and st["fit_exit"] == 2
    assert "q0.csv" in st["reason"] and st["reason"].startswith("fit: bad input")
    assert "failed: bad: fit: bad input" in stdout
    assert "bad input" in (out / "machines" / "bad" / "fit.log").read_text()


def test_killed_worker_loses_nothing(first_run):
    out, _, _, _, killed = first_run
    machines_dir = out / "machines"
    assert not list(machines_dir.glob(".*")), "work-in-progress folders left behind"
    for d in machines_dir.iterdir():
        if d.name != "bad":
            assert _status(out, d.name)["status"] == "ok"
            assert (d / "fit.json").is_file() and (d / "fitted.urdf").is_file()
    if killed is not None:  # the kill hit a machine in progress: it ran again, elsewhere
        st = _status(out, killed)
        assert st["attempt"] == 2 and st["status"] == "ok"


def test_report_has_a_fleet_section(first_run):
    from bondid.report.build import build_report_html

    out = first_run[0]
    text, found = build_report_html(out, out)
    assert '<section id="fleet">' in text and "fleet_strip.png" in text
    assert "y_guide_rx.stiffness" in text and "m03" in text
    assert "fit.json" not in found.json_paths  # the machines' own results stay out
    assert "not found" not in text


def test_second_run_skips_finished_machines(first_run, fleet, cluster, capsys):
    out, _, _, _, _ = first_run
    _, machines, _ = fleet
    c, _ = cluster
    before = {d.name: (d / "status.json").stat().st_mtime_ns for d in (out / "machines").iterdir()}
    code = fleet_main([*_argv(machines, out, c.scheduler_address), "--quiet"])
    printed = capsys.readouterr().out
    assert code == 1  # the bad machine ran again (failed machines are retried) and failed
    assert f"skipping {N_GOOD} of {N_GOOD + 1} machines already done" in printed
    after = {d.name: (d / "status.json").stat().st_mtime_ns for d in (out / "machines").iterdir()}
    assert {k for k in before if before[k] != after[k]} == {"bad"}
    doc = json.loads((out / "fleet.json").read_text())
    assert [o["machine"] for o in doc["outliers"]] == [FAULT[0]]


@pytest.mark.slow
def test_diagnose_counts_effects(cluster, fleet, tmp_path):
    c, _ = cluster
    _, machines, _ = fleet
    two = tmp_path / "two"
    two.mkdir()
    for mid in ("m00", "m01"):
        (two / mid).symlink_to(machines / mid)
    out = tmp_path / "out"
    argv = _argv(two, out, c.scheduler_address, "--diagnose", "--quiet", "--effects")
    argv += ["sensor_delay", "--points", "40", "--diagnose-free", *FREE]
    assert fleet_main(argv) == 0
    doc = json.loads((out / "fleet.json").read_text())
    assert set(doc["effects"]["per_machine"]) == {"m00", "m01"}
    assert sum(doc["effects"]["counts"].values()) == 2
    assert (out / "machines" / "m00" / "diagnosis" / "diagnosis.json").is_file()


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--machines", "/nonexistent/fleet"], "--machines /nonexistent/fleet: not a folder"),
        (["--workers", "0"], "--workers 0"),
        (["--free", "no_such.stiffness"], "no_such.stiffness"),
        (["--bound", "stiffness"], "--bound 'stiffness'"),
        (["--points", "40"], "--points: only with --diagnose"),
        (["--prior", "-1"], "--prior: -1.0 is not a prior width"),
    ],
)
def test_bad_input_exits_2_naming_the_item(tmp_path, capsys, extra, words):
    (tmp_path / "m").mkdir()
    argv = ["--model", str(NOMINAL), "--machines", str(tmp_path / "m"), "--out"]
    argv += [str(tmp_path / "out"), "--workers", "1", *extra]
    assert fleet_main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0]


def test_fit_options_pass_the_prior_through(tmp_path):
    from bondid.fleet.cli import build_parser, fit_argv

    base = ["--model", str(NOMINAL), "--machines", str(tmp_path), "--out", str(tmp_path / "o")]
    argv = fit_argv(build_parser().parse_args([*base, "--prior", "0.1"]))
    assert argv[argv.index("--prior") + 1] == "0.1"
    assert "--prior" not in fit_argv(build_parser().parse_args(base))


def test_no_machine_is_bad_input(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    argv = ["--model", str(NOMINAL), "--machines", str(tmp_path / "empty")]
    assert fleet_main([*argv, "--out", str(tmp_path / "o")]) == 2
    assert "no machine folder found" in capsys.readouterr().err


def test_outlier_rule_known_answer():
    """Median 100, MAD 2 → robust std 2.9652, threshold 10.378: 111 is an outlier, 110 is not;
    an outlier whose own std is large (dev ≤ 3 std) is not flagged."""
    values = {"a": 98.0, "b": 100.0, "c": 102.0, "d": 99.0, "e": 101.0, "f": 111.0, "g": 89.0}
    stds = {"g": 4.0}

    def status(mid: str, v: float) -> dict:
        p = {"name": "k.stiffness", "fitted": v, "std": stds.get(mid)}
        return {"machine": mid, "status": "ok", "fit_exit": 0, "fit": {"parameters": [p]}}

    stats = aggregate([status(k, v) for k, v in values.items()])
    (param,) = stats.parameters
    assert param["median"] == 100.0 and param["mad"] == 2.0
    assert [o["machine"] for o in stats.outliers] == ["f"]
    assert stats.outliers[0]["reason"].startswith("k.stiffness 11 % above the fleet median")


def test_discover_and_plan(tmp_path):
    """A machine's own model.urdf is used; hidden folders are not machines; a finished machine
    is skipped until its data or the settings change."""
    from bondid.fleet.cli import plan
    from bondid.fleet.machines import discover

    root = tmp_path / "m"
    for mid in ("a1", "b2", ".hidden"):
        (root / mid).mkdir(parents=True)
        (root / mid / "q0.csv").write_text("x\n", encoding="utf-8")
    (root / "b2" / "model.urdf").write_text(NOMINAL.read_text(), encoding="utf-8")
    found = discover(root, NOMINAL)
    assert [m.id for m in found] == ["a1", "b2"]
    assert not found[0].own_model and found[1].own_model and found[1].model.name == "model.urdf"
    out = tmp_path / "out" / "machines"
    jobs, done = plan(found, out, ["--max-iter", "5"], None)
    assert len(jobs) == 2 and not done
    (out / "a1").mkdir(parents=True)
    status = {"machine": "a1", "status": "ok", "fingerprint": jobs[0].fingerprint}
    (out / "a1" / "status.json").write_text(json.dumps(status), encoding="utf-8")
    jobs, done = plan(found, out, ["--max-iter", "5"], None)
    assert [j.machine_id for j in jobs] == ["b2"] and [d["machine"] for d in done] == ["a1"]
    jobs, done = plan(found, out, ["--max-iter", "6"], None)  # other settings: run again
    assert len(jobs) == 2
    (root / "a1" / "q0.csv").write_text("xy\n", encoding="utf-8")  # changed data: run again
    jobs, done = plan(found, out, ["--max-iter", "5"], None)
    assert len(jobs) == 2
