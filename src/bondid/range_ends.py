"""Where a fitted value lies in its range, and whether it sits at one of the range's ends.

A value the fit pushed to a bound describes the data, not the machine: the bound, not the
data, decided it. Every report that marks such a value uses this rule, so the fit's table,
its HTML report and the diagnosis's caveats agree on what "at a bound" means.
"""

from __future__ import annotations

import math

#: a value within this share of its range from an end is at that end. An interior-point
#: solver keeps a bounded value a barrier's width inside its bound, and a fit that stops on a
#: stalled cost stops before that width has shrunk: such values lie 1e-5–1e-3 of the range
#: inside, and are at the bound for every purpose of the report.
END_SHARE = 0.005


def range_position(value: float, lower: float, upper: float, *, log: bool) -> float:
    """Where ``value`` lies in ``[lower, upper]``: 0 at the lower end, 1 at the upper one
    (on a log scale when ``log`` and the range and value are positive); 0.5 for an empty
    range."""
    if log and lower > 0 and value > 0:
        lower, upper, value = math.log(lower), math.log(upper), math.log(value)
    return (value - lower) / (upper - lower) if upper > lower else 0.5


def range_end(
    value: float, lower: float, upper: float, *, log: bool, share: float = END_SHARE
) -> str | None:
    """``"lower"`` or ``"upper"`` when ``value`` lies within ``share`` of its range from that
    end, else None (also for a non-finite value or an empty range). A range open on one side
    has no width: there ``value`` is at the finite end when within ``share`` of that end's
    magnitude (an end at 0: exactly on it)."""
    if not math.isfinite(value) or not upper > lower:
        return None
    if not (math.isfinite(lower) and math.isfinite(upper)):
        for side, end in (("lower", lower), ("upper", upper)):
            if math.isfinite(end) and abs(value - end) <= share * abs(end):
                return side
        return None
    t = range_position(value, lower, upper, log=log)
    return "lower" if t <= share else "upper" if t >= 1.0 - share else None
