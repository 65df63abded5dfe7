"""``flexible_link``: a link cut across its length into two consistent parts and a hinge."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from effect_support import GRAD_TOL, gradient_error, noisy_data, refit_of, solve

from bondid.diagnose.augmented import with_values
from bondid.diagnose.effects import get_effect
from bondid.diagnose.effects.flexible_link import FRACTIONS, distal_name
from bondid.diagnose.effects.link_split import Inertial, long_axis, split_inertial
from bondid.linear.affine import build_affine_model
from bondid.model import UrdfDocument, get_parameter, set_parameter
from bondid.model.parameters import link_inertial

ROOT = Path(__file__).resolve().parents[1]
POLAR = ROOT / "tools" / "benchmark" / "designs" / "polar_handler.urdf"
OPS = ({}, {"ext": 0.12, "lift": -0.03, "rot": 0.5})
FEW = ["arm.mass", "turntable.mass", "fork.mass", "table_rx.stiffness"]
#: the parts' moments add up to the link's to rounding
SAME = 1e-12
#: round trip at 0.5 % noise on 2 × 150 lines: the bending stiffnesses (modes at 700 and
#: 1000 Hz) and their dampers
REL_K, REL_D = 0.02, 0.25


@pytest.fixture(scope="module")
def polar() -> UrdfDocument:
    return UrdfDocument.load(POLAR)


def _pseudo(m: float, c: np.ndarray, I_c: np.ndarray) -> np.ndarray:
    """Pseudo-inertia ``[[Σ, h], [hᵀ, m]]`` about the link origin."""
    sigma_c = 0.5 * np.trace(I_c) * np.eye(3) - I_c
    J = np.zeros((4, 4))
    J[:3, :3] = sigma_c + m * np.outer(c, c)
    J[:3, 3] = J[3, :3] = m * c
    J[3, 3] = m
    return J


def test_candidates_are_the_long_bodies(polar):
    e = get_effect("flexible_link")
    cands = e.candidates(polar)
    assert [c.location for c in cands] == ["arm", "fork"]  # the turntable is not long
    c = cands[0]
    assert [v.spec["fraction"] for v in (c, *c.variants)] == list(FRACTIONS)
    assert c.spec["replaces_inertial"] == ["arm"]
    assert [p.name for p in c.parameters] == [
        "stiffness_ry", "stiffness_rz", "damping_ry", "damping_rz"]  # fmt: skip


@pytest.mark.parametrize("fraction", FRACTIONS)
def test_the_parts_are_consistent_and_add_up_to_the_link(polar, fraction):
    m, c, I_c = link_inertial(polar, "arm")
    ax = long_axis(polar, "arm")
    assert ax is not None and np.allclose(np.abs(ax.axis), [1, 0, 0], atol=5e-3)
    assert ax.axis[0] > 0  # pointing away from the origin (the ext joint) toward the tip
    near, far = split_inertial(Inertial(m, c, I_c), ax, ax.cut(fraction))
    J = _pseudo(m, c, I_c)
    Ja, Jb = _pseudo(near.mass, near.com, near.inertia), _pseudo(far.mass, far.com, far.inertia)
    np.testing.assert_allclose(Ja + Jb, J, rtol=0, atol=SAME * np.abs(J).max())
    assert np.linalg.eigvalsh(Ja).min() > 0 and np.linalg.eigvalsh(Jb).min() > 0
    # the cut: the stated fraction of the way from the origin's projection to the far end
    u = ax.cut(fraction)
    assert (u - ax.u_origin) / (ax.half[0] - ax.u_origin) == pytest.approx(fraction)


def test_a_stiff_hinge_gives_back_the_rigid_link(polar):
    """Known answer: with hinges 10⁸ times stiffer than the start (modes near 4 MHz), the
    cut model's FRF is the nominal one (the parts and the re-parented fork placed as before;
    the difference falls as 1/k: 1e-3 at 10⁶)."""
    e = get_effect("flexible_link")
    c = e.candidates(polar)[0]
    aug = e.augment(polar, c)
    for p in c.parameters[:2]:
        set_parameter(aug, p.members[0][0], 1e8 * p.initial)
    assert aug.joint("lift").parent == distal_name("arm")
    assert get_parameter(aug, "arm.mass") + get_parameter(aug, "arm_distal.mass") == (
        pytest.approx(get_parameter(polar, "arm.mass"), rel=1e-14))  # fmt: skip
    f = np.geomspace(1.0, 4000.0, 200)
    for op in OPS:
        H0 = build_affine_model(polar, op).linear_model().frf(f)
        H1 = build_affine_model(aug, op).linear_model().frf(f)
        assert np.max(np.abs(np.log(H1 / H0))) < 1e-4


def test_a_bending_arm_is_refitted(polar):
    """Known answer: the polar handler's arm bending at half its length, its two hinge modes
    at 700 Hz (vertical) and 1 kHz (horizontal), 2 % damped; the candidate refitted from
    30 % too stiff recovers the stiffnesses. The arm's own mass is one of the refitted
    nominal parameters: it now means the near part's (the refit re-centres it)."""
    e = get_effect("flexible_link")
    c = e.candidates(polar)[0]
    p0 = [p.initial for p in c.parameters]
    s = np.array([(700 / c.ref_hz) ** 2, (1000 / c.ref_hz) ** 2])
    truth_v = np.r_[np.array(p0[:2]) * s, np.array(p0[2:]) * np.sqrt(s)]
    truth = e.augment(polar, with_values(c, truth_v))
    data = noisy_data(truth, OPS)
    start = np.r_[1.3 * truth_v[:2], truth_v[2:]]
    refit = refit_of(polar, FEW, data, with_values(c, start))
    i = refit.nominal.names.index("arm.mass")
    assert refit.nominal.centre[i] == pytest.approx(get_parameter(truth, "arm.mass"), rel=1e-12)
    assert gradient_error(refit) < GRAD_TOL
    got = solve(refit)
    np.testing.assert_allclose(got[:2], truth_v[:2], rtol=REL_K)
    np.testing.assert_allclose(got[2:], truth_v[2:], rtol=REL_D)
