"""``transducer_gain``: the gain error of one output row or one input column, as ``ln g``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from effect_support import GRAD_TOL, gradient_error, modifier_fd_error, noisy_data, refit_of, solve

from bondid.diagnose.effects import get_effect
from bondid.model import UrdfDocument

MODEL = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03})
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
FD_TOL = 1e-6
#: round trip at 0.5 % noise (and a floor −70 dB under each response) on 2 × 150 lines: ln g
#: within 3 × the refit's own std of it (measured: 0.004–0.005; the free masses and the
#: prior share a column's or a row's level with the gain)
ABS_LOG = 0.015


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def test_candidates_and_the_factor(doc):
    e = get_effect("transducer_gain")
    cands = e.candidates(doc)
    assert [c.location for c in cands] == ["out.x", "out.y", "out.z", "in.x", "in.y", "in.z"]
    outs, ins, f = ("x", "y", "z"), ("x", "y", "z"), np.array([10.0, 100.0])
    G, _ = e.modifier(cands[1], np.array([np.log(1.2)]), f, outs, ins)
    np.testing.assert_allclose(G[1], 1.2, rtol=1e-14)
    np.testing.assert_allclose(G[[0, 2]], 1.0, rtol=0)
    G, _ = e.modifier(cands[3], np.array([np.log(0.8)]), f, outs, ins)
    np.testing.assert_allclose(G[:, 0], 0.8, rtol=1e-14)
    np.testing.assert_allclose(G[:, 1:], 1.0, rtol=0)
    for c in cands:
        assert modifier_fd_error(e, c, np.array([0.1]), f, outs, ins) < FD_TOL


@pytest.mark.parametrize("side, chan, g", [("out", "y", 1.1), ("in", "x", 0.9)])
def test_a_gain_made_with_the_models_gains_is_refitted(doc, side, chan, g):
    """Known answer: data of the bonder whose ``gain.{side}.{chan}`` (the model's own
    ``[gains]`` machinery, not the candidate's factor) is ``g``; the candidate at that
    channel, refitted from ``ln g = 0``, recovers ``ln g``."""
    truth = doc.copy()
    truth.set_gain(f"gain.{side}.{chan}", g)
    data = noisy_data(truth, OPS)
    e = get_effect("transducer_gain")
    cand = next(c for c in e.candidates(doc) if c.location == f"{side}.{chan}")
    refit = refit_of(doc, FEW, data, cand)
    assert gradient_error(refit) < GRAD_TOL
    (got,) = solve(refit)
    assert got == pytest.approx(np.log(g), abs=ABS_LOG)
