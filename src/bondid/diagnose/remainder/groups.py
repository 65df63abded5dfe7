"""The groups of points a row or column finding is fitted on: an output row, an input column,
or every channel (:func:`groups`)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from .residual import Points, Residual, Selector, SetResidual

#: fewest used points a group needs before anything is fitted to it
MIN_POINTS = 8


def on_output(name: str) -> Selector:
    """The points of output row ``name`` (none in a data set without it)."""

    def select(k: int, st: SetResidual) -> np.ndarray:
        mask = np.zeros(st.Hm.shape, bool)
        if name in st.outputs:
            mask[st.outputs.index(name)] = True
        return mask

    return select


def on_input(name: str) -> Selector:
    """The points of input column ``name`` (none in a data set without it)."""

    def select(k: int, st: SetResidual) -> np.ndarray:
        mask = np.zeros(st.Hm.shape, bool)
        if name in st.inputs:
            mask[:, st.inputs.index(name)] = True
        return mask

    return select


def on_band(lo: float, hi: float) -> Selector:
    """The points with ``lo ≤ f ≤ hi`` [Hz]."""

    def select(k: int, st: SetResidual) -> np.ndarray:
        f = st.freq_hz
        return np.broadcast_to((f >= lo) & (f <= hi), st.Hm.shape)

    return select


def groups(res: Residual, with_global: bool = True) -> Iterator[tuple[str, str, Selector | None]]:
    """``(side, name, selector)`` for every output row and input column with points (when
    there is more than one of them: a single row is every channel), then ``("global", "",
    None)`` with ``with_global``."""
    outs, ins = res.outputs, res.inputs
    if len(outs) > 1:
        for o in outs:
            yield "output", o, on_output(o)
    if len(ins) > 1:
        for i in ins:
            yield "input", i, on_input(i)
    if with_global:
        yield "global", "", None


def group_points(res: Residual) -> Iterator[tuple[str, str, Points]]:
    """``(side, name, points)`` of every group of :func:`groups` holding at least
    :data:`MIN_POINTS` used points (fewer cannot support a fitted shape)."""
    for side, name, select in groups(res):
        pts = res.points(select)
        if pts.size >= MIN_POINTS:
            yield side, name, pts
