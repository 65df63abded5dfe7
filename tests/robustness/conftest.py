"""Shared inputs of the robustness tests: the bonder model, two small data sets, and a runner
that calls a command's ``main(argv)`` in this process (fast) and returns its exit code and
output."""

from __future__ import annotations

import hashlib
import re
import shutil
from collections.abc import Callable
from importlib import import_module
from pathlib import Path

import numpy as np
import pytest
from trust_common import BONDER, MAINS  # the commands' entry points, shared


def sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="session")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``model`` (a copy of the bonder), ``d0``/``d1`` (40 frequencies, 2 % noise, two
    operating points, CSV) in a session folder."""
    from bondid.data.io import write_frf
    from bondid.model.document import UrdfDocument
    from bondid.simulate import log_grid, simulate

    root = tmp_path_factory.mktemp("robust_inputs")
    model = root / "bonder.urdf"
    shutil.copy(BONDER, model)
    doc = UrdfDocument.load(model)
    out = {"model": model, "root": root}
    for k, op in enumerate(({}, {"x": 0.03, "y": -0.02})):
        ds = simulate(doc, op, log_grid(5.0, 3000.0, 40), noise=0.02, seed=k)
        ds.source = str(root / f"d{k}.csv")
        write_frf(ds, root / f"d{k}.csv")
        out[f"d{k}"] = root / f"d{k}.csv"
    return out


RunResult = tuple[int, str, str]


@pytest.fixture
def run(capsys: pytest.CaptureFixture[str]) -> Callable[..., RunResult]:
    """``run(command, *argv)`` → (exit code, stdout, stderr) of ``bondid.<command>``."""

    def _run(command: str, *argv: object) -> RunResult:
        main = import_module(MAINS[command]).main
        capsys.readouterr()
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse errors in the commands that do not catch them
            code = exc.code if isinstance(exc.code, int) else 2
        out, err = capsys.readouterr()
        return int(code), out, err

    return _run


def fast_args(command: str, model: Path, data: list[Path], out: Path | None) -> list[str]:
    """The quickest useful invocation of each command (few parameters, few iterations)."""
    d = [str(p) for p in data]
    o = [] if out is None else ["--out", str(out)]
    if command == "fit":
        return ["--model", str(model), "--data", *d, "--free", "x_guide_ry.stiffness",
                "--max-iter", "3", "--presolve", "0", "--quiet", *o]  # fmt: skip
    if command == "sensitivity":
        return ["--model", str(model), "--data", *d, "--free", "x_guide_ry.stiffness",
                "--no-sweep", "--quiet", *o]  # fmt: skip
    if command == "diagnose":
        return ["--model", str(model), "--data", *d, "--points", "20", "--effects",
                "sensor_delay", "--free", "x_guide_ry.stiffness", "--workers", "1",
                "--no-plots", "--quiet", *o]  # fmt: skip
    if command == "modes":
        return ["--model", str(model), "--no-html", *o]
    if command == "simulate":
        return ["--model", str(model), "--freq", "5:300:20", "--out", str(out or "sim.csv")]
    raise ValueError(command)


def one_line_reason(err: str) -> str:
    """The single 'bad input: …' line of a refused run (asserts there is exactly one)."""
    lines = [ln for ln in err.splitlines() if ln.startswith(("bad input:", "python -m"))]
    reasons = [ln for ln in lines if "bad input" in ln]
    assert len(reasons) == 1, err
    assert "Traceback" not in err and "np.float64" not in err
    return reasons[0]


def mutate(text: str, pattern: str, repl: str, count: int = 1) -> str:
    new, n = re.subn(pattern, repl, text, count=count, flags=re.S)
    assert n, pattern
    return new


def finite(a: np.ndarray) -> bool:
    return bool(np.all(np.isfinite(a)))
