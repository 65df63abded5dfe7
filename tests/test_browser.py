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
