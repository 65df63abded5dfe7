"""The benchmark's truths of the later causes and of causes outside the library
(``tools/benchmark/truth*.py``) and its open-world case list (``cases.open_cases``)."""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from benchmark.cases import all_cases, classes, leave_one_out, open_cases  # noqa: E402
from benchmark.designs import design  # noqa: E402
from benchmark.regimes import measure  # noqa: E402
from benchmark.truth import (  # noqa: E402
    LIBRARY_MORE,
    OUTSIDE,
    TruthEffect,
    expected_remainder,
    observe_data,
    signal_factor,
    strengthen,
    truth_model,
)
from benchmark.truth_signals import BRACKET, bracket_joint  # noqa: E402
from benchmark.truth_structures import first_mode_hz  # noqa: E402

from bondid.diagnose.effects import available  # noqa: E402
from bondid.linear import build_affine_model  # noqa: E402
from bondid.model import UrdfDocument  # noqa: E402
from bondid.model.parameters import link_inertial  # noqa: E402

F = np.geomspace(1.0, 4000.0, 80)
#: two builds of a truth that must agree (one with a cause whose effect is nil) [dB]
SAME_DB = 1e-6


def _pair(case_name: str, **spec):
    """(truth with the case's cause (spec overridden), truth without it, the cause)."""
    case = next(c for c in open_cases() if c.name == case_name)
    e = case.effects[0]
    e = TruthEffect(e.effect, e.location, {**e.spec, **spec})
    nominal = UrdfDocument.load(design(case.design).path)
    return truth_model(nominal, (e,), case.seed), truth_model(nominal, (), case.seed), e


