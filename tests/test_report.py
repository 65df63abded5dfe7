"""The offline report: spec keys become tables, PNGs are embedded, nothing is fetched."""

from __future__ import annotations

import base64
import io
import json
import re
from pathlib import Path

import pytest
from models import one_mass

from bondid.linear import build_affine_model
from bondid.modes import modal_analysis
from bondid.report.__main__ import main as report_main

FIT = {
    "status": "Solve_Succeeded",
    "cost_initial": 12.5,
    "cost_final": 0.125,
    "cost_name": "db_rms_squared",
    "iterations": 17,
    "wall_s": 3.2,
    "parameters": [
        {
            "name": "x_stage.mass",
            "initial": 1.67,
            "fitted": 1.71,
            "lower": 0.5,
            "upper": 5.0,
            "std": 0.01,
        },
        {
            "name": "x_guide_ty.stiffness",
            "initial": 5e7,
            "fitted": 1e8,
            "lower": 1e6,
            "upper": 1e8,
            "std": None,
        },
    ],
}
DIAGNOSIS = {
    "gap": {
        "db_rms": 4.2,
        "by_channel": {"x.x": 3.1, "y.y": 5.0},
        "by_band": [
            {"f_lo_hz": 1.0, "f_hi_hz": 100.0, "db_rms": 0.4},
            {"f_lo_hz": 100.0, "f_hi_hz": 4000.0, "db_rms": 6.6},
        ],
        "modes": [
            {"f_measured_hz": 480.0, "f_model_hz": None, "status": "missing"},
            {"f_measured_hz": 12.4, "f_model_hz": 12.5, "status": "paired"},
        ],
    },
    "candidates": [
        {
            "effect": "soft_mounts",
            "location": "base",
            "parameters": {"k_z": 3.1e6},
            "db_rms_after": 0.9,
            "gap_closed": 0.786,
            "heldout_db_rms_after": 1.1,
            "score": 0.7,
        },
        {
            "effect": "sensor_delay",
            "location": "x.x",
            "parameters": {"tau_s": 2e-5},
            "db_rms_after": 3.9,
            "gap_closed": 0.07,
            "heldout_db_rms_after": 4.0,
            "score": 0.05,
        },
    ],
    "verdict": {"effect": "soft_mounts", "location": "base", "gap_closed": 0.786},
}


SENSITIVITY = {
    "parameters": [
        {"name": "x_stage.mass", "kind": "mass", "overall": 15.9, "std_alone": 0.01,
         "std_all": 0.025, "recommended": True},
        {"name": "x_stage.com.x", "kind": "com", "overall": 0.0, "std_alone": None,
         "std_all": None, "recommended": False},
    ],
    "bands": [{"label": "R 12.4 Hz", "f_lo_hz": 10.0, "f_hi_hz": 15.0, "class": "resonance",
               "top": [{"name": "x_stage.mass", "sensitivity": 15.9004}]}],
    "identifiability": {"noise": 0.5, "noise_estimated": True, "max_rel_std": 0.1,
                        "n_identifiable": 1, "n_parameters": 2, "combinations": [],
                        "recommended": [{"name": "x_stage.mass", "std": 0.025}]},
}  # fmt: skip


def _png(color: tuple[int, int, int]) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (8, 6), color).save(buf, format="PNG")
    return buf.getvalue()


def _run(argv) -> int:
    try:
        return report_main([str(a) for a in argv])
    except SystemExit as exc:
        return int(exc.code or 0)


@pytest.fixture
def results(tmp_path: Path) -> Path:
    res = tmp_path / "results"
    (res / "fit").mkdir(parents=True)
    (res / "fit" / "fit.json").write_text(json.dumps(FIT))
    (res / "fit" / "bode_x.x.png").write_bytes(_png((255, 0, 0)))
    (res / "fit" / "convergence.png").write_bytes(_png((0, 255, 0)))
    (res / "sensitivity.json").write_text(json.dumps(SENSITIVITY))
    (res / "sensitivity_heatmap.png").write_bytes(_png((0, 0, 255)))
    (res / "diagnosis.json").write_text(json.dumps(DIAGNOSIS))
    (res / "residual_map.png").write_bytes(_png((9, 9, 9)))
    lm = build_affine_model(one_mass(2.0, 8e3, 4.0), {}).linear_model()
    modal = modal_analysis(lm, {})
    modal.html[1] = "mode_01.html"
    (res / "modes").mkdir()
    (res / "modes" / "modes.json").write_text(modal.to_json())
    (res / "modes" / "mode_01.html").write_text("<html></html>")
    (res / "modes" / "modes.html").write_text("<html></html>")
    return res


