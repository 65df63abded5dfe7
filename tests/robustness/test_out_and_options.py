"""``--out`` is checked before any work in all six commands and never replaces an input
(issue 16, points 1 and 4); bad option values are refused the same way (point 6)."""

from __future__ import annotations

import json
import shutil

import pytest

from .conftest import fast_args, one_line_reason, sha

FOLDER_COMMANDS = ("fit", "sensitivity", "diagnose", "modes")


def _report_args(results, out):
    return [results, "--out", out]


# case → builder(tmp, inputs) → (out path, words of the reason)
OUT_CASES = {
    "unwritable": lambda t, i: ("/proc/bondid_out", ("not writable",)),
    "under_a_file": lambda t, i: (i["d0"] / "sub", ("is a file",)),
    "existing_file": lambda t, i: (_touch(t / "plain.txt"), ("existing file",)),
    "the_data_file": lambda t, i: (i["d0"], ("input",)),
    "the_model_file": lambda t, i: (i["model"], ("input",)),
}


def _touch(p):
    p.write_text("keep me\n")
    return p


@pytest.mark.parametrize("case", list(OUT_CASES))
@pytest.mark.parametrize("command", [*FOLDER_COMMANDS, "report"])
def test_bad_out_refused_before_any_work(command, case, inputs, run, tmp_path):
    out, words = OUT_CASES[case](tmp_path, inputs)
    before = {p: sha(p) for p in (inputs["model"], inputs["d0"])}
    if command == "report":
        results = tmp_path / "results"
        results.mkdir()
        (results / "fit.json").write_text("{}")
        argv = _report_args(results, out)
    else:
        argv = fast_args(command, inputs["model"], [inputs["d0"]], out)
    code, stdout, err = run(command, *argv)
    assert code == 2, err
    reason = one_line_reason(err)
    assert str(out) in reason or out.name in reason
    for w in words:
        assert w in reason, reason
    assert stdout == ""  # nothing computed, nothing printed
    assert {p: sha(p) for p in before} == before


@pytest.mark.parametrize("case", ["unwritable", "under_a_file", "the_model_file"])
def test_simulate_bad_out(case, inputs, run, tmp_path):
    out, _ = OUT_CASES[case](tmp_path, inputs)
    if case == "unwritable":
        out = "/proc/bondid.csv"
    code, _, err = run("simulate", "--model", inputs["model"], "--out", out)
    assert code == 2 and one_line_reason(err)


@pytest.mark.parametrize(
    ("command", "name"),
    [("diagnose", "refit.urdf"), ("fit", "fitted.urdf"), ("modes", "modes.json")],
)
def test_an_input_inside_out_under_an_output_name_is_refused(command, name, inputs, run, tmp_path):
    out = tmp_path / "OUT"
    out.mkdir()
    model = out / name
    shutil.copy(inputs["model"], model)
    digest = sha(model)
    code, _, err = run(command, *fast_args(command, model, [inputs["d0"]], out))
    assert code == 2 and "input" in one_line_reason(err)
    assert sha(model) == digest


# option → (command, extra argv, words of the reason)
OPTION_CASES = {
    "weight_unknown_channel": ("fit", ["--weight", "q.q=2"], ("q.q", "not in the data")),
    "weight_infinite": ("fit", ["--weight", "x.x=inf"], ("--weight", "finite")),
    "workers_0_fit": ("fit", ["--workers", "0"], ("--workers 0", ">= 1")),
    "workers_0_sensitivity": ("sensitivity", ["--workers", "0"], ("--workers 0", ">= 1")),
    "workers_0_diagnose": ("diagnose", ["--workers", "0"], ("--workers 0", ">= 1")),
    "seed_negative_fit": ("fit", ["--seed", "-1"], ("--seed -1",)),
    "seed_negative_simulate": ("simulate", ["--seed", "-1"], ("--seed -1",)),
    "noise_nan": ("simulate", ["--noise", "nan"], ("--noise nan",)),
    "noise_negative": ("simulate", ["--noise", "-0.1"], ("--noise",)),
    "floor_above_signal": ("simulate", ["--floor-db", "30"], ("--floor-db", "negative")),
    "freq_huge": ("simulate", ["--freq", "1:4000:1e11"], ("--freq", "100000")),
    "freq_inf": ("simulate", ["--freq", "1:inf:10"], ("--freq",)),
    "plot_not_an_image": ("simulate", ["--plot", "x.csv"], ("--plot", ".png")),
    "bound_inverted": ("fit", ["--bound", "x_guide_ry.stiffness=2:1"], ("x_guide_ry",)),
    "points_too_few": ("diagnose", ["--points", "3"], ("--points",)),
}


@pytest.mark.parametrize("case", list(OPTION_CASES))
def test_bad_option_refused(case, inputs, run, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    command, extra, words = OPTION_CASES[case]
    out = tmp_path / ("sim.csv" if command == "simulate" else "out")
    code, _, err = run(command, *fast_args(command, inputs["model"], [inputs["d0"]], out), *extra)
    assert code == 2, err
    reason = one_line_reason(err)
    for w in words:
        assert w in reason, reason
    assert not out.exists() and not (tmp_path / "x.csv").exists()


def test_bound_that_clips_the_start_is_reported(inputs, run, tmp_path):
    out = tmp_path / "fit"
    argv = [*fast_args("fit", inputs["model"], [inputs["d0"]], out),
            "--bound", "x_guide_ry.stiffness=1000:2000"]  # fmt: skip
    code, stdout, err = run("fit", *argv)
    assert code in (0, 1), err
    fit = json.loads((out / "fit.json").read_text())
    p = fit["parameters"][0]
    assert p["initial"] == 2000.0 and p["upper"] == 2000.0  # the start the fit really used
    assert any("outside the bounds" in w for w in fit["warnings"])
    assert "warning:" in stdout and "outside the bounds" in stdout


def test_report_names_the_results_folder_not_out(inputs, run, tmp_path):
    code, _, err = run("report", inputs["d0"])
    reason = one_line_reason(err)
    assert code == 2 and str(inputs["d0"]) in reason and "--out" not in reason


def test_report_never_embeds_a_truncated_png(run, tmp_path):
    res = tmp_path / "r"
    res.mkdir()
    (res / "fit.json").write_text(json.dumps({"status": "x", "parameters": []}))
    (res / "bode_a.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 50)  # killed mid-write
    code, _, err = run("report", res)
    assert code == 0
    page = (res / "report.html").read_text()
    assert "truncated PNG" in page and "data:image/png" not in page
    assert "bode_a.png" in err
