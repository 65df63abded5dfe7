"""Cross-talk between channels of one kind: :class:`ChannelMixing`, the base of the output
side (:mod:`.sensor_misalignment`, ``(I + E) H``) and the input side
(:mod:`.actuator_crosstalk`, ``H (I + F)``), its candidates and its matrix ``I + E``.

Two channels are paired only when they carry the same kind of quantity (two translations or
two rotations; on the input side, two forces or two torques): mixing a translation with a
rotation would need a length. Each candidate holds a list of *entries* ``[a, b]`` and one
signed parameter per entry, near 0 (``NewParameter.signed``, refitted on a linear scale in
steps of :data:`TYPICAL`, about 1°), bounded to ±:data:`LIMIT`; each is a strength, so the
Wald test ``|E|/std`` is that of a zero entry. The matrix is linear in its entries, so its
exact derivative in entry ``k`` is the unit matrix of that entry.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations

import numpy as np

from ...cost.modifier import Mixing
from ...model.document import UrdfDocument
from .base import Candidate, Effect, NewParameter
from .channels import actuators, sensor_kind, sensors

#: bounds of every entry (±30°: far beyond a misalignment, room for a strong cross-talk)
LIMIT = 0.5
#: the refit's step of an entry (≈ 1°)
TYPICAL = 0.02


def entry_parameter(prefix: str, a: str, b: str) -> NewParameter:
    """The signed parameter of the entry ``[a, b]``, named ``{prefix}_{a}_{b}``."""
    return NewParameter(f"{prefix}_{a}_{b}", 0.0, -LIMIT, LIMIT, "1", strength=True,
                        signed=True, typical=TYPICAL)  # fmt: skip


def pair_candidates(
    effect: str, doc: UrdfDocument, channels: Sequence[str], prefix: str, what: str
) -> list[Candidate]:
    """One candidate per pair of ``channels`` of one kind (location ``"a,b"`` in channel
    order, entries ``[a, b]`` and ``[b, a]``) and, with more than one pair, every such entry
    together (location ``"all"``); ``what`` names the side in the description."""
    kinds = {n: sensor_kind(doc, n) for n in channels}
    pairs = [(a, b) for a, b in combinations(channels, 2) if kinds[a] == kinds[b]]
    out = []
    for a, b in pairs:
        entries = [[a, b], [b, a]]
        params = tuple(entry_parameter(prefix, *e) for e in entries)
        out.append(Candidate(effect, f"{a},{b}", params, {"entries": entries}, (),
                             f"cross-talk between {what} {a} and {b}"))  # fmt: skip
    if len(pairs) > 1:
        entries = [e for a, b in pairs for e in ([a, b], [b, a])]
        params = tuple(entry_parameter(prefix, *e) for e in entries)
        out.append(Candidate(effect, "all", params, {"entries": entries}, (),
                             f"cross-talk between every pair of {what} of one kind"))  # fmt: skip
    return out


def identity_plus(
    entries: Sequence[Sequence[str]], values: np.ndarray, channels: Sequence[str]
) -> tuple[np.ndarray, np.ndarray]:
    """``I + E`` ``(n, n)`` over ``channels`` (entry ``[a, b]`` at row ``a``, column ``b``,
    value ``values[k]``) and its derivative ``(n, n, n_entries)``. An entry naming a channel
    the data lack acts on nothing."""
    n = len(channels)
    M = np.eye(n, dtype=complex)
    dM = np.zeros((n, n, len(entries)), complex)
    for k, (a, b) in enumerate(entries):
        if a in channels and b in channels:
            i, j = channels.index(a), channels.index(b)
            M[i, j] += float(values[k])
            dM[i, j, k] = 1.0
    return M, dM


class ChannelMixing(Effect):
    """An FRF modifier that mixes the outputs (``side = "outputs"``: ``L = I + E``) or the
    inputs (``side = "inputs"``: ``R = I + E``), no elementwise factor; a subclass sets
    ``name``, ``description``, ``side`` and its parameters' ``prefix``."""

    is_modifier = True
    mixes = True
    #: ``"outputs"`` (rows) or ``"inputs"`` (columns)
    side = "outputs"
    #: parameter names ``{prefix}_{a}_{b}``
    prefix = "e"

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        channels = sensors(doc) if self.side == "outputs" else actuators(doc)
        return pair_candidates(self.name, doc, channels, self.prefix, self.side)

    def mixing(self, candidate, values, outputs, inputs):
        on_rows = self.side == "outputs"
        channels = tuple(outputs if on_rows else inputs)
        M, dM = identity_plus(candidate.spec["entries"], values, channels)
        return Mixing(left=M, dleft=dM) if on_rows else Mixing(right=M, dright=dM)
