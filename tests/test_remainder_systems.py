"""The synthetic machine of the remainder tests, and checks of it.

A 6-DOF system with three free (rigid-body) drives ``x``, ``y``, ``z`` (their positions are
the outputs, their forces the inputs) and three flexible modes, built in modal coordinates so
its modes are known exactly. The other test_remainder_* files build "measured" data from it
with a known cause and noise, and check what :func:`describe_remainder` says.
"""

from __future__ import annotations

import numpy as np

from bondid.data import FrfData
from bondid.data.noise import add_measurement_noise

NAMES = ("x", "y", "z")
#: the flexible modes [Hz] and their damping
F_FLEX = (150.0, 430.0, 900.0)
ZETA_FLEX = (0.02, 0.015, 0.02)
#: the frequency grid of the synthetic data [Hz]
FREQ = np.geomspace(2.0, 3000.0, 300)


def system(seed: int = 0, f_flex=F_FLEX, zeta=ZETA_FLEX) -> tuple[np.ndarray, ...]:
    """``(M, K, D)`` [kg, N/m, N·s/m] of the machine: masses ~4, 2.5, 1.2 kg on the drives,
    three rigid-body modes and the flexible modes ``f_flex`` with modal damping ``zeta``."""
    rng = np.random.default_rng(seed)
    n = 3 + len(f_flex)
    A = 0.3 * rng.standard_normal((n, n))
    M = np.diag([4.0, 2.5, 1.2, 0.8, 0.5, 0.3, 0.2, 0.15][:n]) + 0.05 * (A @ A.T)
    L = np.linalg.cholesky(M)
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    Phi = np.linalg.solve(L.T, V)  # M-orthonormal mode shapes
    w = np.r_[0.0, 0.0, 0.0, 2 * np.pi * np.asarray(f_flex)]
    z = np.r_[0.0, 0.0, 0.0, np.asarray(zeta)]
    K = M @ Phi @ np.diag(w**2) @ Phi.T @ M
    D = M @ Phi @ np.diag(2 * z * w) @ Phi.T @ M
    return M, K, D


def receptance(M: np.ndarray, K: np.ndarray, D: np.ndarray, f: np.ndarray = FREQ) -> np.ndarray:
    """``(3, 3, n_f)`` receptance of the drives (DOFs 0–2) [m/N]."""
    w = 2 * np.pi * np.asarray(f)
    Z = K[None] - (w**2)[:, None, None] * M[None] + 1j * w[:, None, None] * D[None]
    return np.moveaxis(np.linalg.inv(Z)[:, :3, :3], 0, 2)


def measured(H: np.ndarray, seed: int, f: np.ndarray = FREQ, rel: float = 0.01,
             floor_db: float = -70.0) -> FrfData:  # fmt: skip
    """``H`` with measurement noise (``rel`` relative, a floor ``floor_db`` below the
    response), its coherence the exact information weight ``S/(S + N)``."""
    Hn, coh = add_measurement_noise(H, f, rel=rel, floor_db=floor_db, rng=seed,
                                    floor_ref="response")  # fmt: skip
    return FrfData(f, NAMES, NAMES, Hn, coherence=coh)


def test_modes_of_the_system_are_as_built():
    M, K, D = system()
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])  # fmt: skip
    lam = np.linalg.eigvals(A)
    lam = lam[(lam.imag > 1e-6)]
    f = np.sort(np.abs(lam) / (2 * np.pi))
    np.testing.assert_allclose(f, F_FLEX, rtol=1e-9)


def test_drives_are_free_below_the_first_mode():
    """The drive-point receptance rises as 1/ω² at low frequency (a free axis)."""
    M, K, D = system()
    H = receptance(M, K, D, np.array([0.5, 1.0]))
    for a in range(3):
        ratio = abs(H[a, a, 0]) / abs(H[a, a, 1])
        assert abs(ratio - 4.0) < 0.01
