"""``sensor_dynamics``: a sensor on a compliant mount, a mass-spring-damper seen in its output
only.

A read head, a scale, a target mirror or an accelerometer fixed to the measured body through
a compliant bracket (or a glue or wax layer) moves as the body's motion filtered by the
mount's own mode: the base-excitation transmissibility of a single degree of freedom,

    G(ω) = (ωn² + 2jζωnω) / (ωn² − ω² + 2jζωnω),   ωn = 2π f_n,

which is 1 well below the mount's mode, peaks there and rolls off above it. The sensor is
light against the machine, so the mount changes its own reading and nothing else: an FRF
modifier on that output's row ``OUT.*`` (every column alike).

Candidates: each sensor (the transmitted joints' encoders and the measurement points;
location = the output) and all of them with one common mount (location ``"all"``). New
parameters: ``f_n`` [Hz] (the effect's strength: the mount is absent as ``f_n → ∞``, so its
``value/std`` is the Wald test of a zero compliance, as for a stiffness) and the damping
ratio ``zeta``. Exact derivatives ``∂G/∂ωn = −2ω²(ωn + jζω)/D²`` and
``∂G/∂ζ = −2jωnω³/D²`` (``D`` the denominator). Start: 1 kHz, 5 %. ``f_n`` follows the
starting-point scan with exponent ½ and ``ref_hz`` = its start, so that scaling by
``(f/ref_hz)²`` puts the mount's mode at ``f`` (:mod:`..scan_grid`); the scan runs from 50 Hz
to 12 kHz.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from . import register
from .base import Candidate, Effect, NewParameter
from .channels import sensors
from .sensor_delay import row_mask

F0_HZ = 1000.0
ZETA0 = 0.05
SCAN_HZ = tuple(float(f) for f in np.geomspace(50.0, 12000.0, 60))


def transmissibility(
    w: np.ndarray, wn: float, zeta: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``G`` ``(n,)`` at angular frequencies ``w`` [rad/s] and its derivatives in ``ωn``
    [rad/s] and ``ζ`` (module docstring)."""
    num = wn**2 + 2j * zeta * wn * w
    den = num - w**2
    g = num / den
    dg_dwn = -2.0 * w**2 * (wn + 1j * zeta * w) / den**2
    dg_dzeta = -2j * wn * w**3 / den**2
    return g, dg_dwn, dg_dzeta


@register
class SensorDynamics(Effect):
    name = "sensor_dynamics"
    description = "a sensor on a compliant mount: a mass-spring seen in its output only"
    is_modifier = True

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        params = (
            NewParameter("f_n", F0_HZ, 20.0, 40000.0, "Hz", scan=0.5, strength=True),
            NewParameter("zeta", ZETA0, 1e-3, 1.0, "1"),
        )
        grid = tuple((f / F0_HZ) ** 2 for f in SCAN_HZ)
        what = "compliant mount of sensor(s)"
        return [
            Candidate(self.name, loc, params, {}, grid, f"{what} {loc}", F0_HZ)
            for loc in [*sensors(doc), "all"]
        ]

    def modifier(self, candidate, values, freq_hz, outputs, inputs):
        fn, zeta = (float(v) for v in values)
        w = 2 * np.pi * np.asarray(freq_hz, float)
        g, dg_dwn, dg_dzeta = transmissibility(w, 2 * np.pi * fn, zeta)
        mask = row_mask(candidate.location, tuple(outputs))
        G = np.ones((len(outputs), len(inputs), w.size), complex)
        G[mask] = g
        dG = np.zeros((*G.shape, 2), complex)
        dG[mask, :, :, 0] = 2 * np.pi * dg_dwn
        dG[mask, :, :, 1] = dg_dzeta
        return G, dG
