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
    G, _ = e.modifier(c, np.array([1100.0, 0.03, 1.0, 1.0, 1.0]), f, ("x", "y", "z"), ("x", "y"))
    np.testing.assert_allclose(G[[0, 2]], 1.0, rtol=0)  # the other rows are left alone
    assert abs(G[1, 0, 0] - 1.0) < 1e-6  # rigid mount well below its mode
    # at the mode, |G| = √(1 + 4ζ²)/(2ζ); far above, it falls as (2ζ f_n/f) (damper-borne)
    assert abs(G[1, 1, 1]) == pytest.approx(np.sqrt(1 + 4 * 0.03**2) / 0.06, rel=1e-12)
    np.testing.assert_allclose(G[1, 0], G[1, 1])  # every share 1: the columns alike
    # a share c: the mount point moves c times the reading, H' = (1 + c (G − 1)) H, so that
    # far above the mode the reading keeps 1 − c of itself
    G2, _ = e.modifier(c, np.array([1100.0, 0.03, 1.0, 0.3, -0.8]), f, ("x", "y", "z"),
                       ("x", "y", "z"))  # fmt: skip
    np.testing.assert_allclose(G2[1, 1] - 1.0, 0.3 * (G[1, 1] - 1.0), rtol=1e-8, atol=1e-15)
    assert abs(G2[1, 2, 2] - 1.8) < 0.01
    assert cands[-1].location == "all" and [p.name for p in cands[-1].parameters] == ["f_n", "zeta"]


def test_derivatives_match_finite_differences(doc):
    e = get_effect("sensor_dynamics")
    f = np.geomspace(10.0, 4000.0, 40)
    for c in e.candidates(doc):
        values = np.r_[900.0, 0.04, np.linspace(0.5, -0.7, len(c.parameters) - 2)]
        err = modifier_fd_error(e, c, values, f, ("x", "y", "z"), ("x", "y"))
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
        return H * e.modifier(cand, np.array([fn, zeta, 1.0, 1.0, 1.0]), f, outs, ins)[0]

    data = noisy_data(truth, OPS, transform=mount)
    from bondid.diagnose.augmented import with_values

    refit = refit_of(doc, FEW, data, with_values(cand, [1150.0, 0.05, 1.0, 1.0, 1.0]))
    assert gradient_error(refit) < GRAD_TOL
    got_fn, got_zeta = solve(refit)[:2]
    assert got_fn == pytest.approx(fn, rel=REL_FN)
    assert got_zeta == pytest.approx(zeta, rel=REL_ZETA)


def test_a_mount_that_moves_unlike_its_reading_is_found_from_its_placed_start(doc):
    """Known answer: the y sensor's mount at 1.1 kHz, 3 % damping, its mount point moving
    0.3 times the reading under input y and -0.8 times under input z (a relative reading, a
    rocking body). With every share 1 a mount there fits worse than none; the start placed
    at the missing mode settles its damping and shares with the mode held, ranks first, and
    the refit from it recovers the mount."""
    from bondid.diagnose.starts import Places, candidate_starts

    e = get_effect("sensor_dynamics")
    cand = next(c for c in e.candidates(doc) if c.location == "y")
    truth_values = np.array([1100.0, 0.03, 1.0, 0.3, -0.8])
    truth = doc.copy()
    set_parameter(truth, "x_stage.mass", 1.05 * get_parameter(doc, "x_stage.mass"))

    def mount(H, f, outs, ins):
        return H * e.modifier(cand, truth_values, f, outs, ins)[0]

    data = noisy_data(truth, OPS, transform=mount)
    refit = refit_of(doc, FEW, data, cand)
    starts = candidate_starts(refit, cand, Places(missing=(1100.0,)))
    best = starts[0]
    assert best.label == "mode at 1100 Hz"
    assert best.figure < 0.5 * refit.cost(refit.state0)
    from bondid.diagnose.refit import State

    from_best = refit.with_new(refit.state0, refit.new_values(State(best.x, best.theta)))
    state, _, _ = refit.solve(
        from_best, __import__("bondid.optim.schedules", fromlist=["direct"]).direct(), max_iter=150
    )
    got = refit.new_values(state)
    assert got[0] == pytest.approx(1100.0, rel=REL_FN)
    assert got[1] == pytest.approx(0.03, rel=REL_ZETA)
    np.testing.assert_allclose(got[3:], truth_values[3:], atol=0.03)
