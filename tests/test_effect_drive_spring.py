"""``drive_spring``: a spring and damper in parallel with a drive (a cable carrier)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from effect_support import GRAD_TOL, gradient_error, noisy_data, refit_of, solve

from bondid.diagnose.augmented import with_values
from bondid.diagnose.effects import get_effect
from bondid.linear.affine import build_affine_model
from bondid.model import UrdfDocument, get_parameter

MODEL = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03})
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
#: round trip at 0.5 % noise on 2 × 150 lines: the spring, and its damper (a suspension mode
#: at 8 Hz, damped 5 %, in a band from 1 Hz)
REL_K, REL_D = 0.02, 0.10


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def test_candidates_are_the_drives_without_a_spring(doc):
    cands = get_effect("drive_spring").candidates(doc)
    assert [c.location for c in cands] == ["x", "y"]  # z (the rocker) has a spring already
    c = cands[0]
    assert [p.members for p in c.parameters] == [(("x.stiffness", 1.0),), (("x.damping", 1.0),)]
    assert c.parameters[0].strength and c.ref_hz == 10.0


def test_the_drive_levels_off_at_its_spring(doc):
    """Known answer: with the spring, the drive's static receptance is ``1/k``, and its
    suspension mode sits near the candidate's reference frequency (the spring alone on the
    drive's effective inertia: the rocker's own soft mode nearby moves it by 25 %)."""
    e = get_effect("drive_spring")
    c = e.candidates(doc)[0]
    aug = e.augment(doc, c)
    am = build_affine_model(aug)
    H = am.linear_model().frf(np.array([1e-4]))
    k = c.parameters[0].initial
    assert H[am.outputs.index("x"), am.inputs.index("x"), 0].real == pytest.approx(1 / k, rel=1e-6)
    assert get_parameter(aug, "x.damping") == pytest.approx(c.parameters[1].initial, rel=1e-12)
    A = am.linear_model().state_space()[0]
    f_modes = np.abs(np.linalg.eigvals(A)) / (2 * np.pi)
    assert np.min(np.abs(f_modes - c.ref_hz)) < 0.3 * c.ref_hz


def test_a_cable_carrier_spring_is_refitted(doc):
    """Known answer: the bonder whose x drive is held by a spring that puts its suspension
    mode at 8 Hz, 5 % damped; the candidate refitted from 30 % too stiff and 50 % too much
    damping recovers both."""
    e = get_effect("drive_spring")
    c = e.candidates(doc)[0]
    k = c.parameters[0].initial * (8.0 / c.ref_hz) ** 2
    d = c.parameters[1].initial * 2.5 * (8.0 / c.ref_hz)  # 5 % instead of 2 %
    truth = e.augment(doc, with_values(c, [k, d]))
    data = noisy_data(truth, OPS)
    refit = refit_of(doc, FEW, data, with_values(c, [1.3 * k, 1.5 * d]))
    assert gradient_error(refit) < GRAD_TOL
    got_k, got_d = solve(refit)
    assert got_k == pytest.approx(k, rel=REL_K)
    assert got_d == pytest.approx(d, rel=REL_D)
