"""``tools/band_residuals.py``: the per-band weighted gap of a model against data (known
answers on synthetic FRFs)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from band_residuals import band_figures  # noqa: E402

from bondid.data.measurement import FrfData  # noqa: E402


def _cells(text: str) -> list[dict[int, float]]:
    """``band:dB`` cells per data set of :func:`band_figures`' text."""
    out = []
    for part in text.split(" | "):
        out.append({int(b): float(v) for b, v in (c.split(":") for c in part.split())})
    return out


def test_band_figures_known_errors_and_weights():
    f = np.geomspace(1.0, 1000.0, 300)
    edges = np.geomspace(1.0, 1000.0 * (1 + 1e-12), 4)  # 3 bands of one decade
    model = np.ones((2, 1, f.size), complex) * (1.0 + 0.5j)
    meas = model.copy()
    band = np.searchsorted(edges, f, side="right") - 1
    meas[0, 0, band == 1] *= 10 ** (1.0 / 20)  # +1 dB on channel a.u in band 1
    meas[1, 0, band == 2] *= 10 ** (3.0 / 20)  # +3 dB on channel b.u in band 2 ...
    w = np.ones(meas.shape)
    w[1, 0, band == 2] = 0.0  # ... at weight 0: it does not count
    w[0, 0, band == 2] = 0.5
    d = FrfData(f, ("a", "b"), ("u",), meas, coherence=w)
    (cells,) = _cells(band_figures([d], [model], ["a.u", "b.u"], edges))
    assert cells[0] == pytest.approx(0.0, abs=1e-9)
    # band 1: channel a at 1 dB, channel b at 0, equal weights -> sqrt(1/2)
    assert cells[1] == pytest.approx(np.sqrt(0.5), abs=5e-3)
    assert cells[2] == pytest.approx(0.0, abs=1e-9)
    # one channel alone: band 1 is that channel's 1 dB
    (only_a,) = _cells(band_figures([d], [model], ["a.u"], edges))
    assert only_a[1] == pytest.approx(1.0, abs=5e-3)


def test_band_figures_one_part_per_data_set_and_phase():
    f = np.geomspace(10.0, 100.0, 50)
    edges = np.geomspace(10.0, 100.0 * (1 + 1e-12), 3)
    model = np.ones((1, 1, f.size), complex)
    rot = np.exp(1j * 0.1)  # a phase error of 0.1 rad is 0.1 * 20/ln 10 dB in complex log
    sets = [FrfData(f, ("a",), ("u",), model * rot), FrfData(f, ("a",), ("u",), model)]
    cells = _cells(band_figures(sets, [model, model], ["a.u"], edges))
    assert len(cells) == 2
    assert cells[0][0] == pytest.approx(0.1 * 20 / np.log(10), abs=5e-3)  # printed to 0.01
    assert cells[1][1] == pytest.approx(0.0, abs=1e-12)
