"""Shared inputs of the ``test_trust_*`` modules: the bonder model, one small data file,
an in-process runner of a command's ``main(argv)`` and the one-line check of a refusal."""

from __future__ import annotations

import contextlib
import shutil
import signal
from collections.abc import Callable, Iterator
from importlib import import_module
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BONDER = REPO / "urdf" / "bonder.urdf"

MAINS = {
    "fit": "bondid.fit.cli",
    "sensitivity": "bondid.sensitivity.__main__",
    "diagnose": "bondid.diagnose.cli",
    "modes": "bondid.modes.__main__",
    "simulate": "bondid.simulate",
    "report": "bondid.report.__main__",
    "fleet": "bondid.fleet.cli",
}

RunResult = tuple[int, str, str]


def make_inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``model`` (a copy of the bonder) and ``data`` (40 frequencies, 2 % noise, CSV), for a
    module-scoped fixture."""
    from bondid.data.io import write_frf
    from bondid.model.document import UrdfDocument
    from bondid.simulate import log_grid, simulate

    root = tmp_path_factory.mktemp("trust_inputs")
    model = root / "bonder.urdf"
    shutil.copy(BONDER, model)
    ds = simulate(UrdfDocument.load(model), {}, log_grid(5.0, 3000.0, 40), noise=0.02, seed=0)
    ds.source = str(root / "d0.csv")
    write_frf(ds, root / "d0.csv")
    return {"model": model, "data": root / "d0.csv", "root": root}


@contextlib.contextmanager
def deadline(seconds: int) -> Iterator[None]:
    """Fail (instead of hanging CI) when the block blocks longer than ``seconds``, e.g. in
    an ``open`` of a FIFO (SIGALRM interrupts the system call)."""

    def alarm(signum: int, frame: object) -> None:
        raise TimeoutError(f"still blocked after {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def runner(capsys: pytest.CaptureFixture[str]) -> Callable[..., RunResult]:
    """``run(command, *argv)`` → (exit code, stdout, stderr), in this process."""

    def _run(command: str, *argv: object) -> RunResult:
        main = import_module(MAINS[command]).main
        capsys.readouterr()
        try:
            with deadline(120):
                code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse errors of the commands that parse outside run
            code = exc.code if isinstance(exc.code, int) else 2
        out, err = capsys.readouterr()
        return int(code), out, err

    return _run


def only_line(err: str) -> str:
    """The single line of a refused run's stderr (asserts there is exactly one, and no
    traceback)."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def fast_argv(command: str, model: Path, data: Path, out: Path | None = None) -> list[str]:
    """The quickest invocation of each command."""
    o = [] if out is None else ["--out", str(out)]
    if command == "fit":
        return ["--model", str(model), "--data", str(data), "--free", "x_guide_ry.stiffness",
                "--max-iter", "3", "--presolve", "0", "--quiet", *o]  # fmt: skip
    if command == "sensitivity":
        return ["--model", str(model), "--data", str(data), "--free", "x_guide_ry.stiffness",
                "--no-sweep", "--quiet", *o]  # fmt: skip
    if command == "diagnose":
        return ["--model", str(model), "--data", str(data), "--points", "20", "--effects",
                "sensor_delay", "--free", "x_guide_ry.stiffness", "--workers", "1",
                "--no-plots", "--quiet", *o]  # fmt: skip
    if command == "modes":
        return ["--model", str(model), "--no-html", *o]
    if command == "simulate":
        return ["--model", str(model), "--freq", "5:300:20", "--out", str(out or "sim.csv")]
    raise ValueError(command)
