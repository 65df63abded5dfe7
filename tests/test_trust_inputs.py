"""Input checks before any work: each bad input is refused with exit 2 and ONE line naming
the file or option, the item and what is valid (issue 61)."""

from __future__ import annotations

import os
import re

import pytest
from trust_common import fast_argv, make_inputs, only_line, runner

from bondid.ranges import MAX_CHAIN_DEPTH, MAX_XML_DEPTH

DATA_COMMANDS = ("fit", "sensitivity", "diagnose")


@pytest.fixture(scope="module")
def trust_inputs(tmp_path_factory):
    return make_inputs(tmp_path_factory)


@pytest.fixture
def run_cmd(capsys):
    return runner(capsys)


def _special(kind: str, tmp_path):
    """A path that is not a regular file: FIFO, folder, link loop, dangling link."""
    p = tmp_path / f"{kind}.csv"
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "folder":
        p.mkdir()
    elif kind == "loop":
        os.symlink(tmp_path / "loop2.csv", p)
        os.symlink(p, tmp_path / "loop2.csv")
    elif kind == "dangling":
        os.symlink(tmp_path / "nowhere.csv", p)
    return p


WORDS = {"fifo": "FIFO", "folder": "a folder", "loop": "loop", "dangling": "does not exist"}


@pytest.mark.parametrize("kind", list(WORDS))
@pytest.mark.parametrize("command", DATA_COMMANDS)
def test_a_non_regular_data_file_is_refused_at_once(command, kind, trust_inputs, run_cmd, tmp_path):
    """A FIFO as --data blocked fit, sensitivity and diagnose for good."""
    bad = _special(kind, tmp_path)
    out = tmp_path / "out"
    code, stdout, err = run_cmd(command, *fast_argv(command, trust_inputs["model"], bad, out))
    line = only_line(err)
    assert code == 2 and "--data" in line and str(bad) in line and WORDS[kind] in line, line
    assert stdout == "" and not out.exists()
    assert not [n for n in os.listdir(tmp_path) if ".bondid-" in n]  # no lock, no staging


@pytest.mark.parametrize("kind", ["fifo", "loop"])
def test_a_non_regular_model_is_refused(kind, trust_inputs, run_cmd, tmp_path):
    bad = _special(kind, tmp_path).rename(tmp_path / f"{kind}.urdf")
    code, _, err = run_cmd("modes", "--model", bad, "--no-html")
    line = only_line(err)
    assert code == 2 and "--model" in line and WORDS[kind] in line


def test_a_link_loop_as_out_is_refused(trust_inputs, run_cmd, tmp_path):
    out = _special("loop", tmp_path)
    for command in ("modes", "fit"):
        code, _, err = run_cmd(command, *fast_argv(command, trust_inputs["model"],
                                                   trust_inputs["data"], out))  # fmt: skip
        line = only_line(err)
        assert code == 2 and "--out" in line and "loop" in line


def test_an_unreadable_file_is_refused(monkeypatch, tmp_path):
    """(As root every file is readable, so the refusal of ``open`` is simulated.)"""
    import errno

    from bondid.exceptions import ConfigError
    from bondid.paths import check_input_file

    p = tmp_path / "d.csv"
    p.write_text("x")
    real = os.open

    def denied(path, flags, *a):
        if str(path) == str(p):
            raise PermissionError(errno.EACCES, "Permission denied")
        return real(path, flags, *a)

    monkeypatch.setattr(os, "open", denied)
    with pytest.raises(ConfigError, match=r"--data .*d\.csv: cannot be read \(permission denied\)"):
        check_input_file(p, "--data")


def _bonder(trust_inputs) -> str:
    return trust_inputs["model"].read_text()


