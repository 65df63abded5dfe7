"""Sandboxes and cases of ``tools/sweep_inputs.py`` (the inputs: ``sweep_cases.py``; signals,
a full disk and kills: ``sweep_events.py``).

A sandbox (:class:`Sandbox`) is a copy of the base folder (:func:`make_base`): ``inputs/`` (the
bonder, two small CSV data files, one UFF58 file), ``results/`` (a complete results folder
of bondid.fit, with its manifest), ``fleet/`` (one machine), ``sibling/`` (files no run may
touch). Each case's ``argv`` may add the bad input it needs (a FIFO, a planted manifest, a
mounted full disk) before the sweep's snapshot is taken.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BONDER = ROOT / "urdf" / "bonder.urdf"


@dataclass
class Sandbox:
    """One case's folder and its inputs."""

    root: Path
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def create(cls, base: Path, dest: Path) -> Sandbox:
        shutil.copytree(base, dest, symlinks=True)
        return cls(dest)

    @property
    def model(self) -> Path:
        return self.root / "inputs" / "bonder.urdf"

    @property
    def data(self) -> Path:
        return self.root / "inputs" / "d0.csv"

    @property
    def out(self) -> Path:
        return self.root / "out"

    def model_text(self, pattern: str, repl: str, count: int = 1) -> Path:
        """A copy of the bonder with ``pattern`` replaced (regex), as ``inputs/m.urdf``."""
        text, n = re.subn(pattern, repl, self.model.read_text(), count=count, flags=re.S)
        if not n:
            raise ValueError(pattern)
        p = self.root / "inputs" / "m.urdf"
        p.write_text(text)
        return p

    def file(self, name: str, content: str | bytes) -> Path:
        p = self.root / "inputs" / name
        p.write_bytes(content.encode() if isinstance(content, str) else content)
        return p

    def special(self, kind: str, name: str) -> Path:
        """A FIFO, folder, link loop or dangling link at ``inputs/name``."""
        p = self.root / "inputs" / name
        if kind == "fifo":
            os.mkfifo(p)
        elif kind == "folder":
            p.mkdir()
        elif kind == "loop":
            os.symlink(p.with_name(name + ".2"), p)
            os.symlink(p, p.with_name(name + ".2"))
        elif kind == "dangling":
            os.symlink(self.root / "nowhere", p)
        return p

    def data_rows(self, edit: Callable[[list[str]], None], name: str = "bad.csv") -> Path:
        """A copy of ``d0.csv`` with its lines edited in place by ``edit``."""
        lines = self.data.read_text().splitlines()
        edit(lines)
        return self.file(name, "\n".join(lines) + "\n")


def first_row(lines: list[str]) -> int:
    return next(i for i, ln in enumerate(lines) if ln[:1].isdigit())


def set_cell(lines: list[str], row: int, col: int, value: str) -> None:
    k = first_row(lines) + row
    cells = lines[k].split(",")
    cells[col] = value
    lines[k] = ",".join(cells)


def make_base(base: Path) -> Path:
    """Build the base folder once (in this process)."""
    from bondid.data.io import write_frf
    from bondid.fleet.synthetic import make_fleet
    from bondid.model.document import UrdfDocument
    from bondid.results import open_results
    from bondid.simulate import log_grid, simulate

    (base / "inputs").mkdir(parents=True)
    shutil.copy(BONDER, base / "inputs" / "bonder.urdf")
    doc = UrdfDocument.load(BONDER)
    for k, op in enumerate(({}, {"x": 0.03})):
        ds = simulate(doc, op, log_grid(5.0, 3000.0, 40), noise=0.02, seed=k)
        write_frf(ds, base / "inputs" / f"d{k}.csv")
        if k == 0:
            write_frf(ds, base / "inputs" / "d0.uff")
    res = open_results(base / "results", "fit", [], patterns=("fit.json", "bode_*.png"))
    res.path("fit.json").write_text('{"status": "Solve_Succeeded", "parameters": []}\n')
    res.path("bode_q0.png").write_bytes(_png())
    res.commit(main="fit.json")
    make_fleet(
        doc,
        base / "fleet",
        n_machines=1,
        parameters=["x_guide_ry.stiffness"],
        freq=(5.0, 3000.0, 40),
        seed=3,
    )
    (base / "sibling").mkdir()
    (base / "sibling" / "victim.txt").write_text("must stay\n")
    (base / "sibling" / "notes.txt").write_text("the user's\n")
    return base


def _png() -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 3), (1, 2, 3)).save(buf, format="PNG")
    return buf.getvalue()


Argv = Callable[[Sandbox], list[str]]


@dataclass
class Case:
    """One run: a command, how its arguments are made, and what is expected.

    ``expect``: ``bad`` (exit 2, one line), ``fail`` (exit 1, one line), ``signal`` (ended by
    the signal sent: 130/143 and one line), ``ok`` (0 or 1), ``killed`` (killed on purpose:
    only the case's own check counts).
    """

    name: str
    group: str
    command: str
    argv: Argv
    expect: str = "bad"
    signal: int | None = None
    wait: Callable[[Sandbox, subprocess.Popen[str]], None] | None = None
    outputs: tuple[str, ...] = ("out",)
    check: Callable[[Sandbox, Any], list[str]] | None = None
    runner: Callable[[Sandbox], list[str]] | None = None

    def wait_for(self, box: Sandbox, p: subprocess.Popen[str]) -> None:
        if self.wait is not None:
            self.wait(box, p)


def fit(
    box: Sandbox, *extra: object, model: Path | None = None, data: list[Path] | None = None
) -> list[str]:
    d = [str(x) for x in (data or [box.data])]
    return [
        "--model",
        str(model or box.model),
        "--data",
        *d,
        "--free",
        "x_guide_ry.stiffness",
        "--max-iter",
        "3",
        "--presolve",
        "0",
        "--quiet",
        "--out",
        str(box.out),
        *map(str, extra),
    ]


def sens(box: Sandbox, *extra: object, data: Path | None = None) -> list[str]:
    return [
        "--model",
        str(box.model),
        "--data",
        str(data or box.data),
        "--free",
        "x_guide_ry.stiffness",
        "--no-sweep",
        "--quiet",
        "--out",
        str(box.out),
        *map(str, extra),
    ]


def diag(box: Sandbox, *extra: object, data: Path | None = None) -> list[str]:
    return [
        "--model",
        str(box.model),
        "--data",
        str(data or box.data),
        "--points",
        "20",
        "--effects",
        "sensor_delay",
        "--free",
        "x_guide_ry.stiffness",
        "--workers",
        "1",
        "--no-plots",
        "--quiet",
        "--out",
        str(box.out),
        *map(str, extra),
    ]


def modes(box: Sandbox, *extra: object, model: Path | None = None) -> list[str]:
    return [
        "--model",
        str(model or box.model),
        "--no-html",
        "--out",
        str(box.out),
        *map(str, extra),
    ]


def sim(box: Sandbox, *extra: object, model: Path | None = None) -> list[str]:
    return [
        "--model",
        str(model or box.model),
        "--freq",
        "5:300:20",
        "--out",
        str(box.out / "sim.csv"),
        *map(str, extra),
    ]


def with_out(argv: list[str], target: Path) -> list[str]:
    """``argv`` with its ``--out`` value replaced by ``target``."""
    k = argv.index("--out")
    return [*argv[:k], "--out", str(target), *argv[k + 2 :]]
