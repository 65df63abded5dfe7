"""``actuator_lag``: a second-order lag ``1/(1 + jωT − ω²T₂²)`` on the inputs (amplifier,
current loop), of which the first-order lag ``1/(1 + jωT)`` is the limit ``T₂ → 0``.

An amplifier with its current loop is seldom one pole: two real poles ``T₁``, ``T₂'`` give
``T = T₁ + T₂'`` and ``T₂² = T₁·T₂'`` (``T ≥ 2T₂``), a loop with some overshoot complex poles
(``T < 2T₂``), and ``T₂`` far below ``T`` the first-order lag. A first-order candidate
refitted to data of a two-pole lag (poles a decade apart) stays well above the noise level,
its one pole splitting the difference; the second-order form reaches it.

Candidates: each input (actuated) joint alone (location = the joint, acting on its column of
channels ``*.IN``) and all inputs together (location ``"all"``, one common lag). An FRF
modifier with the exact derivatives ``∂G/∂T = −jω G²`` and ``∂G/∂T₂ = 2ω²T₂ G²``. Start
T = 50 µs (a 3.2 kHz corner) and T₂ = T/8 (the second pole 63× further out: nearly first
order), scanned together from 1 µs to 3 ms; bounds 1 ns to 50 ms for T, 0.1 ns to 50 ms for
T₂. ``T``, the lag time (the sum of the time constants), is the effect's strength.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from . import register
from .base import Candidate, Effect, NewParameter, per_joint_candidates
from .sensor_delay import row_mask

T0 = 5e-5
#: the start of the second-order time ``T₂`` relative to ``T``
T2_SHARE = 1.0 / 8.0
SCAN = tuple(float(t / T0) for t in np.geomspace(1e-6, 3e-3, 54))


def lag_factor(w: np.ndarray, T: float, T2: float) -> np.ndarray:
    """``1/(1 + jωT − ω²T₂²)`` at angular frequencies ``w`` [rad/s] (``(n,)`` complex)."""
    return 1.0 / (1.0 + 1j * w * T - (w * T2) ** 2)


@register
class ActuatorLag(Effect):
    name = "actuator_lag"
    description = "second-order lag on the inputs (per input joint, or all)"
    is_modifier = True

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        params = (
            NewParameter("T", T0, 1e-9, 5e-2, "s", scan=1.0, strength=True),
            NewParameter("T2", T0 * T2_SHARE, 1e-10, 5e-2, "s", scan=1.0),
        )
        return per_joint_candidates(self, doc, params, SCAN, "lag on input(s)")

    def modifier(self, candidate, values, freq_hz, outputs, inputs):
        T, T2 = (float(v) for v in values)
        w = 2 * np.pi * np.asarray(freq_hz, float)
        g = lag_factor(w, T, T2)
        mask = row_mask(candidate.location, tuple(inputs))
        G = np.ones((len(outputs), len(inputs), w.size), complex)
        G[:, mask] = g
        dG = np.zeros((*G.shape, 2), complex)
        dG[:, mask, :, 0] = -1j * w * g**2
        dG[:, mask, :, 1] = 2.0 * w**2 * T2 * g**2
        return G, dG
