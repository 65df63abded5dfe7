"""``sensor_delay``: a pure time delay ``e^{−jωτ}`` on measured outputs.

Candidates: each output (sensor) joint alone (location = the joint, acting on its row of
channels ``OUT.*``) and all outputs together (location ``"all"``, one common τ). An FRF
modifier with the exact derivative ``∂G/∂τ = −jω G``. Start τ = 20 µs, scanned from 0.5 µs
to 1 ms; bounds 1 ns to 5 ms.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from . import register
from .base import Candidate, Effect, NewParameter, per_joint_candidates

TAU0 = 2e-5
SCAN = tuple(float(t / TAU0) for t in np.geomspace(5e-7, 1e-3, 54))


def row_mask(location: str | None, names: tuple[str, ...]) -> np.ndarray:
    """Boolean ``(len(names),)``: which rows/columns the effect acts on."""
    if location in (None, "all"):
        return np.ones(len(names), bool)
    return np.array([n == location for n in names])


@register
class SensorDelay(Effect):
    name = "sensor_delay"
    description = "pure time delay on the measured outputs (per output joint, or all)"
    is_modifier = True

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        p = NewParameter("tau", TAU0, 1e-9, 5e-3, "s", scan=1.0, strength=True)
        return per_joint_candidates(self, doc, p, SCAN, "delay on output(s)")

    def modifier(self, candidate, values, freq_hz, outputs, inputs):
        tau = float(values[0])
        w = 2 * np.pi * np.asarray(freq_hz, float)
        g = np.exp(-1j * w * tau)
        mask = row_mask(candidate.location, tuple(outputs))
        G = np.ones((len(outputs), len(inputs), w.size), complex)
        G[mask] = g
        dG = np.zeros((*G.shape, 1), complex)
        dG[mask, :, :, 0] = -1j * w * g
        return G, dG
