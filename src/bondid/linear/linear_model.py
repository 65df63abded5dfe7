"""The linearised machine at one operating point: :class:`LinearModel`."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


def _symmetric(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)


def viscous_equivalent(M: np.ndarray, K: np.ndarray, D: np.ndarray, G: np.ndarray) -> np.ndarray:
    """The damping ``(n, n)`` that dissipates as much as ``D`` and the hysteretic stiffness
    ``G`` together at each vibration mode's own frequency: ``D + M Φ diag(φᵢᵀGφᵢ/ωᵢ) Φᵀ M``
    over the mass-normalised undamped modes ``Φ`` of ``(M, K)`` (exact at every resonance of
    a loss factor on a symmetric K; rigid-body modes take none). SI units, ``(n, n)`` each."""
    import scipy.linalg

    w2, phi = scipy.linalg.eigh(_symmetric(K), _symmetric(M))
    keep = w2 > 1e-12 * max(float(np.abs(w2).max(initial=0.0)), 1e-300)
    phi, w = phi[:, keep], np.sqrt(w2[keep])
    g = np.einsum("ni,nm,mi->i", phi, G, phi)
    MP = M @ phi
    return D + (MP * (g / w)) @ MP.T


def state_matrix(M: np.ndarray, K: np.ndarray, D: np.ndarray) -> np.ndarray:
    """The state matrix ``A`` ``(2n, 2n)`` of ``M q̈ + D q̇ + K q = 0`` with ``x = [q, q̇]``
    (``M``, ``K``, ``D`` ``(n, n)``, SI units; ``M`` invertible)."""
    n = M.shape[0]
    Minv = np.linalg.inv(M)
    return np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ D]])


#: an eigenvalue is oscillatory (one of a conjugate pair) when Im λ > this · max(1, |λ|)
OSCILLATORY_RTOL = 1e-9


def is_oscillatory(lam: np.ndarray) -> np.ndarray:
    """Boolean mask of the eigenvalues ``lam`` with ``Im λ > 0`` beyond rounding."""
    lam = np.asarray(lam)
    return lam.imag > OSCILLATORY_RTOL * np.maximum(1.0, np.abs(lam))


def state_eigenvalues(M: np.ndarray, K: np.ndarray, D: np.ndarray) -> np.ndarray:
    """The eigenvalues λ ``(2n,)`` (1/s) of the state matrix of ``M q̈ + D q̇ + K q = 0``
    (``M``, ``K``, ``D`` ``(n, n)`` in SI units; ``(0,)`` when ``n = 0``).

    Raises:
        numpy.linalg.LinAlgError: a singular ``M``.
    """
    if M.shape[0] == 0:
        return np.zeros(0, dtype=complex)
    return np.linalg.eigvals(state_matrix(M, K, D))


def underdamped(M: np.ndarray, K: np.ndarray, D: np.ndarray) -> list[tuple[float, float]]:
    """``(f_hz, ζ)`` of the oscillatory eigenvalues of ``M q̈ + D q̇ + K q = 0``, lowest first
    (``M``, ``K``, ``D`` ``(n, n)`` in SI units)."""
    lam = state_eigenvalues(M, K, D)
    return sorted(
        (float(abs(v) / (2.0 * np.pi)), float(-v.real / abs(v))) for v in lam[is_oscillatory(lam)]
    )


@dataclass
class LinearModel:
    """M δq̈ + D δq̇ + K δq = B u,  y = C δq (velocity coordinates of the model).

    Attributes:
        M: mass matrix, ``(nv, nv)``, kg / kg·m².
        K: stiffness (joint springs + gravity stiffness ∂g/∂q), ``(nv, nv)``.
        D: damping, ``(nv, nv)``.
        B: input matrix, ``(nv, n_in)``: input i is a generalised force on a joint.
        C: output matrix, ``(n_out, nv)``: output i is a joint position.
        dofs: joint name of each velocity coordinate, length ``nv``.
        inputs: input (excited joint) names, length ``n_in``.
        outputs: output (sensed joint) names, length ``n_out``.
        q0: the configuration, ``(nq,)``.
        G: hysteretic stiffness ``(nv, nv)`` (the structural loss factor times K): the
            dynamic stiffness is ``K + jG − ω²M + jωD``; None without one. It has no
            time-domain form: :meth:`viscous` gives the model the modes and the state space
            use.
    """

    M: np.ndarray
    K: np.ndarray
    D: np.ndarray
    B: np.ndarray
    C: np.ndarray
    dofs: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    q0: np.ndarray
    G: np.ndarray | None = None

    @property
    def nv(self) -> int:
        return int(self.M.shape[0])

    def viscous(self) -> LinearModel:
        """This model with its hysteretic stiffness replaced by its viscous equivalent
        (:func:`viscous_equivalent`); itself without ``G``."""
        if self.G is None:
            return self
        return replace(self, D=viscous_equivalent(self.M, self.K, self.D, self.G), G=None)

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(A (2nv,2nv), B (2nv,n_in), C (n_out,2nv), D (n_out,n_in)) with x = [δq, δq̇]; a
        hysteretic stiffness enters as its viscous equivalent (:meth:`viscous`)."""
        n = self.nv
        A = state_matrix(self.M, self.K, self.viscous().D)
        Bs = np.vstack([np.zeros((n, self.B.shape[1])), np.linalg.inv(self.M) @ self.B])
        Cs = np.hstack([self.C, np.zeros((self.C.shape[0], n))])
        Ds = np.zeros((self.C.shape[0], self.B.shape[1]))
        return A, Bs, Cs, Ds

    def frf(self, freq_hz: np.ndarray, quantity: str = "receptance") -> np.ndarray:
        """FRF ``(n_out, n_in, n_freq)`` at ``freq_hz`` (Hz); see :func:`bondid.frf.frf`."""
        from .response import frf

        return frf(self.M, self.K, self.D, self.B, self.C, freq_hz, quantity, G=self.G)
