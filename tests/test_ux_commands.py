"""The command line as a person meets it: ``python -m bondid``, progress bars, one-line
warnings, the optional Dask of ``bondid.fleet``."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from bondid.__main__ import COMMANDS, main
from bondid.progress import Progress
from bondid.warnlines import format_line, one_line_warnings

ROOT = Path(__file__).resolve().parents[1]


def _python(*args: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=300,
                          cwd=ROOT, **kw)  # fmt: skip


def test_python_m_bondid_lists_every_command_and_runs_one(tmp_path: Path):
    proc = _python("-m", "bondid")
    assert proc.returncode == 0
    listed = [line.split()[0] for line in proc.stdout.splitlines() if line.startswith("  ")]
    assert listed == [c for c, _ in COMMANDS]
    for c, _ in COMMANDS:  # each a module python -m runs
        mod = "bondid.simulate" if c == "simulate" else f"bondid.{c}.__main__"
        assert (ROOT / "src" / (mod.replace(".", "/") + ".py")).is_file(), mod
    bad = _python("-m", "bondid", "fitt")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "fit" in bad.stderr
    # a command runs as python -m bondid.COMMAND: same exit code (2: the model is missing)
    a = _python("-m", "bondid", "fit", "--model", "nope.urdf", "--data", "d.csv")
    b = _python("-m", "bondid.fit", "--model", "nope.urdf", "--data", "d.csv")
    assert a.returncode == b.returncode == 2 and a.stderr == b.stderr


def test_bondid_report_through_the_dispatcher(tmp_path: Path, capsys):
    res = tmp_path / "r"
    res.mkdir()
    (res / "fit.json").write_text('{"status": "ok", "parameters": []}')
    with pytest.raises(SystemExit) as stop:
        main(["report", str(res), "--quiet"])
    assert stop.value.code == 0 and (res / "report.html").is_file()


def test_progress_bar_has_a_total_and_writes_lines_into_logs(capsys):
    prog = Progress("fit (iterations)", 200)
    for it in range(0, 13):
        prog.set(it, f"cost {100 - it:.4g}")
    assert prog.count == 12 and prog.total == 200
    prog.close("Solve_Succeeded")
    err = capsys.readouterr().err
    assert "\r" not in err  # stderr is not a terminal here: whole lines only
    assert err.strip().splitlines()[-1].startswith("fit (iterations): done (12/200, Solve")
    quiet = Progress("x", 3, quiet=True)
    quiet.update(3)
    quiet.close()
    assert capsys.readouterr().err == ""


def test_a_warning_is_one_line_with_a_short_path(capsys):
    import numpy as np

    import bondid

    here = Path(bondid.__file__).resolve().parent / "fit" / "outputs.py"
    line = format_line(RuntimeWarning("divide by zero\n  in log"), RuntimeWarning, str(here), 9)
    assert line == "warning: RuntimeWarning: divide by zero in log (bondid/fit/outputs.py:9)"
    with one_line_warnings(), warnings.catch_warnings():
        warnings.simplefilter("always")
        np.log(np.zeros(1))
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("warning: RuntimeWarning: divide by zero")
    assert str(Path.cwd()) not in err and "site-packages" not in err


def test_fleet_without_dask_says_what_to_install(monkeypatch):
    from bondid.cluster.client import require_dask
    from bondid.exceptions import DependencyError

    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import fails as if missing
    with pytest.raises(DependencyError, match=r"pip install 'bondid\[fleet\]'"):
        require_dask()


def test_only_the_fleet_imports_dask():
    code = (
        "import sys, bondid.fit.cli, bondid.sensitivity.__main__, bondid.diagnose.cli,"
        " bondid.modes.__main__, bondid.report.build, bondid.simulate, bondid.__main__;"
        " print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))"
    )
    proc = _python("-c", code)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"
