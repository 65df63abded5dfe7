"""Caveats of a kept effect: a parameter on a bound of its range, one common factor on every
channel, and a mixing the other side reproduces (whose side, drives or sensors, FRF data
cannot tell)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bondid.diagnose.caveats import at_bound, caveats, is_common_factor, other_side_share
from bondid.diagnose.effects import get_effect
from bondid.diagnose.summary import caveat_lines
from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
OUTS, INS = ("x", "y", "z"), ("x", "y", "z")


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")


def candidate(doc, effect: str, location: str):
    found = [c for c in get_effect(effect).candidates(doc) if c.location == location]
    assert found, f"{effect} has no candidate at {location!r}"
    return found[0]


def test_a_parameter_on_its_bound_is_named_with_its_side(doc):
    cand = candidate(doc, "actuator_lag", "all")
    t, t2 = cand.parameters
    low = at_bound(cand, [t.lower * 1.0001, 1e-4])
    assert [(c.kind, c.parameter, c.side) for c in low] == [("at_bound", "T", "lower")]
    assert "lower end" in low[0].text and " s)" in low[0].text
    high = at_bound(cand, [1e-3, t2.upper])
    assert [(c.parameter, c.side) for c in high] == [("T2", "upper")]
    assert at_bound(cand, [1e-3, 1e-4]) == []


def test_a_signed_parameter_is_placed_on_a_linear_scale(doc):
    cand = candidate(doc, "actuator_crosstalk", "x,y")
    a, _ = cand.parameters
    assert a.signed
    hits = at_bound(cand, [a.upper, 0.0])
    assert [(c.parameter, c.side) for c in hits] == [(a.name, "upper")]
    assert at_bound(cand, [0.0, 0.0]) == []  # the middle of a symmetric range


@pytest.mark.parametrize(
    ("effect", "location", "values", "common"),
    [
        ("actuator_lag", "all", [1e-3, 2e-4], True),
        ("sensor_delay", "all", [40e-6], True),
        ("sensor_delay", "y", [40e-6], False),
        ("actuator_lag", "x", [1e-3, 2e-4], False),
        ("sensor_dynamics", "y", [1e4, 1.0], False),  # a structure, not a factor
    ],
)
def test_a_factor_on_every_channel_is_common(doc, effect, location, values, common):
    cand = candidate(doc, effect, location)
    assert is_common_factor(cand, values, OUTS, INS) is common


def test_one_input_makes_its_lag_a_common_factor(doc):
    cand = candidate(doc, "actuator_lag", "x")
    assert is_common_factor(cand, [1e-3, 2e-4], OUTS, ("x",))
    assert not is_common_factor(cand, [1e-3, 2e-4], OUTS, ("x", "y"))


def test_mixing_absent_effects_and_structures_are_not_common_factors(doc):
    mis = get_effect("sensor_misalignment").candidates(doc)[0]
    assert not is_common_factor(mis, [0.01] * len(mis.parameters), OUTS, INS)
    lag = candidate(doc, "actuator_lag", "all")
    assert not is_common_factor(lag, [0.0, 0.0], OUTS, INS)  # no lag: factor 1 everywhere
    jc = get_effect("joint_compliance").candidates(doc)[0]
    assert not is_common_factor(jc, [p.initial for p in jc.parameters], OUTS, INS)


def test_caveats_are_listed_in_the_json_shape_and_printed(doc):
    cand = candidate(doc, "actuator_lag", "all")
    found = caveats(cand, {"T": 1e-3, "T2": cand.parameters[1].upper}, [(OUTS, INS)])
    assert [c["kind"] for c in found] == ["at_bound", "common_factor"]
    assert set(found[0]) == {"kind", "text", "parameter", "side"}
    lines = caveat_lines([{"effect": "actuator_lag", "location": "all", "caveats": found}])
    assert len(lines) == 2
    assert lines[1].startswith("  caveat, actuator_lag@all: it multiplies every channel")
    # a sequence of the wrong length is no effect of this candidate: nothing is claimed
    assert caveats(cand, [1.0], [(OUTS, INS)]) == []


#: a mixing the other side reproduces leaves at most this share of its change (exact algebra
#: up to round-off); one it cannot reproduce leaves at least the other
SAME_SIDE_TOL, OTHER_SIDE_MIN = 1e-9, 0.3


def _axes(f_hz: np.ndarray, resonant: bool) -> np.ndarray:
    """A 2 × 2 receptance ``(2, 2, n_freq)``: two decoupled rigid axes (mass 2 kg, inertia
    0.01 kg·m²), the second with a 5 %-damped mode at 300 Hz when ``resonant``."""
    s = 2j * np.pi * f_hz
    H = np.zeros((2, 2, f_hz.size), complex)
    H[0, 0] = 1.0 / (2.0 * s**2)
    k = 0.01 * (2 * np.pi * 300.0) ** 2 if resonant else 0.0
    c = 2 * 0.05 * 0.01 * 2 * np.pi * 300.0 if resonant else 0.0
    H[1, 1] = 1.0 / (0.01 * s**2 + c * s + k)
    return H


@pytest.mark.parametrize("left", [True, False])
def test_a_mixing_between_axes_in_a_constant_ratio_is_on_either_side(left):
    """Known answer: two rigid axes have FRFs in a constant ratio, so ``E H0 = H0 F`` with
    ``F = H0⁻¹ E H0`` constant (share ~0); with a mode on one axis the ratio varies and the
    other side cannot reproduce the mixing."""
    f = np.geomspace(5.0, 2000.0, 200)
    M = np.array([[1.0, 0.02], [-0.01, 1.0]], complex)
    for resonant, expect_same in ((False, True), (True, False)):
        H0 = _axes(f, resonant)
        H = np.einsum("ij,jkf->ikf", M, H0) if left else np.einsum("ijf,jk->ikf", H0, M)
        share = other_side_share(H, M, left)
        if expect_same:
            assert share <= SAME_SIDE_TOL
        else:
            assert share >= OTHER_SIDE_MIN


def test_the_either_side_caveat_follows_the_kept_models_frf(doc):
    cand = candidate(doc, "sensor_misalignment", "x,y")
    vals = [0.02 if i == 0 else -0.01 for i in range(len(cand.parameters))]
    f = np.geomspace(5.0, 2000.0, 200)
    outs, ins = ("x", "y"), ("x", "y")
    mix = get_effect("sensor_misalignment").mixing(cand, np.array(vals), outs, ins)
    for resonant, expected in ((False, ["either_side"]), (True, [])):
        H = np.einsum("ij,jkf->ikf", mix.left, _axes(f, resonant))
        found = caveats(cand, vals, [(outs, ins)], [H])
        assert [c["kind"] for c in found] == expected
        if expected:
            assert "drives pushing across" in found[0]["text"]
    assert caveats(cand, vals, [(outs, ins)]) == []  # no FRF: not looked for


def _three_axes(f_hz: np.ndarray) -> np.ndarray:
    """A 3 × 3 receptance ``(3, 3, n_freq)``: x and y rigid (2 kg each, FRFs in a constant
    ratio), z with a 5 %-damped mode at 300 Hz, and a weak resonant coupling ``h_yz = h_zy``
    (a tenth of z's direct FRF)."""
    s = 2j * np.pi * f_hz
    wz = 2 * np.pi * 300.0
    H = np.zeros((3, 3, f_hz.size), complex)
    H[0, 0] = H[1, 1] = 1.0 / (2.0 * s**2)
    H[2, 2] = 1.0 / (0.01 * (s**2 + 2 * 0.05 * wz * s + wz**2))
    H[1, 2] = H[2, 1] = 0.1 * H[2, 2]
    return H


def test_only_the_channels_the_fit_used_can_tell_the_sides_apart(doc):
    """Known answer: sensor x reading 2 % of y. On x.y the drives' side reproduces it (x and
    y in a constant ratio); on x.z it cannot (y's coupling to z is resonant, x's is nil),
    and there the relative change is whole. With x.z left out of the fit the sides are one
    to the data and the caveat appears; with x.z used it does not."""
    f = np.geomspace(5.0, 2000.0, 200)
    M = np.eye(3, dtype=complex)
    M[0, 1] = 0.02
    H = np.einsum("ij,jkf->ikf", M, _three_axes(f))
    used = np.ones((3, 3), bool)
    assert other_side_share(H, M, True, used) >= OTHER_SIDE_MIN
    used[0, 2] = False
    assert other_side_share(H, M, True, used) <= SAME_SIDE_TOL

    cand = candidate(doc, "sensor_misalignment", "x,y")
    vals = [0.02 if i == 0 else 0.0 for i in range(len(cand.parameters))]
    outs = ins = ("x", "y", "z")
    mix = get_effect("sensor_misalignment").mixing(cand, np.array(vals), outs, ins)
    assert np.allclose(mix.left, M)
    everything = {f"{o}.{i}" for o in outs for i in ins}
    for names, expected in ((everything, []), (everything - {"x.z"}, ["either_side"])):
        found = caveats(cand, vals, [(outs, ins)], [H], [names])
        assert [c["kind"] for c in found] == expected
