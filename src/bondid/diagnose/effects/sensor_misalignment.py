"""``sensor_misalignment``: cross-talk between outputs, an output mixing matrix near identity.

A sensor whose measuring direction is turned by a small angle α toward another measured
direction reads ``cos α`` of its own motion plus ``sin α`` of the other (an interferometer or a
scale not square to its axis, a tilted accelerometer), and electrical cross-talk between two
channels adds a share of one to the other alike. To first order that is

    H' = (I + E) H,

``E`` with small off-diagonal entries ``E[a, b]`` (how much of output ``b`` appears in output
``a``): the leakage into a cross channel is proportional to a direct one. An FRF modifier that
mixes the rows (:meth:`~.base.Effect.mixing`), no elementwise factor.

Candidates: every pair of sensors that measure the same kind of quantity (two translations
or two rotations; location ``"a,b"`` in output order, parameters ``E[a, b]`` and
``E[b, a]``), and every such entry together (location ``"all"``). Mixing a translation with a
rotation would need a length, so those entries are left out. Each entry is a *signed*
parameter near 0 (``NewParameter.signed``, refitted on a linear scale in steps of 0.02,
about 1°), bounded to ±0.5; each is a strength: the Wald test ``|E[a, b]|/std`` is that of a
zero entry. Exact derivatives: ``∂L/∂E[a, b]`` is the unit matrix of entry ``(a, b)``.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from ...cost.modifier import Mixing
from ...model.document import UrdfDocument
from . import register
from .base import Candidate, Effect, NewParameter
from .channels import sensor_kind, sensors

#: bounds of every entry (±30°: far beyond a misalignment, room for a strong cross-talk)
LIMIT = 0.5
#: the refit's step of an entry (≈ 1°)
TYPICAL = 0.02


def _entry(a: str, b: str) -> NewParameter:
    return NewParameter(f"e_{a}_{b}", 0.0, -LIMIT, LIMIT, "1", strength=True, signed=True,
                        typical=TYPICAL)  # fmt: skip


@register
class SensorMisalignment(Effect):
    name = "sensor_misalignment"
    description = "cross-talk / misalignment between outputs: an output mixing matrix near I"
    is_modifier = True
    mixes = True

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        names = sensors(doc)
        kinds = {n: sensor_kind(doc, n) for n in names}
        pairs = [(a, b) for a, b in combinations(names, 2) if kinds[a] == kinds[b]]
        out = []
        for a, b in pairs:
            entries = [[a, b], [b, a]]
            out.append(Candidate(
                self.name, f"{a},{b}", (_entry(a, b), _entry(b, a)), {"entries": entries}, (),
                f"cross-talk between outputs {a} and {b}",
            ))  # fmt: skip
        if len(pairs) > 1:
            entries = [e for a, b in pairs for e in ([a, b], [b, a])]
            out.append(Candidate(
                self.name, "all", tuple(_entry(a, b) for a, b in entries), {"entries": entries},
                (), "cross-talk between every pair of outputs of one kind",
            ))  # fmt: skip
        return out

    def mixing(self, candidate, values, outputs, inputs):
        n = len(outputs)
        entries = candidate.spec["entries"]
        L = np.eye(n, dtype=complex)
        dL = np.zeros((n, n, len(entries)), complex)
        for k, (a, b) in enumerate(entries):
            if a in outputs and b in outputs:
                i, j = outputs.index(a), outputs.index(b)
                L[i, j] += float(values[k])
                dL[i, j, k] = 1.0
        return Mixing(left=L, dleft=dL)
