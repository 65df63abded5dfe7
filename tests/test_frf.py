"""The FRF engine against closed forms (seed eqs. 4.8, 4.13) and python-control."""

from __future__ import annotations

import control
import numpy as np
import pytest
from models import one_mass, random_pose, sprung_robot, two_mass_chain

from bondid.frf import convert_quantity, frf
from bondid.frf.jacobian import frf_and_jacobian
from bondid.linear import build_affine_model, linearise
from bondid.linear.parameter_map import ParameterMap
from bondid.model import select_parameters

FREQ = np.logspace(-1, 3.6, 400)
TOL_CLOSED_FORM = 1e-12  # relative
TOL_PEER = 1e-9  # relative, vs python-control (the figure)
TOL_TWO_MASS = 1e-9  # relative; the closed form (4.13) cancels digits near its anti-resonance


def _max_rel(a, b):
    return np.max(np.abs(a - b) / np.abs(b))


def test_one_mass_reproduces_seed_eq_4_8():
    m, k, d = 0.1363, 1.4429, 0.0031  # the seed's z-stage values
    H = linearise(one_mass(m, k, d)).frf(FREQ)
    w = 2 * np.pi * FREQ
    expected = 1.0 / (-m * w**2 + 1j * d * w + k)
    assert H.shape == (1, 1, FREQ.size)
    assert _max_rel(H[0, 0], expected) < TOL_CLOSED_FORM


def _eq_4_13(m1, m2, k1, d1, k2, d2, k12, d12, w):
    """The seed's two-mass transfer matrix (4.13)-(4.15), Z = K − ω²M + jωD."""
    det = (-(w**2) * m1 + 1j * w * (d1 + d12) + k1 + k12) * (
        -(w**2) * m2 + 1j * w * (d12 + d2) + k12 + k2
    ) - (1j * w * d12 + k12) ** 2
    H11 = -(w**2) * m2 + 1j * w * (d12 + d2) + k12 + k2
    H22 = -(w**2) * m1 + 1j * w * (d1 + d12) + k1 + k12
    H12 = 1j * w * d12 + k12
    return np.array([[H11, H12], [H12, H22]]) / det


# joint space (a, r) of the chain ground -a-> A -r-> B; physical x_A = a, x_B = a + r.
# a force on body B alone is τ = (F, F); a force on A alone is τ = (F, 0).
_T = np.array([[1.0, 0.0], [1.0, 1.0]])  # physical displacement = T @ joint displacement


def _physical(H):
    return np.einsum("ij,jkf,lk->ilf", _T, H, _T)


def test_two_mass_without_parasitic_k2_reproduces_eq_4_13():
    m1, m2, k1, d1, k12, d12 = 1.67, 0.1363, 5e4, 40.0, 1.4429e3, 0.31
    doc = two_mass_chain(m1, m2, k1, d1, k12, d12)  # body_a = m1 grounded, body_b = m2
    H = _physical(linearise(doc).frf(FREQ))
    w = 2 * np.pi * FREQ
    ref = _eq_4_13(m1, m2, k1, d1, 0.0, 0.0, k12, d12, w)
    assert _max_rel(H, ref) < TOL_TWO_MASS


def test_two_mass_with_parasitic_k2_reproduces_eq_4_13():
    """With k2, d2 > 0 (m2 grounded through the parasitic spring): joint springs in a tree
    hold two of the three springs of Fig. 7, so this case has k1 = d1 = 0 — m1 rides on m2."""
    m1, m2, k2, d2, k12, d12 = 1.67, 0.1363, 2e4, 12.0, 1.4429e3, 0.31
    doc = two_mass_chain(m2, m1, k2, d2, k12, d12)  # body_a = m2 grounded, body_b = m1
    H = _physical(linearise(doc).frf(FREQ))  # order (m2, m1)
    H = H[::-1, ::-1]  # → order (m1, m2)
    w = 2 * np.pi * FREQ
    ref = _eq_4_13(m1, m2, 0.0, 0.0, k2, d2, k12, d12, w)
    assert _max_rel(H, ref) < TOL_TWO_MASS


def _normwise_rel(a, b):
    """Worst over frequencies of ‖a − b‖_F / ‖b‖_F per frequency (matrix relative error)."""
    return np.max(np.linalg.norm(a - b, axis=(0, 1)) / np.linalg.norm(b, axis=(0, 1)))


