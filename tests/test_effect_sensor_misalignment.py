"""``sensor_misalignment``: output cross-talk, a mixing matrix ``I + E`` with signed entries."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from effect_support import GRAD_TOL, gradient_error, mixed_refit, modifier_fd_error, solve

from bondid.diagnose.effects import get_effect
from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03})
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
FD_TOL = 1e-6
#: round trip at 0.5 % noise on 2 × 150 lines: every entry within this (absolute, ≈ 0.06°)
ABS_E = 1e-3


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def test_candidates_pair_outputs_of_one_kind():
    bonder = UrdfDocument.load(MODEL)  # x, y prismatic; z revolute
    e = get_effect("sensor_misalignment")
    cands = e.candidates(bonder)
    assert [c.location for c in cands] == ["x,y"]
    assert all(p.signed and p.strength and p.initial == 0.0 for p in cands[0].parameters)
    polar = UrdfDocument.load(ROOT / "tools" / "benchmark" / "designs" / "polar_handler.urdf")
    assert [c.location for c in e.candidates(polar)] == ["ext,lift"]


def test_mixing_and_derivatives(doc):
    e = get_effect("sensor_misalignment")
    c = e.candidates(doc)[0]
    outs, ins = ("x", "y", "z"), ("x", "y", "z")
    m = e.mixing(c, np.array([0.03, -0.02]), outs, ins)
    want = np.eye(3)
    want[0, 1], want[1, 0] = 0.03, -0.02
    np.testing.assert_allclose(m.left, want, rtol=0)
    assert m.right is None
    err = modifier_fd_error(e, c, np.array([0.03, -0.02]), np.geomspace(10, 4000, 9), outs, ins)
    assert err < FD_TOL
    # an output the data lack: its entries act on nothing
    m2 = e.mixing(c, np.array([0.03, -0.02]), ("x", "z"), ins)
    np.testing.assert_allclose(m2.left, np.eye(2), rtol=0)


def test_cross_talk_is_refitted_from_none(doc):
    """Known answer: the bonder with a mass 5 % off, its x sensor turned 1.7° toward y (``E[x,
    y] = 0.03``) and y picking up 1.5 % of x with the opposite sign; the refit from no
    cross-talk recovers both entries."""
    e = get_effect("sensor_misalignment")
    cand = e.candidates(doc)[0]
    E = np.array([0.03, -0.015])
    refit = mixed_refit(doc, FEW, OPS, e, cand, E)
    assert refit.modifier is not None and refit.modifier.mixing is not None
    assert gradient_error(refit) < GRAD_TOL
    got = solve(refit)
    np.testing.assert_allclose(got, E, atol=ABS_E)
