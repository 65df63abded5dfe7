"""What a kept effect's figures do not say: ``caveats`` of an effect in ``diagnosis.json``.

A kept effect passed the rule, yet two things can make its name or its values a weaker
statement than they look, and both can be read off the effect alone:

* **a parameter at the end of its range** (``at_bound``): the refit pushed a parameter onto
  one of the bounds its effect allows (a mount's mode at the lowest frequency it may have, a
  stiffness at its stiffest). The effect then reaches as far as the library lets it and
  stands in for something beyond: its value describes the data, not the machine;
* **one common factor on every channel** (``common_factor``): an FRF modifier that multiplies
  every entry of the FRF matrix by the same function of frequency. Measured FRFs cannot place
  such a factor: ``g(ω)·H`` is the same whether ``g`` sits in the drives (a lag in every
  amplifier), in the sensors or in the acquisition, so the side the effect's name gives is
  the library's choice, not the data's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from .effects import available
from .effects.base import Candidate, NewParameter

#: a parameter is at a bound when it lies within this share of its range's (log) width of it
BOUND_SHARE = 0.005
#: frequencies [Hz] at which a modifier's factor is compared across channels (any spread
#: of values: a factor common to every channel is common at every frequency)
PROBE_HZ = (3.0, 30.0, 300.0, 3000.0)
#: relative spread across channels below which a factor counts as common to all
COMMON_RTOL = 1e-9
#: each data set's ``(outputs, inputs)``
Channels = Sequence[tuple[Sequence[str], Sequence[str]]]


@dataclass(frozen=True)
class Caveat:
    """One caveat of a kept effect.

    Attributes:
        kind: ``at_bound`` or ``common_factor`` (module docstring).
        text: the caveat in words, for the summary and the report.
        parameter: the parameter at its bound (``at_bound``), else None.
        side: ``lower`` or ``upper`` (``at_bound``), else None.
    """

    kind: str
    text: str
    parameter: str | None = None
    side: str | None = None

    def as_dict(self) -> dict[str, str | None]:
        return asdict(self)


def _position(p: NewParameter, value: float) -> float:
    """Where ``value`` lies in ``p``'s range: 0 at the lower bound, 1 at the upper one (on a
    log scale for a positive parameter, the scale its refit moves it on)."""
    lo, hi = p.lower, p.upper
    if not p.signed and lo > 0 and value > 0:
        lo, hi, value = math.log(lo), math.log(hi), math.log(value)
    return (value - lo) / (hi - lo) if hi > lo else 0.5


def at_bound(cand: Candidate, values: Sequence[float]) -> list[Caveat]:
    """The parameters of ``cand`` at ``values`` (SI, in the candidate's order) that sit on a
    bound of their range, one caveat each."""
    out = []
    for p, v in zip(cand.parameters, values, strict=True):
        if not math.isfinite(v) or p.upper <= p.lower:
            continue
        t = _position(p, float(v))
        side = "lower" if t <= BOUND_SHARE else "upper" if t >= 1.0 - BOUND_SHARE else None
        if side is None:
            continue
        unit = "" if p.unit in ("", "1") else f" {p.unit}"
        out.append(Caveat(
            "at_bound",
            f"{p.name} = {v:.4g}{unit} is at the {side} end of the range this effect allows"
            f" ({p.lower:.4g}–{p.upper:.4g}{unit}): the effect stands in for something"
            " beyond it; its value describes the data, not the machine",
            parameter=p.name, side=side,
        ))  # fmt: skip
    return out


def is_common_factor(
    cand: Candidate, values: Sequence[float], outputs: Sequence[str], inputs: Sequence[str]
) -> bool:
    """Does the FRF-modifier ``cand`` at ``values`` multiply every entry of an
    ``(n_out, n_in)`` FRF by one common factor (no mixing; the same ``G`` in every entry at
    every probe frequency)? False for a structural candidate."""
    cls = available().get(cand.effect)
    if cls is None or not cls.is_modifier or not outputs or not inputs:
        return False
    effect = cls()
    theta = np.asarray(values, float)
    outs, ins = tuple(outputs), tuple(inputs)
    if effect.mixes and effect.mixing(cand, theta, outs, ins) is not None:
        return False
    G, _ = effect.modifier(cand, theta, np.asarray(PROBE_HZ, float), outs, ins)
    G = np.asarray(G).reshape(len(outs) * len(ins), len(PROBE_HZ))
    if np.allclose(G, 1.0, rtol=0.0, atol=COMMON_RTOL):
        return False  # the effect is absent at these values: nothing to place
    spread = np.abs(G - G[:1]).max(axis=0)
    return bool(np.all(spread <= COMMON_RTOL * np.abs(G[0]).clip(min=1e-300)))


def common_factor(cand: Candidate, values: Sequence[float], channels: Channels) -> list[Caveat]:
    """The ``common_factor`` caveat when ``cand`` at ``values`` is one factor on every
    channel of every data set (``channels``: each set's ``(outputs, inputs)``)."""
    if not channels or not all(is_common_factor(cand, values, o, i) for o, i in channels):
        return []
    return [Caveat(
        "common_factor",
        "it multiplies every channel by one common factor: to FRF data such a factor in the"
        " drives, in the sensors or in the acquisition looks the same, so the data do not"
        " say on which side it is",
    )]  # fmt: skip


def caveats(
    cand: Candidate,
    values: Mapping[str, float] | Sequence[float],
    channels: Channels,
) -> list[dict[str, str | None]]:
    """Every caveat of the kept effect ``cand`` at its fitted ``values`` (SI; a mapping in the
    candidate's parameter order, or a sequence), as ``diagnosis.json`` lists them."""
    vals = [float(v) for v in (values.values() if isinstance(values, Mapping) else values)]
    if len(vals) != len(cand.parameters):
        return []
    found = [*at_bound(cand, vals), *common_factor(cand, vals, channels)]
    return [c.as_dict() for c in found]
