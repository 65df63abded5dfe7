"""``sensor_dynamics``: a sensor on a compliant mount, a light head on a spring that its own
output reads (``<sensor_mount>``), excited by the body's motion at the head's place."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from effect_support import GRAD_TOL, gradient_error, noisy_data, refit_of, solve

from bondid.diagnose.augmented import with_values
from bondid.diagnose.effects import get_effect
from bondid.diagnose.effects import sensor_dynamics as sd
from bondid.diagnose.effects._chain import add_joint, add_link
from bondid.exceptions import ModelError
from bondid.linear.affine import build_affine_model
from bondid.model import UrdfDocument, get_parameter
from bondid.model.mounts import SensorMount
from bondid.model.points import Point

MODEL = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03})
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
#: a head of 1e-7 of the body's mass: its reaction on the machine below this (relative)
LIGHT_TOL = 1e-4
#: round trip at 0.5 % noise on 2 × 150 lines: the mount's stiffness and damper
REL_K, REL_C = 0.01, 0.05


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def test_candidates_carry_the_heads_places_as_variants(doc):
    cands = get_effect("sensor_dynamics").candidates(doc)
    assert [c.location for c in cands] == ["x", "y", "z"]
    y = cands[1]
    assert y.spec["body"] == "y_stage" and y.spec["kind"] == "prismatic"
    np.testing.assert_allclose(np.abs(y.spec["axis"]), [0.0, 1.0, 0.0], atol=1e-12)
    # the centre of mass, then the hull's faces across the measuring direction (x and z)
    assert len(y.variants) == 4
    moved = [np.flatnonzero(np.abs(np.subtract(v.spec["place"], y.spec["place"])) > 1e-9)
             for v in y.variants]  # fmt: skip
    assert sorted(int(m[0]) for m in moved) == [0, 0, 2, 2]
    assert [p.members[0][0] for p in y.parameters] == [
        "sensor_mount_y.stiffness", "sensor_mount_y.damping"]  # fmt: skip
    assert y.parameters[0].strength and y.ref_hz == sd.F0_HZ
    z = cands[2]  # an angle sensor: a rotational mount, its place does not matter
    assert z.spec["kind"] == "revolute" and z.variants == ()


def test_a_light_head_reads_the_body_at_its_place_through_the_mount(doc, monkeypatch):
    """Known answer: with a weightless head, the output reads its row plus ``(G − 1)`` times
    the body's absolute motion at the head's place along the measuring direction, ``G`` the
    base-excitation transmissibility of the mount (a lever arm makes the body's tilts count)."""
    monkeypatch.setattr(sd, "HEAD_SHARE", 1e-7)
    e = get_effect("sensor_dynamics")
    cand = next(v for v in get_effect("sensor_dynamics").candidates(doc)[1].variants
                if abs(v.spec["place"][0]) > 0.05)  # fmt: skip
    aug = e.augment(doc, cand)
    f = np.array([30.0, 400.0, 900.0, 1000.0, 1300.0, 3000.0])
    am = build_affine_model(aug)
    H = am.linear_model().frf(f)
    # the nominal model with a probe at the head's place, same direction, absolute
    probe = doc.copy()
    add_link(probe, "probe")
    add_joint(probe, "probe_fix", "fixed", cand.spec["body"], "probe", xyz=cand.spec["place"])
    probe.set_point(Point("probe", "probe", "translation", tuple(cand.spec["axis"]), "local"))
    ap = build_affine_model(probe, outputs=("x", "y", "z", "probe"))
    Hp = ap.linear_model().frf(f)
    cols = [ap.inputs.index(i) for i in am.inputs]
    k, c = (p.initial for p in cand.parameters)
    m = cand.spec["mass"]
    s = 2j * np.pi * f
    G = (c * s + k) / (m * s**2 + c * s + k)
    want = Hp[1][cols] + (G - 1.0) * Hp[3][cols]
    got = H[am.outputs.index("y")]
    scale = np.abs(want).max(axis=1, keepdims=True)
    assert np.abs(got - want).max() / scale.max() < LIGHT_TOL
    np.testing.assert_allclose(H[0], Hp[0][cols], rtol=LIGHT_TOL, atol=LIGHT_TOL * scale.max())


def test_the_mount_element_round_trips_and_names_a_bad_joint(doc):
    e = get_effect("sensor_dynamics")
    aug = e.augment(doc, e.candidates(doc)[0])
    again = UrdfDocument.from_string(aug.to_string())
    assert again.sensor_mounts == [SensorMount("x", "sensor_mount_x")]
    bad = doc.copy()
    bad.add_sensor_mount(SensorMount("x", "no_such_joint"))
    with pytest.raises(ModelError, match=r"no_such_joint.*not a movable joint"):
        build_affine_model(bad)


def test_a_compliant_sensor_mount_is_refitted(doc):
    """Known answer: the bonder with a mass 5 % off and its y sensor's head at the hull's
    face on a mount at 1.1 kHz, 3 % damping; the candidate refitted from 1.15 kHz and 5 %
    recovers the stiffness and the damper."""
    e = get_effect("sensor_dynamics")
    cand = next(v for v in e.candidates(doc)[1].variants if abs(v.spec["place"][0]) > 0.05)
    m = cand.spec["mass"]
    k = m * (2 * np.pi * 1100.0) ** 2
    c = 2 * 0.03 * np.sqrt(k * m)
    truth = e.augment(doc, with_values(cand, [k, c]))
    from bondid.model import set_parameter

    set_parameter(truth, "x_stage.mass", 1.05 * get_parameter(doc, "x_stage.mass"))
    data = noisy_data(truth, OPS)
    k0 = m * (2 * np.pi * 1150.0) ** 2
    refit = refit_of(doc, FEW, data, with_values(cand, [k0, 2 * 0.05 * np.sqrt(k0 * m)]))
    assert gradient_error(refit) < GRAD_TOL
    got_k, got_c = solve(refit)
    assert got_k == pytest.approx(k, rel=REL_K)
    assert got_c == pytest.approx(c, rel=REL_C)
