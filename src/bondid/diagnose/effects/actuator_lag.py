"""``actuator_lag``: a first-order lag ``1/(1 + jωT)`` on the inputs (amplifier/current loop).

Candidates: each input (actuated) joint alone (location = the joint, acting on its column of
channels ``*.IN``) and all inputs together (location ``"all"``, one common T). An FRF
modifier with the exact derivative ``∂G/∂T = −jω/(1 + jωT)²``. Start T = 50 µs (a 3.2 kHz
corner), scanned from 1 µs to 3 ms; bounds 1 ns to 50 ms.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from . import register
from .base import Candidate, Effect, NewParameter, per_joint_candidates
from .sensor_delay import row_mask

T0 = 5e-5
SCAN = tuple(float(t / T0) for t in np.geomspace(1e-6, 3e-3, 54))


@register
class ActuatorLag(Effect):
    name = "actuator_lag"
    description = "first-order lag on the inputs (per input joint, or all)"
    is_modifier = True

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        p = NewParameter("T", T0, 1e-9, 5e-2, "s", scan=1.0, strength=True)
        return per_joint_candidates(self, doc, p, SCAN, "lag on input(s)")

    def modifier(self, candidate, values, freq_hz, outputs, inputs):
        T = float(values[0])
        jw = 2j * np.pi * np.asarray(freq_hz, float)
        g = 1.0 / (1.0 + jw * T)
        mask = row_mask(candidate.location, tuple(inputs))
        G = np.ones((len(outputs), len(inputs), jw.size), complex)
        G[:, mask] = g
        dG = np.zeros((*G.shape, 1), complex)
        dG[:, mask, :, 0] = -jw * g**2
        return G, dG
