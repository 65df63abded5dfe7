"""The cases of ``tools/sweep_inputs.py``: the inputs a hostile or unlucky user gives every
command (bad data files and models, bad options, a results folder of the wrong shape, bad
output targets and planted manifests), and with ``sweep_events.py`` every case (``CASES``)."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sweep_events import DISK, KILLS, SIGNALS
from sweep_sandbox import (
    Argv,
    Case,
    Sandbox,
    diag,
    first_row,
    fit,
    modes,
    sens,
    set_cell,
    sim,
    with_out,
)

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
    ("noise_inf", "sensitivity", lambda b: sens(b, "--noise", "inf")),
    ("max_rel_std_negative", "sensitivity", lambda b: sens(b, "--max-rel-std", "-1")),
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
        elif kind == "manifest_fifo":
            os.mkfifo(b.out / "diagnose.manifest.json")
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
    ("manifest_fifo", _report_special("manifest_fifo")),
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


TARGETS: list[tuple[str, str, Argv, str]] = [
    ("out_link_loop", "modes", _out_link_loop, "bad"),
    ("out_dangling_link", "modes", _out_dangling, "bad"),
    ("out_is_a_file", "fit", lambda b: with_out(fit(b), b.root / "sibling" / "victim.txt"), "bad"),
    ("out_is_the_data", "fit", lambda b: with_out(fit(b), b.data), "bad"),
    ("out_under_a_file", "modes", lambda b: with_out(modes(b), b.data / "x"), "bad"),
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
