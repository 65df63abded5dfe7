"""``transducer_gain``: a gain error of one sensor (an output row) or one actuator (an input
column): a sensitivity, a scale factor, a motor constant or an amplifier gain that is not the
model's.

``H_meas = g · H`` on the row ``OUT.*`` (location ``"out.OUT"``) or the column ``*.IN``
(location ``"in.IN"``), the factor of the model's ``[gains]`` (``gain.out.OUT``,
``gain.in.IN``, :mod:`bondid.model.points`) as a candidate. It is fitted as its logarithm
``log_gain = ln g``: a *signed* parameter (``NewParameter.signed``, refitted on a linear scale
in steps of 0.05, 5 %), 0 when the gain is right, bounded to ±1.5 (a factor 4.5 either way);
it is the strength, so the verdict's Wald test is ``|ln g|/std``. An FRF modifier with the
exact derivative ``∂G/∂ln g = G``. A common gain of every output or every input is not a
candidate: it scales the whole FRF as the machine's masses and springs together do.
"""

from __future__ import annotations

import numpy as np

from ...model.document import UrdfDocument
from . import register
from .base import Candidate, Effect, NewParameter
from .channels import actuators, sensors

LIMIT = 1.5
TYPICAL = 0.05


@register
class TransducerGain(Effect):
    name = "transducer_gain"
    description = "gain error of one sensor (output row) or one actuator (input column)"
    is_modifier = True

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        p = NewParameter("log_gain", 0.0, -LIMIT, LIMIT, "1", strength=True, signed=True,
                         typical=TYPICAL)  # fmt: skip
        out = [Candidate(self.name, f"out.{s}", (p,), {"side": "out", "channel": s}, (),
                         f"gain error of sensor {s}") for s in sensors(doc)]  # fmt: skip
        out += [Candidate(self.name, f"in.{a}", (p,), {"side": "in", "channel": a}, (),
                          f"gain error of actuator {a}") for a in actuators(doc)]  # fmt: skip
        return out

    def modifier(self, candidate, values, freq_hz, outputs, inputs):
        g = float(np.exp(float(values[0])))
        shape = (len(outputs), len(inputs), np.size(freq_hz))
        G = np.ones(shape, complex)
        dG = np.zeros((*shape, 1), complex)
        side, chan = candidate.spec["side"], candidate.spec["channel"]
        names = outputs if side == "out" else inputs
        if chan in names:
            i = names.index(chan)
            idx = (i,) if side == "out" else (slice(None), i)
            G[idx] = g
            dG[(*idx, Ellipsis, 0)] = g
        return G, dG
