"""Pseudo-inertia and log-Cholesky maps of bondid against Pinocchio 4.1's ``PseudoInertia`` and
``LogCholeskyParameters`` and against the textbook formulas, to 1e-12 (relative): the ground
on which bondid uses Pinocchio's maps instead of its own."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from bondid.consistency.log_cholesky import (
    _U_INDEX,
    jacobian_pi_theta,
    pi_from_theta,
    pi_from_theta_casadi,
    theta_from_pi,
)
from bondid.consistency.pseudo_inertia import pi_from_pseudo_inertia, pseudo_inertia

#: relative agreement required
TOL = 1e-12
N = 200


def _thetas() -> np.ndarray:
    return np.random.default_rng(7).normal(scale=0.7, size=(N, 10))


def _U(theta: np.ndarray) -> np.ndarray:
    """The textbook upper factor (Rucker & Wensing 2022), Pinocchio's θ order."""
    U = np.zeros((4, 4))
    for k, (i, j) in enumerate(_U_INDEX):
        U[i, j] = np.exp(theta[1 + k]) if i == j else theta[1 + k]
    U[3, 3] = 1.0
    return np.exp(theta[0]) * U


def _pi_of_J(J: np.ndarray) -> np.ndarray:
    """``pi`` of a pseudo-inertia by the textbook formula: m = J33, h = J[:3, 3],
    Ī = tr(Σ) 𝟙 − Σ, Pinocchio's order Ixx, Ixy, Iyy, Ixz, Iyz, Izz."""
    S = J[:3, :3]
    inertia = np.trace(S) * np.eye(3) - S
    idx = ((0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2))
    return np.array([J[3, 3], *J[:3, 3], *(inertia[i, j] for i, j in idx)])


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


def test_log_cholesky_map_and_jacobian_agree_with_pinocchio_and_the_formula():
    for th in _thetas():
        lc = pin.LogCholeskyParameters(th)
        ref = _pi_of_J(_U(th) @ _U(th).T)
        assert _rel(lc.toDynamicParameters(), ref) < TOL
        assert _rel(pi_from_theta(th), ref) < TOL
        assert _rel(np.asarray(pi_from_theta_casadi(th)).ravel(), ref) < TOL
        assert _rel(jacobian_pi_theta(th), lc.calculateJacobian()) < TOL
        # the inverse map bondid carries (Pinocchio has none) round-trips
        assert np.abs(theta_from_pi(ref) - th).max() < 1e-9


def test_jacobian_against_finite_differences():
    th = _thetas()[0]
    h = 1e-6
    fd = np.column_stack([
        (pi_from_theta(th + h * e) - pi_from_theta(th - h * e)) / (2 * h) for e in np.eye(10)
    ])  # fmt: skip
    assert _rel(jacobian_pi_theta(th), fd) < 1e-8


def test_pseudo_inertia_both_ways_agree_with_pinocchio():
    for th in _thetas():
        pi = _pi_of_J(_U(th) @ _U(th).T)
        J = pin.PseudoInertia.FromDynamicParameters(pi).toMatrix()
        assert _rel(pseudo_inertia(pi), J) < TOL
        assert _rel(pi_from_pseudo_inertia(J), pi) < TOL
        assert _rel(J, _U(th) @ _U(th).T) < TOL