def _db(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return 20 / np.log(10) * np.abs(np.log(a / b))


def test_open_cases_cover_every_later_cause_and_the_outside_ones():
    cases = open_cases()
    names = [c.name for c in cases]
    assert len(set(names)) == len(names)
    assert not set(names) & {c.name for c in all_cases()}
    assert len(all_cases()) == 74  # the first list is left as it was
    for cause in (*LIBRARY_MORE, *OUTSIDE):
        mine = [c for c in cases if c.effects[0].effect == cause]
        assert len({c.design for c in mine}) >= 2, cause
        assert len({c.regime for c in mine}) >= 2, cause
    assert set(LIBRARY_MORE) <= set(available())  # every later cause is a library class
    assert not set(OUTSIDE) & set(available())
    assert Counter(c.regime for c in cases).keys() >= {"coh", "nocoh", "harsh", "acc", "mob"}


def test_a_case_knows_its_class_and_its_leave_one_out_list():
    cases = {c.name: c for c in open_cases()}
    sd = cases["bonder/sdyn/coh"]
    assert classes(sd) == ("sensor_dynamics",)
    assert "sensor_dynamics" not in leave_one_out(sd)
    assert set(leave_one_out(sd)) == set(available()) - {"sensor_dynamics"}
    hp = cases["bonder/hp/nocoh"]
    assert classes(hp) == () and leave_one_out(hp) == tuple(available())
    old = next(c for c in all_cases() if c.name.startswith("bonder/jct/"))
    assert classes(old) == ("joint_compliance",)


def test_every_open_truth_builds_and_is_observed_on_the_nominal_channels():
    for case in open_cases()[::2]:
        d = design(case.design)
        nominal = UrdfDocument.load(d.path)
        truth = truth_model(nominal, case.effects, case.seed)
        UrdfDocument.from_string(truth.to_string()).build_pinocchio_model()
        obs = observe_data(truth, case.effects, d.operating_points[1], F)
        am = build_affine_model(nominal, d.operating_points[1])
        assert obs.outputs == am.outputs and obs.inputs == am.inputs, case.name
        assert np.all(np.isfinite(obs.H)), case.name
        for r in expected_remainder(case.effects[0]):
            assert set(r.rows) <= set(am.outputs) and set(r.columns) <= set(am.inputs)


def test_the_read_head_adds_its_bracket_to_one_row_only():
    """Known answer: the output reads the drive plus the head's deflection along it
    (``ℓθ``), the other rows only feel the 20 g head; well below the bracket's mode the
    reading is the drive's, and the row peaks near the bracket's mode."""
    truth, base, e = _pair("bonder/sdyn/coh")
    obs = observe_data(truth, (e,), {}, F)
    am = build_affine_model(truth, {}, outputs=("x", "y", "z", bracket_joint("y")))
    H = am.linear_model().frf(F)
    np.testing.assert_allclose(obs.H[1], H[1] + BRACKET * H[3], rtol=1e-12)
    ref = observe_data(base, (), {}, F)
    low = F < 20
    assert np.max(_db(obs.H[1][:, low], ref.H[1][:, low])) < 0.2  # 2 % head mass at most
    others = np.sqrt(np.mean(_db(obs.H[[0, 2]], ref.H[[0, 2]]) ** 2))
    row = np.sqrt(np.mean(_db(obs.H[1], ref.H[1]) ** 2))
    assert row > 5 * others
    rigid, _, _ = _pair("bonder/sdyn/coh", f=1e6)  # the same head on a rigid bracket
    ratio = np.abs(obs.H[1] / observe_data(rigid, (e,), {}, F).H[1])
    peak = F[np.argmax(ratio.max(axis=0))]
    assert 0.8 * e.spec["f"] < peak < 1.25 * e.spec["f"]


def test_turned_sensors_read_a_rotation_of_the_pair():
    truth, _, e = _pair("bonder/mis/nocoh")
    obs = observe_data(truth, (e,), {}, F)
    ref = observe_data(truth, (), {}, F)  # the same machine read square
    a, b = np.radians(e.spec["deg"]), np.radians(e.spec["deg_other"])
    np.testing.assert_allclose(obs.H[0], np.cos(a) * ref.H[0] + np.sin(a) * ref.H[1], rtol=1e-12)
    np.testing.assert_allclose(obs.H[1], np.cos(b) * ref.H[1] + np.sin(b) * ref.H[0], rtol=1e-12)
    np.testing.assert_array_equal(obs.H[2], ref.H[2])


def test_the_cable_carrier_holds_the_drive_and_hangs_a_mass_on_it():
    truth, base, _ = _pair("bonder/drv/harsh")
    k = truth.stiffness("x")
    assert k > 0 and base.stiffness("x") == 0
    am = build_affine_model(truth)
    H0 = am.linear_model().frf(np.array([1e-4]))
    assert H0[0, 0, 0].real == pytest.approx(1 / k, rel=1e-6)  # static: the carrier's spring
    m_carrier = link_inertial(truth, "truth_carrier")[0]
    assert 0.0 < m_carrier < 0.1 * sum(link_inertial(base, n)[0] for n in
                                       ("x_stage", "y_stage", "z_stage"))  # fmt: skip


def test_the_bending_arm_adds_up_to_the_link_and_bends_at_its_frequency():
    truth, base, e = _pair("polar/flk/mob")
    parts = ["arm", "arm_truth_mid", "arm_truth_tip"]
    assert sum(link_inertial(truth, p)[0] for p in parts) == pytest.approx(
        link_inertial(base, "arm")[0], rel=1e-12)  # fmt: skip
    assert first_mode_hz(truth, "arm") == pytest.approx(e.spec["f"], rel=1e-3)
    # with rigid hinges the cut arm is the arm
    stiff, _, _ = _pair("polar/flk/mob", f=1e6)
    for op in design("polar").operating_points:
        a = observe_data(stiff, (), op, F).H
        b = observe_data(base, (), op, F).H
        assert np.max(_db(a, b)) < 1e-3


def test_the_highpass_outside_the_library():
    f = np.array([0.5, 4.0, 100.0])
    w = 2 * np.pi * f
    outs = ins = ("gx", "gy", "theta")
    G = signal_factor([TruthEffect("amplifier_highpass", "gy", {"f": 4.0})], f, outs, ins)
    s = 1j * w / (2 * np.pi * 4.0)
    np.testing.assert_allclose(G[:, 1], np.broadcast_to(s**2 / (1 + 1.4 * s + s**2), (3, 3)))
    np.testing.assert_array_equal(G[:, [0, 2]], 1.0)


def test_the_cross_talk_truth_turns_a_drives_force():
    truth, _, e = _pair("bonder_b/xtalk/harsh")
    obs = observe_data(truth, (e,), {}, F)
    ref = observe_data(truth, (), {}, F)
    i, j = obs.inputs.index("xa"), obs.inputs.index("ya")
    s = e.spec["share"]
    np.testing.assert_allclose(obs.H[:, i], np.sqrt(1 - s**2) * ref.H[:, i] + s * ref.H[:, j],
                               rtol=1e-12)  # fmt: skip
    np.testing.assert_array_equal(np.delete(obs.H, i, axis=1), np.delete(ref.H, i, axis=1))


def test_the_gain_truth_is_the_models_own_gain():
    truth, base, e = _pair("bonder_b/gain/nocoh")
    obs, ref = observe_data(truth, (e,), {}, F), observe_data(base, (), {}, F)
    np.testing.assert_allclose(obs.H[:, 0], e.spec["gain"] * ref.H[:, 0], rtol=1e-12)
    np.testing.assert_allclose(obs.H[:, 1:], ref.H[:, 1:], rtol=1e-12)


def test_strengthening_makes_every_later_cause_show_more():
    for case in open_cases()[::4]:
        e = case.effects[0]
        s = strengthen(e)
        assert s.effect == e.effect and s.location == e.location and s.spec != e.spec
    g = strengthen(TruthEffect("transducer_gain", "out.y", {"gain": 0.9}))
    assert np.log(g.spec["gain"]) == pytest.approx(1.5 * np.log(0.9))


def test_measuring_through_the_observation_keeps_the_first_cases_files(tmp_path):
    """The files of a first-list case are the same whether its signal factor is applied
    directly or through the observation (the runner's path now)."""
    case = next(c for c in all_cases() if c.name.startswith("bonder_b/sd/"))
    d = design(case.design)
    truth = truth_model(UrdfDocument.load(d.path), case.effects, case.seed)

    def factor(ff, o, i):
        return signal_factor(case.effects, ff, o, i)

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    _, old = measure(truth, d.operating_points, F, "nocoh", factor, tmp_path / "a", 3)
    _, new = measure(truth, d.operating_points, F, "nocoh", factor, tmp_path / "b", 3,
                     case.effects)  # fmt: skip
    for a, b in zip(old, new, strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_bending_links_remainder_is_expected_where_its_hinges_drive_the_machine():
    """The clamped first mode sets the arm's hinges; in the assembled machine the modes the
    hinges drive lie elsewhere, and a remainder is scored against those: one band around
    each mode whose most energetic DOF is a hinge."""
    from benchmark.truth import hinge_modes

    from bondid.modes.analysis import modal_analysis

    truth, base, e = _pair("polar/flk/mob")
    modes = modal_analysis(build_affine_model(truth).linear_model()).vibration_modes()
    bending = sorted(m.f_hz for m in modes if m.dominant_dof.startswith("arm_truth_hinge"))
    assert len(bending) == 4 and hinge_modes(truth, "arm") == pytest.approx(bending)
    # the clamped first mode is not where the machine's hinge modes are
    assert min(bending) > 1.4 * e.spec["f"]
    expected = expected_remainder(e, truth)
    assert [r.kind for r in expected] == ["missing_mode"] * 4
    assert [r.band_hz for r in expected] == [(0.7 * f, 1.4 * f) for f in hinge_modes(truth, "arm")]
    # without the truth model: the band around the clamped mode, as before
    (r0,) = expected_remainder(e)
    assert r0.band_hz == pytest.approx((0.7 * e.spec["f"], 1.4 * e.spec["f"]))
    assert hinge_modes(base, "arm") == []
