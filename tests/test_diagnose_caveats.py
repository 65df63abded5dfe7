"""Caveats of a kept effect: a parameter on a bound of its range, and one common factor on
every channel (whose side, drives or sensors, FRF data cannot tell)."""

from __future__ import annotations

from pathlib import Path

import pytest

from bondid.diagnose.caveats import at_bound, caveats, is_common_factor
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
