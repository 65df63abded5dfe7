"""``sensor_dynamics``: a sensor on a compliant mount, a mass-spring-damper seen in its output
only.

A read head, a scale, a target mirror or an accelerometer fixed to the measured body through
a compliant bracket (or a glue or wax layer) vibrates on its mount: its deflection is the
motion of the mount point filtered by the mount's own mode, ``(G − 1)·m``, with the
base-excitation transmissibility of a single degree of freedom

    G(ω) = (ωn² + 2jζωnω) / (ωn² − ω² + 2jζωnω),   ωn = 2π f_n,

which is 1 well below the mount's mode, peaks there and rolls off above it. The reading is
the sensor's coordinate ``q`` plus that deflection. The mount point's motion ``m`` is not the
reading: a reading is relative (a scale on a carrier that moves too), and a head above or
beside the measured point also moves with the body's rotations, so ``m`` is a share of ``q``
that differs from one input to the next (even in sign: a cross channel's ``q`` may be a
small relative motion while the mount rocks with the body). Near ``f_n``, where ``G − 1`` is
large, that share is a number per input column, ``c_j``:

    H'[row, j] = (1 + c_j (G − 1)) · H[row, j],

so well above the mode the reading keeps ``(1 − c_j)`` of its coordinate instead of rolling
off. With every ``c_j = 1`` the mount moves as its reading (a stage over a still frame) and
the row is ``G·H``; a model without the shares puts ``G``'s roll-off and sign change above
``f_n`` on every column and lands the refit's mode out of the band. The sensor is light
against the machine, so the mount changes its own reading and nothing else: an FRF modifier
on that output's row ``OUT.*``.

Candidates: each sensor (the transmitted joints' encoders and the measurement points;
location = the output), with a share per actuator, and all of them with one common mount
(location ``"all"``) with every share 1 (a share per row and column would be a free mode in
every channel, not a mount). New parameters: ``f_n`` [Hz] (the effect's strength: the mount
is absent as ``f_n → ∞``, so its ``value/std`` is the Wald test of a zero compliance, as for a
stiffness), the damping ratio ``zeta`` and the shares ``c_<input>`` (signed, start 1).
Exact derivatives ``∂G/∂ωn = −2ω²(ωn + jζω)/D²`` and ``∂G/∂ζ = −2jωnω³/D²`` (``D`` the
denominator), times ``c_j``; ``∂H'/∂c_j ∝ G − 1``. Start: 1 kHz, 5 %; ζ at most
:data:`ZETA_MAX` (a mount is a lightly damped mode). ``f_n`` follows the
starting-point scan with exponent ½ and ``ref_hz`` = its start, so that scaling by
``(f/ref_hz)²`` puts the mount's mode at ``f`` (:mod:`..scan_grid`); the scan runs from 50 Hz
to 12 kHz.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from . import register
from .base import Candidate, Effect, NewParameter
from .channels import actuators, sensors
from .sensor_delay import row_mask

F0_HZ = 1000.0
ZETA0 = 0.05
SCAN_HZ = tuple(float(f) for f in np.geomspace(50.0, 12000.0, 60))
#: the most damping a mount is given: its transmissibility still peaks (|G(f_n)| ≈ 2.2); a
#: heavier-damped one shows no mode, only a smooth gain and phase change that a bandwidth
#: limit or a delay makes, and above the band it would stand in for those
ZETA_MAX = 0.25
#: bound of a share (a mount point moving several times its reading, either sign: a small
#: relative reading under a rocking body) and its refit step
SHARE_LIMIT, SHARE_STEP = 5.0, 0.25


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
        mode = (
            NewParameter("f_n", F0_HZ, 20.0, 40000.0, "Hz", scan=0.5, strength=True),
            NewParameter("zeta", ZETA0, 1e-3, ZETA_MAX, "1"),
        )
        ins = actuators(doc)
        shares = tuple(NewParameter(f"c_{i}", 1.0, -SHARE_LIMIT, SHARE_LIMIT, "1", signed=True,
                                    typical=SHARE_STEP) for i in ins)  # fmt: skip
        grid = tuple((f / F0_HZ) ** 2 for f in SCAN_HZ)
        what = "compliant mount of sensor(s)"
        out = [Candidate(self.name, loc, (*mode, *shares), {"shares": list(ins)}, grid,
                         f"{what} {loc}", F0_HZ) for loc in sensors(doc)]  # fmt: skip
        out.append(Candidate(self.name, "all", mode, {"shares": []}, grid, f"{what} all", F0_HZ))
        return out

    def modifier(self, candidate, values, freq_hz, outputs, inputs):
        fn, zeta = (float(v) for v in values[:2])
        w = 2 * np.pi * np.asarray(freq_hz, float)
        g, dg_dwn, dg_dzeta = transmissibility(w, 2 * np.pi * fn, zeta)
        named = list(candidate.spec.get("shares", []))
        c = np.ones(len(inputs))
        for k, name in enumerate(named):
            if name in inputs:
                c[inputs.index(name)] = float(values[2 + k])
        mask = row_mask(candidate.location, tuple(outputs))
        G = np.ones((len(outputs), len(inputs), w.size), complex)
        G[mask] = 1.0 + c[:, None] * (g - 1.0)
        dG = np.zeros((*G.shape, len(values)), complex)
        dG[mask, :, :, 0] = 2 * np.pi * c[:, None] * dg_dwn
        dG[mask, :, :, 1] = c[:, None] * dg_dzeta
        for k, name in enumerate(named):
            if name in inputs:
                dG[mask, inputs.index(name), :, 2 + k] = g - 1.0
        return G, dG