def _model(tmp_path, text: str, name: str = "m.urdf"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_deep_xml_is_refused_before_parsing(trust_inputs, run_cmd, tmp_path):
    """200,000 nested elements crashed the process (exit -11) in a deep copy."""
    n = 200_000
    deep = _bonder(trust_inputs).replace(
        "</robot>", "<gazebo>" + "<a>" * n + "</a>" * n + "</gazebo></robot>"
    )
    model = _model(tmp_path, deep)
    code, _, err = run_cmd("modes", "--model", model, "--no-html")
    line = only_line(err)
    assert code == 2 and str(model) in line and f"at most {MAX_XML_DEPTH}" in line


def _chain(text: str, n: int, kind: str = "fixed") -> str:
    parts, prev = [], "z_bearing_rz_moving"
    inert = ('<inertial><mass value="0.001"/><inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6"'
             ' iyz="0" izz="1e-6"/></inertial>')  # fmt: skip
    for i in range(n):
        parts.append(f'<link name="c{i}">{inert}</link><joint name="cj{i}" type="{kind}">'
                     f'<parent link="{prev}"/><child link="c{i}"/></joint>')  # fmt: skip
        prev = f"c{i}"
    return text.replace("</robot>", "\n".join(parts) + "</robot>")


def test_a_long_chain_is_refused_and_a_shorter_one_runs(trust_inputs, run_cmd, tmp_path):
    """3,000 fixed links exhausted Python's recursion (a 2,973-line traceback)."""
    model = _model(tmp_path, _chain(_bonder(trust_inputs), 3000))
    code, _, err = run_cmd("modes", "--model", model, "--no-html")
    line = only_line(err)
    assert code == 2 and f"at most {MAX_CHAIN_DEPTH} links" in line and "3016" in line
    ok = _model(tmp_path, _chain(_bonder(trust_inputs), 300), "ok.urdf")
    code, _, err = run_cmd("modes", "--model", ok, "--no-html")
    assert code == 0, err
    assert "Traceback" not in err


MAGNITUDES = {
    # case → (pattern, replacement, words of the reason)
    "spring_1e300": (r"<springStiffness>200000<", "<springStiffness>1e300<",
                     ("x_guide_ry", "springStiffness", "1e+300", "1e+15")),
    "mass_1e-300": (r'<mass value="1.67"/>', '<mass value="1e-300"/>',
                    ("x_stage", "mass", "1e-300", "from 1e-09 to 1e+09 kg")),
    "mass_1e300": (r'<mass value="1.67"/>', '<mass value="1e300"/>', ("x_stage", "mass")),
    "origin_1e300": (r'<origin xyz="0 0 0.155" rpy="0 0 0"/>',
                     '<origin xyz="1e300 0 0.155" rpy="0 0 0"/>',
                     ("joint 'x'", "origin x", "1e+300", "coordinate")),
    "inertia_1e300": (r'ixx="0.00581" (ixy="[^"]*" ixz="[^"]*") iyy="[^"]*" (iyz="[^"]*")'
                      r' izz="[^"]*"', r'ixx="1e300" \1 iyy="1e300" \2 izz="1e300"',
                      ("x_stage", "moment of inertia", "1e+12")),
    "damping_1e300": (r'damping="1.6"', 'damping="1e300"', ("x_guide_ry", "damping")),
    "limits_inverted": (r'<limit lower="-0.1" upper="0.1"', '<limit lower="0.1" upper="-0.1"',
                        ("joint 'x'", "lower 0.1 > upper -0.1")),
    "box_1e300": (r'<box size="0.5 0.4 0.12"/>', '<box size="1e300 0.4 0.12"/>',
                  ("base", "box size")),
}  # fmt: skip


@pytest.mark.parametrize("case", list(MAGNITUDES))
def test_absurd_magnitudes_are_refused_naming_item_and_range(case, trust_inputs, run_cmd,
                                                             tmp_path):  # fmt: skip
    pattern, repl, words = MAGNITUDES[case]
    text, n = re.subn(pattern, repl, _bonder(trust_inputs), count=1)
    assert n == 1
    model = _model(tmp_path, text)
    for command in ("modes", "fit"):
        argv = fast_argv(command, model, trust_inputs["data"], tmp_path / "out")
        code, _, err = run_cmd(command, *argv)
        line = only_line(err)
        assert code == 2 and str(model) in line, line
        for w in words:
            assert w in line, line
        assert not (tmp_path / "out").exists()


def test_urdfdoms_own_lines_are_folded_into_ours(trust_inputs, run_cmd, tmp_path):
    text = re.sub(r'(<joint name="x_guide_ry" type="revolute">.*?)<limit[^>]*/>', r"\1",
                  _bonder(trust_inputs), count=1, flags=re.S)  # fmt: skip
    model = _model(tmp_path, text)
    fd2 = tmp_path / "fd2.txt"
    saved = os.dup(2)
    with open(fd2, "wb") as sink:  # what reaches file descriptor 2 itself
        os.dup2(sink.fileno(), 2)
        try:
            code, _, err = run_cmd("modes", "--model", model, "--no-html")
        finally:
            os.dup2(saved, 2)
            os.close(saved)
    native = fd2.read_text()
    line = only_line(err)
    assert code == 2 and "does not specify limits" in line and "joint.cpp" not in line
    assert native.strip() == ""


def test_a_frequency_beyond_any_instrument_is_refused(trust_inputs, run_cmd, tmp_path):
    lines = trust_inputs["data"].read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln[:1].isdigit())
    last = len(lines) - 1
    cells = lines[last].split(",")
    cells[0] = "1e300"
    lines[last] = ",".join(cells)
    data = tmp_path / "d.csv"
    data.write_text("\n".join(lines) + "\n")
    assert k < last
    code, _, err = run_cmd("fit", *fast_argv("fit", trust_inputs["model"], data))
    line = only_line(err)
    assert code == 2 and str(data) in line and "frequency 1e+300 Hz" in line
    assert "1e+06 Hz" in line


