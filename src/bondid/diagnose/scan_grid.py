"""The starting-point scan grid of a candidate: :func:`scan_grid`.

The rule of the candidate starts' scale scan (:mod:`.starts`): the
candidate's own grid of scale factors (:attr:`~.effects.base.Candidate.scan_grid`), plus, for
a structural candidate, the factors that put its mode at each measured mode the refitted model
lacks. Scaling the ``scan = 1`` parameters (stiffnesses) by ``s`` moves the candidate's mode
from ``ref_hz`` to ``ref_hz·√s``, so the mode lands at ``f`` for ``s = (f/ref_hz)²``.
"""

from __future__ import annotations

from collections.abc import Sequence

from .effects import Candidate


def hint_scales(cand: Candidate, hints_hz: Sequence[float]) -> list[float]:
    """Scale factors that put ``cand``'s mode at each of ``hints_hz`` [Hz] (empty for a
    candidate without a reference mode, e.g. a delay)."""
    if not cand.ref_hz:
        return []
    return [(float(f) / cand.ref_hz) ** 2 for f in hints_hz]


def scan_grid(cand: Candidate, hints_hz: Sequence[float]) -> tuple[tuple[float, ...], list[float]]:
    """``(grid, hints)``: the scan grid of ``cand`` (its own factors and the hints', sorted,
    without repeats; empty when the candidate has no scan) and the hints' factors alone
    (:func:`hint_scales`)."""
    hints = hint_scales(cand, hints_hz)
    if not cand.scan_grid:
        return (), hints
    return tuple(sorted({*cand.scan_grid, *hints})), hints
