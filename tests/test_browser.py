"""The static mode page rendered by headless Chromium, as a person would open it (offline).

Chromium runs with software WebGL (SwiftShader) and every background network feature off;
the page is opened from a file:// URL. Skipped only when no chromium binary is installed.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from bondid.modes.__main__ import main as modes_main

pytestmark = pytest.mark.browser

BONDER = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"
FLAGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--window-size=1200,900",
]


def _chromium() -> str:
    exe = shutil.which("chromium") or (
        "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None
    )
    if exe is None:
        pytest.skip("chromium is not installed (apt-get install chromium)")
    return exe


def _screenshot(exe: str, page: Path, png: Path, budget_ms: int, profile: Path) -> np.ndarray:
    from PIL import Image

    cmd = [
        exe,
        *FLAGS,
        f"--user-data-dir={profile}",
        f"--virtual-time-budget={budget_ms}",
        f"--screenshot={png}",
        page.resolve().as_uri(),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert png.is_file(), (
        f"chromium wrote no screenshot (rc {proc.returncode}): {proc.stderr[-800:]}"
    )
    return np.asarray(Image.open(png).convert("RGB")).astype(int)


def _empty_scene(path: Path) -> None:
    from bondid.modes.viewer import ModeScene

    with ModeScene() as scene:
        scene.viewer["/Grid"].set_property("visible", False)
        scene.viewer["/Axes"].set_property("visible", False)
        path.write_text(scene.static_html("empty"), encoding="utf-8")


@pytest.mark.slow
def test_static_mode_page_renders_the_machine(tmp_path: Path):
    exe = _chromium()
    out = tmp_path / "res"
    code = modes_main(
        [
            "--model",
            str(BONDER),
            "--out",
            str(out),
            "--quiet",
            "--mode",
            "7",
            "--amplitude",
            "0.08",
            "--fitted",
            str(BONDER),
        ]
    )
    assert code == 0
    _empty_scene(tmp_path / "empty.html")

    shot = _screenshot(exe, out / "modes.html", tmp_path / "modes.png", 5000, tmp_path / "p1")
    later = _screenshot(exe, out / "modes.html", tmp_path / "later.png", 5600, tmp_path / "p2")
    empty = _screenshot(exe, tmp_path / "empty.html", tmp_path / "empty.png", 2000, tmp_path / "p3")
    assert shot.shape == (900, 1200, 3) and empty.shape == shot.shape

    # non-blank: not one flat colour
    assert shot.std() > 10
    # the machine covers a real part of the view: pixels that differ from the empty scene
    # (same background gradient) — excluding the caption box at the top left
    diff = np.abs(shot - empty).sum(axis=2) > 40
    diff[:120, :700] = False
    frac = diff.mean()
    assert 0.03 < frac < 0.8, f"machine covers {frac:.1%} of the view"
    # its colours: the red x-stage (URDF 0.8 0.15 0.15) and the orange fitted machine
    r, g, b = shot[..., 0], shot[..., 1], shot[..., 2]
    red = (r > 140) & (g < 70) & (b < 70)
    orange = (r > 180) & (g > 90) & (g < 190) & (b < 70)
    assert red.sum() > 500, f"only {red.sum()} red pixels"
    assert orange.sum() > 2000, f"only {orange.sum()} orange pixels"
    # the mode is animated: 0.6 s later (virtual time) the machines have moved
    moved = (np.abs(later - shot).sum(axis=2) > 40).sum()
    assert moved > 300, f"only {moved} pixels changed between frames"


REPORT_FIT = {
    "status": "Solve_Succeeded", "success": True, "iterations": 94, "wall_s": 49.2,
    "cost_name": "complex_log_l2", "cost_initial": 53.1, "cost_final": 0.243,
    "parameters": [
        {"name": "x_stage.mass", "unit": "kg", "initial": 1.67, "fitted": 2.13, "lower": 0.8,
         "upper": 2.5, "std": 0.0015},
        {"name": "x_stage.inertia.ixx", "unit": "kg·m²", "initial": 0.0058, "fitted": 0.0049,
         "lower": 0.0029, "upper": 0.0087, "std": None},
    ],
    "db_rms": {"initial": 7.289, "final": 0.493, "noise_level": 0.508, "weighting": "auto",
               "by_dataset": [{"file": "data/q0.csv",
                               "by_channel": {"x.x": {"initial": 6.9, "final": 0.18}}}]},
    "channels_by_file": [{"file": "data/q0.csv", "used": ["x.x"], "left_out": {"y.x": 0.0}}],
}  # fmt: skip
REPORT_DIAGNOSIS = {
    "gap": {"db_rms": 2.4, "by_channel": {"x.x": 1.2, "x.y": 3.9},
            "by_band": [{"f_lo_hz": 300.0, "f_hi_hz": 600.0, "db_rms": 4.1}]},
    "candidates": [{"effect": "soft_mounts", "location": "base", "parameters": {"k_z": 3e6},
                    "db_rms_after": 2.3, "gap_closed": 0.04}],
    "verdict": {"effect": "none", "location": None, "gap_closed": 0.0,
                "outcome": "unexplained", "reason": "no candidate passes the rule"},
    "remainder": [{"kind": "missing_mode", "text": "a mode near 480 Hz in x.y is in no model"}],
}  # fmt: skip


def _runs(mask: np.ndarray) -> int:
    """The longest vertical run of True pixels in any column of ``mask``."""
    best = 0
    for col in mask.T:
        run = 0
        for v in col:
            run = run + 1 if v else 0
            best = max(best, run)
    return best


def test_report_first_screen_leads_with_the_answer(tmp_path: Path):
    """The report as a person opens it: the fit's and the diagnosis's cards (green = at the
    noise level, red = not explained) on the first screen, above everything else; no Python
    dict in any table cell. Layout, not pixels: the cards' coloured edges are found."""
    import json
    from html.parser import HTMLParser

    from bondid.report.build import build_report

    exe = _chromium()
    res = tmp_path / "res"
    (res / "diag").mkdir(parents=True)
    (res / "fit.json").write_text(json.dumps(REPORT_FIT))
    (res / "diag" / "diagnosis.json").write_text(json.dumps(REPORT_DIAGNOSIS))
    page = build_report(res)
    shot = _screenshot(exe, page, tmp_path / "report.png", 1000, tmp_path / "p4")
    assert shot.shape == (900, 1200, 3)
    r, g, b = shot[..., 0], shot[..., 1], shot[..., 2]
    green = (abs(r - 0x33) < 30) & (abs(g - 0xAA) < 30) & (abs(b - 0x33) < 30)
    red = (abs(r - 0xCC) < 30) & (abs(g - 0x33) < 30) & (abs(b - 0x33) < 30)
    assert _runs(green[:600]) > 80, "no fit card on the first screen"
    assert _runs(red[:600]) > 80, "no diagnosis card on the first screen"
    # the cards sit side by side near the top: their edges start in the upper third
    assert np.nonzero(green.any(axis=1))[0][0] < 300 and np.nonzero(red.any(axis=1))[0][0] < 300

    class Cells(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.depth, self.cells, self.text = 0, [], ""

        def handle_starttag(self, tag, attrs):
            if tag in ("td", "th"):
                self.depth, self.text = 1, ""

        def handle_endtag(self, tag):
            if tag in ("td", "th") and self.depth:
                self.cells.append(self.text)
                self.depth = 0

        def handle_data(self, data):
            if self.depth:
                self.text += data

    html = page.read_text(encoding="utf-8")
    parser = Cells()
    parser.feed(html)
    assert len(parser.cells) > 20
    assert not [c for c in parser.cells if "{'" in c or "['" in c]
    assert "7.29 dB → 0.493 dB" in html and "at the noise level" in html
    assert "Not explained" in html and "a mode near 480 Hz" in html
