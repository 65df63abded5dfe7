"""The cases of ``tools/sweep_inputs.py``: sandboxes and the inputs a hostile or unlucky
user gives every command.

A sandbox (``Sandbox``) is a copy of the base folder (``make_base``): ``inputs/`` (the
bonder, two small CSV data files, one UFF58 file), ``results/`` (a complete results folder
of bondid.fit, with its manifest), ``fleet/`` (one machine), ``sibling/`` (files no run may
touch). Each case's ``argv`` may add the bad input it needs (a FIFO, a planted manifest, a
mounted full disk) before the snapshot is taken.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
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


# -- bad data files ---------------------------------------------------------------------------

DATA_BAD: dict[str, Callable[[Sandbox], Path]] = {
    "fifo": lambda b: b.special("fifo", "f.csv"),
    "folder": lambda b: b.special("folder", "f.csv"),
    "link_loop": lambda b: b.special("loop", "f.csv"),
    "dangling_link": lambda b: b.special("dangling", "f.csv"),
    "missing": lambda b: b.root / "inputs" / "nope.csv",
    "empty": lambda b: b.file("e.csv", ""),
    "binary": lambda b: b.file("b.csv", bytes(range(256)) * 4),
    "latin1": lambda b: b.file("l.csv", "# quantity: réceptance\n".encode("latin-1")),
    "header_only": lambda b: b.file("h.csv", "freq_hz,x.x.re,x.x.im\n"),
    "one_line": lambda b: b.file("o.csv", "freq_hz,x.x.re,x.x.im\n10,1e-6,1e-7\n"),
    "nan_cell": lambda b: b.data_rows(lambda ls: set_cell(ls, 3, 1, "nan")),
    "cell_1e300": lambda b: b.data_rows(lambda ls: set_cell(ls, 3, 1, "1e300")),
    "zero_cell": lambda b: b.data_rows(
        lambda ls: (set_cell(ls, 3, 1, "0"), set_cell(ls, 3, 2, "0"))
    ),
    "freq_1e300": lambda b: b.data_rows(lambda ls: set_cell(ls, 39, 0, "1e300")),
    "freq_negative": lambda b: b.data_rows(lambda ls: set_cell(ls, 0, 0, "-5")),
    "freq_duplicate": lambda b: b.data_rows(
        lambda ls: ls.insert(first_row(ls) + 2, ls[first_row(ls) + 2])
    ),
    "unknown_channel": lambda b: b.data_rows(
        lambda ls: ls.__setitem__(
            first_row(ls) - 1, ls[first_row(ls) - 1].replace("x.x.re", "q.q.re", 1)
        )
    ),
    "wrong_suffix": lambda b: b.file("d.txt", b.data.read_text()),
    "uff_garbage": lambda b: b.file("g.uff", "    -1\n    58\n garbage\n" * 5),
    "uff_truncated": lambda b: b.file("t.uff", (b.root / "inputs" / "d0.uff").read_bytes()[:1500]),
    "same_file_twice": lambda b: b.data,
}


def _data_case(name: str, command: str) -> Case:
    build = DATA_BAD[name]
    argv_of = {"fit": fit, "sensitivity": sens, "diagnose": diag}[command]

    def argv(b: Sandbox) -> list[str]:
        bad = build(b)
        if name == "same_file_twice":
            return fit(b, data=[bad, bad]) if command == "fit" else argv_of(b, data=bad)
        return argv_of(b, data=bad) if command != "fit" else fit(b, data=[bad])

    return Case(f"data_{name}-{command}", "bad data", command, argv)


# -- bad models -------------------------------------------------------------------------------


def _deep(b: Sandbox) -> Path:
    n = 200_000
    return b.model_text("</robot>", "<gazebo>" + "<a>" * n + "</a>" * n + "</gazebo></robot>")


def _chain(b: Sandbox) -> Path:
    parts, prev = [], "z_bearing_rz_moving"
    for i in range(3000):
        parts.append(
            f'<link name="c{i}"/><joint name="cj{i}" type="fixed"><parent'
            f' link="{prev}"/><child link="c{i}"/></joint>'
        )
        prev = f"c{i}"
    return b.model_text("</robot>", "\n".join(parts) + "</robot>")


BOMB = (
    '<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol">'
    + "".join(
        f'<!ENTITY lol{i} "{("&lol" + (str(i - 1) if i > 1 else "") + ";") * 10}">'
        for i in range(1, 10)
    )
    + ']><robot name="r">&lol9;</robot>'
)
EXTERNAL = (
    '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
    '<robot name="r"><link name="&x;"/></robot>'
)

MODEL_BAD: dict[str, Callable[[Sandbox], Path]] = {
    "fifo": lambda b: b.special("fifo", "f.urdf"),
    "link_loop": lambda b: b.special("loop", "f.urdf"),
    "missing": lambda b: b.root / "inputs" / "nope.urdf",
    "not_xml": lambda b: b.file("n.urdf", "this is not XML"),
    "binary": lambda b: b.file("b.urdf", b"\x89PNG\r\n\x1a\n\xff\xfe\x00"),
    "xml_bomb": lambda b: b.file("bomb.urdf", BOMB),
    "external_entity": lambda b: b.file("ext.urdf", EXTERNAL),
    "deep_200k": _deep,
    "chain_3000": _chain,
    "spring_1e300": lambda b: b.model_text(r"<springStiffness>200000<", "<springStiffness>1e300<"),
    "mass_1e-300": lambda b: b.model_text(r'<mass value="1.67"/>', '<mass value="1e-300"/>'),
    "mass_1e300": lambda b: b.model_text(r'<mass value="1.67"/>', '<mass value="1e300"/>'),
    "origin_1e300": lambda b: b.model_text(r'xyz="0 0 0.155"', 'xyz="1e300 0 0.155"'),
    "limits_inverted": lambda b: b.model_text(
        r'lower="-0.1" upper="0.1"', 'lower="0.1" upper="-0.1"'
    ),
    "no_limit": lambda b: b.model_text(
        r'(<joint name="x_guide_ry" type="revolute">.*?)<limit[^>]*/>', r"\1"
    ),
    "negative_mass": lambda b: b.model_text(r'<mass value="1.67"/>', '<mass value="-1"/>'),
    "damping_text": lambda b: b.model_text(r'damping="1.6"', 'damping="soft"'),
    "kinematic_loop": lambda b: b.model_text(
        "</robot>",
        '<joint name="loop" type="fixed"><parent link="base"/>'
        '<child link="x_stage"/></joint></robot>',
    ),
    "no_transmission": lambda b: b.model_text(r"<transmission .*</transmission>", ""),
    "missing_mesh": lambda b: b.model_text(
        r'<box size="0.5 0.4 0.12"/>', '<mesh filename="nope.stl"/>'
    ),
}


def _model_case(name: str, command: str) -> Case:
    build = MODEL_BAD[name]
    argv_of = {
        "fit": lambda b, m: fit(b, model=m),
        "modes": lambda b, m: modes(b, model=m),
        "simulate": lambda b, m: sim(b, model=m),
    }[command]
    return Case(f"model_{name}-{command}", "bad model", command, lambda b: argv_of(b, build(b)))


# -- bad options ------------------------------------------------------------------------------

OPTIONS: list[tuple[str, str, Argv]] = [
    ("max_iter_huge", "fit", lambda b: fit(b, "--max-iter", "99999999999999999999")),
    ("max_iter_negative", "fit", lambda b: fit(b, "--max-iter", "-1")),
    ("channels_twice", "fit", lambda b: fit(b, "--channels", "x.x,x.x")),
    ("channels_unknown", "fit", lambda b: fit(b, "--channels", "q.q")),
    ("band_outside", "fit", lambda b: fit(b, "--band", "5000:6000")),
    ("band_1e300", "fit", lambda b: fit(b, "--band", "1:1e300")),
    ("band_inverted", "fit", lambda b: fit(b, "--band", "300:20")),
    ("weight_inf", "fit", lambda b: fit(b, "--weight", "x.x=inf")),
    ("free_unknown", "fit", lambda b: fit(b, "--free", "nosuch.stiffness")),
    ("prior_nan", "fit", lambda b: fit(b, "--prior", "nan")),
    ("seed_float", "fit", lambda b: fit(b, "--seed", "1.5")),
    ("multistart_0", "fit", lambda b: fit(b, "--multistart", "0")),
    ("unknown_option", "fit", lambda b: fit(b, "--bogus")),
    ("bound_inverted", "fit", lambda b: fit(b, "--bound", "x_guide_ry.stiffness=2:1")),
    ("study_missing", "fit", lambda b: fit(b, "--study", b.root / "nope.toml")),
    ("channels_twice", "sensitivity", lambda b: sens(b, "--channels", "x.x", "x.x")),
    ("band_outside", "sensitivity", lambda b: sens(b, "--band", "5000:6000")),
    ("scales_inverted", "sensitivity", lambda b: sens(b, "--scales", "2:1:0.1")),
    ("workers_0", "sensitivity", lambda b: sens(b, "--workers", "0")),
    ("band_outside", "diagnose", lambda b: diag(b, "--band", "5000:6000")),
    ("points_3", "diagnose", lambda b: diag(b, "--points", "3")),
    ("effects_unknown", "diagnose", lambda b: diag(b, "--effects", "nosuch")),
    ("channels_twice", "diagnose", lambda b: diag(b, "--channels", "x.x,x.x")),
    ("freq_1e300", "simulate", lambda b: sim(b, "--freq", "1:1e300:10")),
    ("freq_one_point", "simulate", lambda b: sim(b, "--freq", "1:10:1")),
    ("noise_nan", "simulate", lambda b: sim(b, "--noise", "nan")),
    ("q_1e300", "simulate", lambda b: sim(b, "--q", "x=1e300")),
    ("q_unknown_joint", "simulate", lambda b: sim(b, "--q", "nosuch=0.1")),
    ("out_txt", "simulate", lambda b: ["--model", str(b.model), "--out", str(b.out / "s.txt")]),
    ("mode_999", "modes", lambda b: modes(b, "--mode", "999")),
    ("amplitude_inf", "modes", lambda b: modes(b, "--amplitude", "inf")),
    ("amplitude_nan", "modes", lambda b: modes(b, "--amplitude", "nan")),
    ("q_nan", "modes", lambda b: modes(b, "--q", "x=nan")),
    ("version_typo", "modes", lambda b: modes(b, "--verison")),
    ("no_arguments", "report", lambda b: []),
    (
        "workers_0",
        "fleet",
        lambda b: [
            "--model",
            str(b.model),
            "--machines",
            str(b.root / "fleet"),
            "--out",
            str(b.out),
            "--workers",
            "0",
        ],
    ),
    (
        "machines_missing",
        "fleet",
        lambda b: [
            "--model",
            str(b.model),
            "--machines",
            str(b.root / "nope"),
            "--out",
            str(b.out),
        ],
    ),
]


# -- the report's inputs ----------------------------------------------------------------------


def _report_json(name: str, text: str) -> Argv:
    def argv(b: Sandbox) -> list[str]:
        (b.out).mkdir()
        (b.out / name).write_text(text)
        return [str(b.out)]

    return argv


def _report_special(kind: str) -> Argv:
    def argv(b: Sandbox) -> list[str]:
        b.out.mkdir()
        (b.out / "fit.json").write_text('{"status": "x", "parameters": []}')
        if kind == "fifo":
            os.mkfifo(b.out / "bode_x.png")
        else:
            (b.out / "bode_x.png").symlink_to(b.root / "sibling" / "victim.txt")
        return [str(b.out)]

    return argv


REPORT: list[tuple[str, Argv]] = [
    ("fit_json_list", _report_json("fit.json", "[1, 2, 3]")),
    ("fit_json_params_text", _report_json("fit.json", '{"status": "x", "parameters": "p"}')),
    ("modes_number", _report_json("modes.json", '{"modes": 3}')),
    (
        "diagnosis_verdict_list",
        _report_json("diagnosis.json", '{"gap": {}, "candidates": [], "verdict": [1]}'),
    ),
    ("sensitivity_params_object", _report_json("sensitivity.json", '{"parameters": {}}')),
    ("fleet_machines_text", _report_json("fleet.json", '{"machines": "m"}')),
    ("png_fifo", _report_special("fifo")),
    ("png_link_out", _report_special("link")),
    ("folder_missing", lambda b: [str(b.root / "nope")]),
    ("folder_is_file", lambda b: [str(b.data)]),
]


# -- output targets and planted manifests -----------------------------------------------------


def _planted(manifest: str, entries: str, command: str = "fit") -> Argv:
    def argv(b: Sandbox) -> list[str]:
        b.out.mkdir()
        (b.out / "fit.json").write_text('{"status": "x", "parameters": []}')
        (b.out / manifest).write_text(entries.replace("ROOT", str(b.root)))
        if command == "report":
            return [str(b.out)]
        return fit(b) if command == "fit" else modes(b)

    return argv


def _link_in_out(b: Sandbox) -> list[str]:
    """A complete fit folder whose stale plot was replaced by a link to a file outside."""
    shutil.copytree(b.root / "results", b.out)
    (b.out / "bode_q0.png").unlink()
    (b.out / "bode_q0.png").symlink_to(b.root / "sibling" / "victim.txt")
    return fit(b)


def _lock_link(b: Sandbox) -> list[str]:
    (b.root / ".out.bondid-lock").symlink_to(b.root / "sibling" / "victim.txt")
    return modes(b)


VICTIM = '{"files": [{"name": "NAME", "bytes": 10, "sha256": "0"}]}'


def _out_link_loop(b: Sandbox) -> list[str]:
    os.symlink(b.root / "out2", b.out)
    os.symlink(b.out, b.root / "out2")
    return modes(b)


def _out_dangling(b: Sandbox) -> list[str]:
    os.symlink(b.root / "nowhere", b.out)
    return modes(b)


def _out(argv: list[str], target: Path) -> list[str]:
    k = argv.index("--out")
    return [*argv[:k], "--out", str(target), *argv[k + 2 :]]


TARGETS: list[tuple[str, str, Argv, str]] = [
    ("out_link_loop", "modes", _out_link_loop, "bad"),
    ("out_dangling_link", "modes", _out_dangling, "bad"),
    ("out_is_a_file", "fit", lambda b: _out(fit(b), b.root / "sibling" / "victim.txt"), "bad"),
    ("out_is_the_data", "fit", lambda b: _out(fit(b), b.data), "bad"),
    ("out_under_a_file", "modes", lambda b: _out(modes(b), b.data / "x"), "bad"),
    (
        "manifest_traversal",
        "fit",
        _planted("fit.manifest.json", VICTIM.replace("NAME", "../sibling/victim.txt")),
        "bad",
    ),
    (
        "manifest_absolute",
        "fit",
        _planted("fit.manifest.json", VICTIM.replace("NAME", "ROOT/sibling/victim.txt")),
        "bad",
    ),
    (
        "manifest_users_file",
        "modes",
        _planted("modes.manifest.json", VICTIM.replace("NAME", "notes.txt")),
        "bad",
    ),
    ("manifest_not_json", "fit", _planted("fit.manifest.json", "{oops"), "bad"),
    (
        "report_manifest_traversal",
        "report",
        _planted("report.manifest.json", VICTIM.replace("NAME", "../sibling/victim.txt"), "report"),
        "bad",
    ),
    ("link_inside_out", "fit", _link_in_out, "ok"),
    ("lock_file_link", "modes", _lock_link, "bad"),
]


def _sibling_intact(box: Sandbox, run: Any) -> list[str]:
    v = box.root / "sibling" / "victim.txt"
    return [] if v.is_file() and v.read_text() == "must stay\n" else ["touched"]


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
    return [] if st.is_file() and '"ok"' in st.read_text() else ["wrong_exit"]


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
        "sigint_modes", "signals", "modes", lambda b: modes(b), "signal", signal.SIGINT, _after(1.5)
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
        b.extra["previous"] = {p.name: p.read_bytes() for p in out.iterdir()}
        st = os.statvfs(disk)
        with open(disk / "filler", "wb", buffering=0) as fh:
            fh.write(b"\0" * max(0, st.f_bavail * st.f_frsize - 24 * 1024))
        if command == "report":
            return [str(out)]
        if command == "simulate":
            return ["--model", str(b.model), "--out", str(disk / "s.csv"), "--freq", "1:4000:5000"]
        make = {"modes": modes, "fit": fit, "sensitivity": sens}[command]
        return _out(make(b), out)

    return argv


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


def _all_cases() -> list[Case]:
    cases = [_data_case(n, "fit") for n in DATA_BAD]
    cases += [
        _data_case(n, c)
        for n in ("fifo", "link_loop", "freq_1e300", "binary")
        for c in ("sensitivity", "diagnose")
    ]
    cases += [_model_case(n, "modes") for n in MODEL_BAD]
    cases += [
        _model_case(n, c)
        for n in (
            "fifo",
            "deep_200k",
            "chain_3000",
            "spring_1e300",
            "mass_1e-300",
            "limits_inverted",
        )
        for c in ("fit", "simulate")
    ]
    cases += [Case(f"{n}-{c}", "bad options", c, a) for n, c, a in OPTIONS]
    cases += [Case(f"{n}-report", "report inputs", "report", a) for n, a in REPORT]
    cases += [
        Case(n, "out and manifests", c, a, e, check=_sibling_intact) for n, c, a, e in TARGETS
    ]
    return cases + SIGNALS + DISK + KILLS


CASES = _all_cases()
assert len({c.name for c in CASES}) == len(CASES), "case names must be unique"
