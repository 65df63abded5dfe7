"""Copy the pictures the tutorial's commands drew into ``docs/tutorial/img/``, made lighter.

Run the tutorial's commands from the repository's top folder first (they write
``results/``), then ``python docs/tools/tutorial_images.py``. Each PNG is scaled to at most
1400 px and stored with a 128-colour palette; the pages the commands write as HTML (the mode
viewer, the report) are photographed with headless Chromium when it is installed.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "results"
IMG = ROOT / "docs" / "tutorial" / "img"
#: source (under results/) -> name in docs/tutorial/img/
PICTURES = {
    "bode_bonder_q0.png": "fit_bode_q0.png",
    "convergence.png": "fit_convergence.png",
    "sens/sensitivity_bands.png": "sensitivity_bands.png",
    "sens/sweep.png": "sensitivity_sweep.png",
    "diag/residual_map.png": "diagnose_residual_map.png",
}
#: HTML pages (under results/) -> screenshot name, window size
PAGES = {
    "modes/modes.html": ("modes_viewer.png", "1200,800"),
    "report.html": ("report.png", "1200,1400"),
}
MAX_PX = 1400


def shrink(src: Path, dst: Path) -> None:
    im = Image.open(src).convert("RGB")
    im.thumbnail((MAX_PX, MAX_PX))
    im.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(dst, optimize=True)


def screenshot(page: Path, dst: Path, size: str) -> bool:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        return False
    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "shot.png"
        cmd = [chromium, "--headless=new", "--no-sandbox", "--use-angle=swiftshader",
               "--enable-unsafe-swiftshader", "--virtual-time-budget=8000",
               f"--screenshot={raw}", f"--window-size={size}", page.resolve().as_uri()]  # fmt: skip
        subprocess.run(cmd, capture_output=True, timeout=120, check=False)
        if not raw.exists():
            return False
        shrink(raw, dst)
    return True


def main() -> int:
    IMG.mkdir(parents=True, exist_ok=True)
    for src, name in PICTURES.items():
        if (RESULTS / src).exists():
            shrink(RESULTS / src, IMG / name)
            print(f"{name}: {(IMG / name).stat().st_size // 1024} KiB")
        else:
            print(f"{src}: not in results/ (run the tutorial's commands first)", file=sys.stderr)
    for src, (name, size) in PAGES.items():
        if (RESULTS / src).exists() and screenshot(RESULTS / src, IMG / name, size):
            print(f"{name}: {(IMG / name).stat().st_size // 1024} KiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
