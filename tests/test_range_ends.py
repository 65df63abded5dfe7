"""At a bound or not: one rule (bondid.range_ends) for the fit's table, its report and the
diagnosis's caveats; known answers on linear, log and half-open ranges."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from bondid.fit.summary import parameter_table
from bondid.range_ends import END_SHARE, range_end, range_position
from bondid.report.headline import at_bound


def test_range_position_known_answers():
    assert range_position(2.0, 1.0, 3.0, log=False) == pytest.approx(0.5)
    # log scale: the geometric middle of [1, 100] is 10
    assert range_position(10.0, 1.0, 100.0, log=True) == pytest.approx(0.5)
    # a signed range is never read on a log scale
    assert range_position(0.0, -1.0, 1.0, log=True) == pytest.approx(0.5)
    assert range_position(5.0, 2.0, 2.0, log=False) == 0.5  # empty range


@pytest.mark.parametrize(
    ("value", "lower", "upper", "log", "side"),
    [
        # a barrier's width inside the bound, as a stalled interior-point fit leaves it
        (0.027 * (1 + 1.7e-4), 0.027, 0.081, True, "lower"),
        (69.9972, 23.333, 70.0, True, "upper"),
        (0.054, 0.027, 0.081, True, None),
        # just outside the share, either side
        (math.exp(math.log(0.027) + 2 * END_SHARE * math.log(3.0)), 0.027, 0.081, True, None),
        (-0.999, -1.0, 1.0, False, "lower"),
        (0.0, -1.0, 1.0, False, None),
        # half-open ranges: at the finite end only when (nearly) on it
        (0.0, 0.0, math.inf, True, "lower"),
        (1e-9, 0.0, math.inf, True, None),
        (2.0, 2.0, math.inf, False, "lower"),
        (math.nan, 0.0, 1.0, False, None),
    ],
)
def test_range_end(value, lower, upper, log, side):
    assert range_end(value, lower, upper, log=log) == side


def test_the_fit_table_and_the_report_mark_the_same_parameters():
    """A fit that stopped a barrier's width inside two bounds: both ends marked in the
    printed table and in the report, the free one not."""
    names = ["seg0.mass", "b1.stiffness", "seg1.com.x"]
    lower = np.array([0.027, 23.333, -0.05])
    upper = np.array([0.081, 70.0, 0.05])
    fitted = np.array([0.0270045, 69.9972, 0.01])
    result = SimpleNamespace(
        names=names, initial=np.array([0.054, 46.667, 0.0]), fitted=fitted,
        std=np.array([math.nan, math.nan, 1e-3]), lower=lower, upper=upper,
    )  # fmt: skip
    rows = parameter_table(result)
    marked = [n for n in names if any(r.startswith(n) and r.endswith("[bound]") for r in rows)]
    assert marked == ["seg0.mass", "b1.stiffness"]
    entries = [
        {"name": n, "fitted": float(f), "lower": float(lo), "upper": float(hi)}
        for n, f, lo, hi in zip(names, fitted, lower, upper, strict=True)
    ]
    assert [e["name"] for e in entries if at_bound(e)] == marked
