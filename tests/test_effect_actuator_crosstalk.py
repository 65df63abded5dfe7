"""``actuator_crosstalk``: input cross-talk, a mixing matrix ``I + F`` on the columns, told
apart from an output misalignment ``(I + E)`` on the rows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from effect_support import (
    GRAD_TOL,
    gradient_error,
    mixed_refit,
    modifier_fd_error,
    noisy_data,
    refit_of,
    solve,
)

from bondid.cost.modifier import Mixing
from bondid.diagnose.effects import get_effect
from bondid.model import UrdfDocument
from bondid.simulate import log_grid, simulate

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03})
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
FD_TOL = 1e-6
#: round trip at 0.5 % noise on 2 × 150 lines: every entry within this (absolute)
ABS_F = 1e-3


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def test_candidates_pair_inputs_of_one_kind(doc):
    e = get_effect("actuator_crosstalk")
    cands = e.candidates(doc)  # x, y forces; z a torque
    assert [c.location for c in cands] == ["x,y"]
    assert [p.name for p in cands[0].parameters] == ["f_x_y", "f_y_x"]
    assert all(p.signed and p.strength and p.initial == 0.0 for p in cands[0].parameters)
    polar = UrdfDocument.load(ROOT / "tools" / "benchmark" / "designs" / "polar_handler.urdf")
    assert [c.location for c in e.candidates(polar)] == ["ext,lift"]


def test_mixing_acts_on_the_columns(doc):
    e = get_effect("actuator_crosstalk")
    c = e.candidates(doc)[0]
    outs, ins = ("x", "y", "z"), ("x", "y", "z")
    m = e.mixing(c, np.array([0.03, -0.02]), outs, ins)
    want = np.eye(3)
    want[0, 1], want[1, 0] = 0.03, -0.02
    np.testing.assert_allclose(m.right, want, rtol=0)
    assert m.left is None
    err = modifier_fd_error(e, c, np.array([0.03, -0.02]), np.geomspace(10, 4000, 9), outs, ins)
    assert err < FD_TOL
    # column y of H R gains 0.03 × column x: input y's command also drives x
    H = simulate(doc, {}, log_grid(10.0, 1000.0, 5)).H
    got = m.apply(H)
    np.testing.assert_allclose(got[:, 1], H[:, 1] + 0.03 * H[:, 0], rtol=1e-12)
    np.testing.assert_allclose(got[:, 2], H[:, 2], rtol=0)
    # an input the data lack: its entries act on nothing
    m2 = e.mixing(c, np.array([0.03, -0.02]), outs, ("x", "z"))
    np.testing.assert_allclose(m2.right, np.eye(2), rtol=0)


def test_cross_talk_is_refitted_from_none(doc):
    """Known answer: the bonder with a mass 5 % off, 2 % of y's command driving x and −1 % of
    x's driving y; the refit from no cross-talk recovers both entries."""
    e = get_effect("actuator_crosstalk")
    cand = e.candidates(doc)[0]
    F = np.array([0.02, -0.01])
    refit = mixed_refit(doc, FEW, OPS, e, cand, F)
    assert refit.modifier is not None and refit.modifier.mixing is not None
    assert gradient_error(refit) < GRAD_TOL
    np.testing.assert_allclose(solve(refit), F, atol=ABS_F)


def test_output_mixing_does_not_fit_input_cross_talk(doc):
    """The two sides leak in proportion to different direct channels: data with input
    cross-talk leave the output-side candidate well above the input-side one."""
    e_in, e_out = get_effect("actuator_crosstalk"), get_effect("sensor_misalignment")
    F = np.array([0.03, 0.0])
    c_in = e_in.candidates(doc)[0]

    def mix(H, f, outs, ins):
        return e_in.mixing(c_in, F, outs, ins).apply(H)

    data = noisy_data(doc, OPS, transform=mix)
    costs = {}
    for e in (e_in, e_out):
        refit = refit_of(doc, FEW, data, e.candidates(doc)[0])
        costs[e.name] = refit.solve(refit.state0, _direct(), max_iter=150)[1]
    assert costs["actuator_crosstalk"] < 0.5 * costs["sensor_misalignment"]


def _direct():
    from bondid.optim.schedules import direct

    return direct()


def test_mixing_dataclass_applies_right_only():
    R = np.array([[1.0, 0.1], [0.0, 1.0]], complex)
    H = np.arange(8, dtype=complex).reshape(2, 2, 2)
    np.testing.assert_allclose(Mixing(right=R).apply(H), np.einsum("abf,bc->acf", H, R))