def test_report_has_tables_images_and_no_network(results: Path, tmp_path: Path):
    out = tmp_path / "out"
    assert _run([results, "--out", out, "--quiet"]) == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    # fit summary and parameter table, the at-bound row flagged
    assert "Solve_Succeeded" in page and "x_guide_ty.stiffness" in page
    assert re.search(r'<tr class="flag"><td class="l">x_guide_ty\.stiffness', page)
    assert "12.5 → 0.125" in page  # the cost before → after
    # diagnosis: verdict on the first screen (no outcome field: an effect = explained)
    card = page[page.index('id="diagnosis-headline"') : page.index('id="fit"')]
    assert "Explained: soft_mounts at base" in card and "78.6 %" in card
    assert '<td class="l">y.y</td><td>5</td>' in page
    assert "6.6" in page and "missing" in page and "sensor_delay" in page
    # one effect and nothing dropped: no effect tables (the verdict says it)
    assert "in the order added" not in page and "dropped as redundant" not in page


def test_report_lists_the_effects_and_the_dropped_one(results: Path, tmp_path: Path):
    """Two effects kept and one dropped by the backward elimination: both tables, in order."""
    diag = dict(DIAGNOSIS)
    diag["effects"] = [
        {"step": 2, "effect": "joint_compliance", "location": "a->b:tz", "db_rms_after": 1.39,
         "gap_closed": 0.54},
        {"step": 3, "effect": "flexible_base", "location": "bed", "db_rms_after": 0.935,
         "gap_closed": 0.69},
    ]  # fmt: skip
    diag["dropped"] = [{"step": 1, "effect": "joint_compliance", "location": "a->b:rz",
                        "score_with": 0.815, "score_without": 0.831}]  # fmt: skip
    (results / "diagnosis.json").write_text(json.dumps(diag))
    out = tmp_path / "out"
    assert _run([results, "--out", out, "--quiet"]) == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    kept = page.index("in the order added")
    first, second = page.index("a-&gt;b:tz", kept), page.index("flexible_base", kept)
    assert kept < first < second and "69.0 %" in page
    gone = page.index("dropped as redundant")
    assert gone > second and page.index("a-&gt;b:rz", gone) > gone
    assert "0.831" in page[gone:] and "0.815" in page[gone:]
    # sensitivity: readable tables, no dict reprs
    assert "Recommended free parameters (1)" in page and "2.5 %" in page
    assert "resonance 12.4 Hz" in page and "{'" not in page
    # modes: the frequency of the one-mass model and relative links to the animations
    f_hz = (8e3 / 2.0) ** 0.5 / (2 * 3.141592653589793)
    assert f"{f_hz:.6g}" in page
    assert 'href="../results/modes/mode_01.html"' in page
    assert 'href="../results/modes/modes.html"' in page
    # every PNG embedded byte for byte
    blobs = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    pngs = sorted(p.read_bytes() for p in results.rglob("*.png"))
    assert sorted(base64.b64decode(b) for b in blobs) == pngs
    # offline: nothing external
    assert "http://" not in page and "https://" not in page
    assert "<script" not in page and "<link" not in page and "@import" not in page


def test_report_missing_parts_noted(tmp_path: Path):
    res = tmp_path / "r"
    res.mkdir()
    (res / "fit.json").write_text("{not json")
    (res / "extra").mkdir()  # a PNG no command's manifest lists, apart from any result file
    (res / "extra" / "plot.png").write_bytes(_png((1, 2, 3)))
    assert _run([res]) == 0  # default --out: the results folder itself
    page = (res / "report.html").read_text(encoding="utf-8")
    assert "could not read fit.json" in page
    assert "diagnosis.json not found" in page and "modes.json not found" in page
    assert "Other plots" in page and page.count("data:image/png;base64,") == 1
    # the form, ``bondid.report --out DIR``, reports on DIR itself
    (res / "report.html").unlink()
    assert _run(["--out", res, "--quiet"]) == 0
    assert (res / "report.html").read_text(encoding="utf-8") == page


def test_report_bad_input_exit_2(tmp_path: Path, capsys):
    assert _run([]) == 2  # neither RESULTS_DIR nor --out
    capsys.readouterr()
    assert _run([tmp_path / "nope"]) == 2
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _run([empty]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("bad input:") for line in err)
    assert not (empty / "report.html").exists()
