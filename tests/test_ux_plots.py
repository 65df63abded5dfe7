"""Bode plots a newcomer reads right: the file's quantity and units on the axes, the
``OUT.IN`` key in the legend, channels left out of the fit greyed and labelled."""

from __future__ import annotations

import numpy as np

from bondid.data.quantity import convert_quantity
from bondid.plots import Curve, build_bode
from bondid.plots.bode import CHANNEL_KEY

F = np.geomspace(1.0, 1000.0, 50)
OUT = ("x", "y")


def _frf() -> np.ndarray:
    s = 2j * np.pi * F
    H = np.empty((2, 2, F.size), complex)
    for a in range(2):
        for b in range(2):
            H[a, b] = (1 + a + b) / (s**2 + 2 * s + 1e4 * (1 + a))
    return H


def test_accelerance_axes_in_the_files_units_and_the_channel_key():
    H = convert_quantity(_frf(), F, "receptance", "accelerance")
    fig = build_bode(F, [Curve("measured", H, kind="measured")], outputs=OUT, inputs=OUT,
                     quantity="accelerance", units={"x": "m", "y": ("m", "u(y)")})  # fmt: skip
    axes = fig.get_axes()
    assert axes[0].get_ylabel() == "accelerance [dB re 1 (m/s²)/N]"  # x.x
    assert axes[2].get_ylabel() == "accelerance [dB re 1 (m/s²)/u(y)]"  # x.y: a gain on y
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert CHANNEL_KEY in texts and "OUT.IN" in CHANNEL_KEY
    # the magnitude drawn is the accelerance's own (not the receptance's)
    y = axes[0].get_lines()[0].get_ydata()
    np.testing.assert_allclose(y, 20 * np.log10(np.abs(H[0, 0])), rtol=1e-12)


def test_left_out_channels_are_greyed_and_labelled():
    H = _frf()
    fig = build_bode(F, [Curve("measured", H, kind="measured"), Curve("model", H)],
                     outputs=OUT, inputs=OUT, left_out=["y.x"])  # fmt: skip
    axes = fig.get_axes()
    cell = axes[4]  # y.x: row 1, column 0
    assert cell.get_title() == "y.x  (left out of the fit)"
    assert any(t.get_gid() == "left-out" for t in cell.texts)
    assert cell.get_facecolor()[:3] != axes[0].get_facecolor()[:3]
    assert all(line.get_alpha() is not None and line.get_alpha() < 0.5 for line in cell.get_lines())
    assert axes[0].get_title() == "x.x" and not axes[0].texts
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "channel left out of the fit" in texts