@pytest.mark.parametrize(
    ("command", "extra", "words"),
    [
        ("fit", ["--channels", "x.x,x.x"], ("--channels", "x.x is given twice")),
        ("diagnose", ["--channels", "x.x,x.x"], ("--channels", "given twice")),
        ("sensitivity", ["--channels", "x.x", "x.x"], ("--channels", "given twice")),
        ("fit", ["--band", "5000:6000"], ("--band 5000:6000", "no frequency line", "5–3000")),
        ("sensitivity", ["--band", "5000:6000"], ("--band 5000:6000",)),
        ("diagnose", ["--band", "5000:6000"], ("--band 5000:6000",)),
        ("fit", ["--band", "1:1e300"], ("--band", "1e+06 Hz")),
        ("fit", ["--max-iter", "99999999999999999999"], ("--max-iter", "out of range")),
        ("fit", ["--seed", "-99999999999999999999"], ("--seed", "out of range")),
        ("diagnose", ["--points", "1e3"], ("--points", "not an integer")),
        ("fit", ["--bogus"], ("unrecognized arguments: --bogus", "--help")),
        ("modes", ["--q", "x=1e300"], ("--q", "x = 1e+300", "position")),
        ("simulate", ["--freq", "1:1e300:10"], ("--freq", "1e+06 Hz")),
    ],
)
def test_bad_options_are_refused_in_one_line(command, extra, words, trust_inputs, run_cmd,
                                             tmp_path):  # fmt: skip
    out = tmp_path / ("sim.csv" if command == "simulate" else "out")
    argv = fast_argv(command, trust_inputs["model"], trust_inputs["data"], out)
    code, _, err = run_cmd(command, *argv, *extra)
    line = only_line(err)
    assert code == 2, err
    for w in words:
        assert w in line, line
    assert not out.exists()


@pytest.mark.parametrize("command", [*DATA_COMMANDS, "modes", "simulate", "report", "fleet"])
def test_every_command_prints_its_version_and_one_line_usage_errors(command, run_cmd):
    import bondid

    code, stdout, err = run_cmd(command, "--version")
    assert code == 0 and stdout.strip() == f"bondid {bondid.__version__}"
    code, _, err = run_cmd(command, "--no-such-option")
    line = only_line(err)
    assert code == 2 and line.startswith(f"python -m bondid.{command}: bad input:")
    assert line.endswith(f"see python -m bondid.{command} --help")


REPORT_SHAPES = {
    "fit.json": ("[1, 2, 3]", "the file is a list"),
    "modes.json": ('{"modes": 3}', "key 'modes' is an integer"),
    "diagnosis.json": ('{"gap": {}, "candidates": [], "verdict": []}', "key 'verdict' is a list"),
    "sensitivity.json": ('{"parameters": {"a": 1}}', "key 'parameters' is a JSON object"),
}


@pytest.mark.parametrize("name", list(REPORT_SHAPES))
def test_report_refuses_json_of_the_wrong_shape(name, run_cmd, tmp_path):
    res = tmp_path / "r"
    res.mkdir()
    text, words = REPORT_SHAPES[name]
    (res / name).write_text(text)
    code, _, err = run_cmd("report", res)
    line = only_line(err)
    assert code == 2 and str(res / name) in line and words in line, line
    assert not (res / "report.html").exists()


def test_report_refuses_a_link_out_of_the_folder_and_a_fifo(run_cmd, tmp_path):
    res = tmp_path / "r"
    res.mkdir()
    (res / "fit.json").write_text('{"status": "x", "parameters": []}')
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"\x89PNG")
    (res / "bode_x.png").symlink_to(secret)
    code, _, err = run_cmd("report", res)
    assert code == 2 and "outside the results folder" in only_line(err)
    (res / "bode_x.png").unlink()
    os.mkfifo(res / "bode_x.png")
    code, _, err = run_cmd("report", res)
    assert code == 2 and "not a regular file" in only_line(err)
    (res / "bode_x.png").unlink()
    os.mkfifo(res / "sensitivity.manifest.json")  # the report reads every manifest
    code, _, err = run_cmd("report", res)
    assert code == 2 and "not a regular file" in only_line(err)