def _control_frf(lm, freq):
    A, B, C, D = lm.state_space()
    sys = control.ss(A, B, C, D)
    resp = sys.frequency_response(2 * np.pi * freq)
    return np.asarray(resp.complex).reshape(C.shape[0], B.shape[1], freq.size)


@pytest.mark.parametrize("robot", ["ur5", "panda"])
def test_robot_frf_matches_python_control(robot):
    doc = sprung_robot(robot)
    lm = linearise(doc, random_pose(doc))
    H = lm.frf(FREQ)
    assert _normwise_rel(H, _control_frf(lm, FREQ)) < TOL_PEER


@pytest.mark.parametrize("quantity", ["mobility", "accelerance"])
def test_quantities_follow_the_exp_plus_jwt_convention(quantity):
    m, k, d = 0.5, 2e3, 1.0
    lm = linearise(one_mass(m, k, d))
    H = lm.frf(FREQ, quantity)
    w = 2 * np.pi * FREQ
    rec = 1.0 / (k - m * w**2 + 1j * d * w)
    factor = 1j * w if quantity == "mobility" else -(w**2)
    assert _max_rel(H[0, 0], factor * rec) < TOL_CLOSED_FORM
    back = convert_quantity(H, FREQ, quantity, "receptance")
    assert _max_rel(back[0, 0], rec) < TOL_CLOSED_FORM


def _fd_jacobian_error(am, pmap, p0, f):
    """Worst column-wise relative difference between ``frf_and_jacobian`` and central
    differences of the plain engine (``LinearModel.frf``)."""
    H, J = frf_and_jacobian(am, f, *pmap.jacobian(p0))
    assert _max_rel(H, am.linear_model().frf(f)) < 1e-12
    worst = 0.0
    for col in range(p0.size):
        h = 1e-6 * max(1.0, abs(p0[col]))
        up, dn = p0.copy(), p0.copy()
        up[col] += h
        dn[col] -= h
        fd = (
            am.with_values(*pmap.values(up)).linear_model().frf(f)
            - am.with_values(*pmap.values(dn)).linear_model().frf(f)
        ) / (2 * h)
        # a parameter the FRF does not depend on: both are 0 (scale 0 → no error)
        scale = max(np.abs(J[..., col]).max(), np.abs(fd).max())
        worst = max(worst, np.abs(fd - J[..., col]).max() / scale if scale > 0 else 0.0)
    return worst


def test_frf_jacobian_matches_central_differences():
    """Inputs = outputs (every joint driven and measured): the mirrored-channel path."""
    doc = sprung_robot("ur5")
    am = build_affine_model(doc, random_pose(doc))
    pmap = ParameterMap(doc, am, select_parameters(doc, ["all"]))
    assert _fd_jacobian_error(am, pmap, pmap.p0, np.logspace(0, 3, 60)) < 1e-6


@pytest.mark.parametrize("symmetric", [True, False])
def test_frf_jacobian_with_outputs_other_than_inputs(symmetric):
    """The paths the bonder does not take: outputs that are not the inputs (no mirrored
    channels; one solve with [B, Cᵀ]) and, with a non-symmetric gravity stiffness, a second
    solve with Zᵀ and the full n² contraction."""
    from dataclasses import replace

    doc = sprung_robot("ur5")
    pose = random_pose(doc)
    joints = doc.movable_joint_names
    am = build_affine_model(doc, pose, outputs=[joints[1], joints[4]])
    if not symmetric:
        skew = np.random.default_rng(3).standard_normal(am.G_basis.shape)
        am = replace(am, G_basis=am.G_basis + 5.0 * (skew - np.swapaxes(skew, 2, 3)))
    assert am.C.shape[0] == 2 and am.B.shape[1] > 2
    names = select_parameters(doc, ["all"])
    pmap = ParameterMap(doc, am, names)
    assert _fd_jacobian_error(am, pmap, pmap.p0, np.logspace(0, 3, 60)) < 1e-6


def test_engine_rejects_non_positive_frequencies():
    from bondid.exceptions import DataError

    lm = linearise(one_mass(1.0, 1.0, 0.1))
    with pytest.raises(DataError):
        frf(lm.M, lm.K, lm.D, lm.B, lm.C, np.array([0.0, 1.0]))
