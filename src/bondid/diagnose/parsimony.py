"""The simpler of two FRF modifiers the data cannot tell apart (:func:`prefer_simpler`).

A step tests its best-scoring refit. When another refit scores within the noise of it
(:func:`.scoring.indistinguishable`: the best one does not beat it by the significance part of
the verdict rule taken with one parameter) and is an FRF modifier that changes **the same
entries** of the FRF with **fewer parameters**, the data support both equally and the simpler
explains as much: that one is tested and named, the other listed as indistinguishable from it.

The case it is for: a pure delay on every output and a second-order lag on every input are
both one common factor on the whole FRF matrix. Below its corner a well-damped second-order
lag (ζ ≈ 0.6–0.9, a Bessel-like loop) has a nearly flat magnitude and a nearly linear phase,
i.e. it is a delay to within the noise: on data with a 35 µs delay on every output, a refitted
lag (T ≈ 31 µs, T₂ ≈ 26 µs) scores within a fraction of the noise of the refitted delay.
A lag the data do tell from a delay (a magnitude roll-off in band) is not affected: its
score then beats the delay's by more than the noise.

Structural candidates are never swapped this way: a flexible base and soft mounts (9 and 8
parameters) are different physical hypotheses, and which one the data favour is the
evidence the diagnosis reports, even when it is weak.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from . import scoring
from .effects import available
from .effects.base import Candidate

#: the frequency [Hz] at which a modifier's entries are read (any in-band value: a modifier
#: at its start values differs from 1 wherever it acts)
PROBE_HZ = 1000.0


def entries(cand: Candidate | None, outputs: Sequence[str], inputs: Sequence[str]):
    """``(n_out, n_in)`` bool: the FRF entries an FRF-modifier candidate changes, read at its
    typical values (a signed parameter at its typical size: at its start, 0, it changes
    nothing) on a probe FRF of independent random entries, mixing included; None for a
    structural candidate or an unknown effect."""
    if cand is None:
        return None
    cls = available().get(cand.effect)
    if cls is None or not cls.is_modifier:
        return None
    effect = cls()
    values = np.array([p.typical if p.signed else p.initial for p in cand.parameters], float)
    outs, ins = tuple(outputs), tuple(inputs)
    G, _ = effect.modifier(cand, values, np.array([PROBE_HZ]), outs, ins)
    probe = np.random.default_rng(0).standard_normal((len(outs), len(ins), 1)) + 1.0
    mixing = effect.mixing(cand, values, outs, ins)
    changed = G * (mixing.apply(probe) if mixing is not None else probe)
    return (np.abs(changed - probe) > 1e-12 * np.abs(probe).max())[..., 0]


def prefer_simpler(
    results: Sequence[Any],
    scores: Sequence[float],
    order: list[int],
    noise: scoring.NoiseReference | None,
    outputs: Sequence[str],
    inputs: Sequence[str],
) -> tuple[list[int], int | None]:
    """``order`` (indices of ``results``, the one tested first) with the simpler equivalent
    modifier of the module docstring moved to the front, and the index it displaced (None
    when nothing moved). ``scores``: held-out scores [dB] in the order of ``results``."""
    if len(order) < 2 or not scoring.determined(results[order[0]]):
        return order, None
    best = results[order[0]]
    mask = entries(best.candidate, outputs, inputs)
    if mask is None:
        return order, None
    test = {"rule": "noise", **noise.as_dict()} if scoring.usable(noise) else {"rule": "margin"}
    tied = {order[j] for j, _ in scoring.indistinguishable([scores[i] for i in order], test)}
    simpler = []
    for i in order[1:]:
        r = results[i]
        if i not in tied or r.n_own >= best.n_own or not scoring.determined(r):
            continue
        other = entries(r.candidate, outputs, inputs)
        if other is not None and other.shape == mask.shape and np.array_equal(other, mask):
            simpler.append(i)
    if not simpler:
        return order, None
    pick = min(simpler, key=lambda i: (results[i].n_own, scores[i]))
    return [pick] + [i for i in order if i != pick], order[0]
