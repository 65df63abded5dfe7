"""``sensor_dynamics``: a sensor on a compliant mount (its transmissibility on one output row)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from effect_support import GRAD_TOL, gradient_error, modifier_fd_error, noisy_data, refit_of, solve

from bondid.diagnose.effects import get_effect
from bondid.model import UrdfDocument, get_parameter, set_parameter

MODEL = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03})
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
#: the exact derivatives against central differences (relative to the largest)
FD_TOL = 1e-6
#: round trip at 0.5 % noise on 2 × 150 lines: the mount's frequency and damping ratio
REL_FN, REL_ZETA = 0.005, 0.05


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def test_candidates_and_the_transmissibility(doc):
    e = get_effect("sensor_dynamics")
    cands = e.candidates(doc)
    assert [c.location for c in cands] == ["x", "y", "z", "all"]
    c = cands[1]
    assert c.ref_hz == c.parameters[0].initial and c.parameters[0].strength
    f = np.array([1.0, 1100.0, 1e5])
    G, _ = e.modifier(c, np.array([1100.0, 0.03]), f, ("x", "y", "z"), ("x", "y"))
    np.testing.assert_allclose(G[[0, 2]], 1.0, rtol=0)  # the other rows are left alone
    assert abs(G[1, 0, 0] - 1.0) < 1e-6  # rigid mount well below its mode
    # at the mode, |G| = √(1 + 4ζ²)/(2ζ); far above, it falls as (2ζ f_n/f) (damper-borne)
    assert abs(G[1, 1, 1]) == pytest.approx(np.sqrt(1 + 4 * 0.03**2) / 0.06, rel=1e-12)
    np.testing.assert_allclose(G[1, 0], G[1, 1])  # every column of the row alike


def test_derivatives_match_finite_differences(doc):
    e = get_effect("sensor_dynamics")
    f = np.geomspace(10.0, 4000.0, 40)
    for c in e.candidates(doc):
        err = modifier_fd_error(e, c, np.array([900.0, 0.04]), f, ("x", "y", "z"), ("x", "y"))
        assert err < FD_TOL, (c.label, err)


def test_a_compliant_sensor_mount_is_refitted(doc):
    """Known answer: the bonder with a mass 5 % off and its y sensor on a mount at 1.1 kHz,
    3 % damping; the candidate refitted from 1.15 kHz and 5 % recovers both."""
    e = get_effect("sensor_dynamics")
    cand = next(c for c in e.candidates(doc) if c.location == "y")
    fn, zeta = 1100.0, 0.03
    truth = doc.copy()
    set_parameter(truth, "x_stage.mass", 1.05 * get_parameter(doc, "x_stage.mass"))

    def mount(H, f, outs, ins):
        return H * e.modifier(cand, np.array([fn, zeta]), f, outs, ins)[0]

    data = noisy_data(truth, OPS, transform=mount)
    from bondid.diagnose.augmented import with_values

    refit = refit_of(doc, FEW, data, with_values(cand, [1150.0, 0.05]))
    assert gradient_error(refit) < GRAD_TOL
    got_fn, got_zeta = solve(refit)
    assert got_fn == pytest.approx(fn, rel=REL_FN)
    assert got_zeta == pytest.approx(zeta, rel=REL_ZETA)
