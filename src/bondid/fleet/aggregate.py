"""Fleet statistics from the machines' status records: medians, robust spreads, outliers.

Outlier rule (per parameter, over the machines whose fit succeeded): a machine's value ``v``
is an outlier when ``|v − median| > 3.5 × 1.4826 · MAD`` (the robust z-score of Iglewicz and
Hoaglin, 3.5 robust standard deviations) **and**, when the machine's own standard deviation
``std`` is known, ``|v − median| > 3 · std`` (the machine's own estimate does not allow the
median). At least :data:`MIN_MACHINES` values are needed for a parameter to have outliers.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..jsonsafe import number
from .state import STATUS_OK

ROBUST_Z, MAD_TO_STD, OWN_STD_Z = 3.5, 1.4826, 3.0
MIN_MACHINES = 5
#: a robust spread below this fraction of |median| counts as this fraction (identical values)
REL_SPREAD_FLOOR = 1e-9
RULE = (
    f"|value − median| > {ROBUST_Z} × {MAD_TO_STD}·MAD and |value − median| > {OWN_STD_Z} × the"
    f" machine's own std (when known); at least {MIN_MACHINES} fitted machines per parameter"
)


@dataclass
class FleetStats:
    """What :func:`aggregate` finds (JSON-ready lists and dictionaries)."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    parameters: list[dict[str, Any]] = field(default_factory=list)
    outliers: list[dict[str, Any]] = field(default_factory=list)
    effects: dict[str, Any] | None = None


def fit_ok(status: Mapping[str, Any]) -> bool:
    """True when the machine's fit converged (its values enter the statistics)."""
    return status.get("fit_exit") == 0 and isinstance(status.get("fit"), Mapping)


def _rows(statuses: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    rows = []
    for st in statuses:
        fit = st.get("fit") if isinstance(st.get("fit"), Mapping) else {}
        params = [p for p in (fit or {}).get("parameters") or [] if isinstance(p, Mapping)]
        base = {"machine": st.get("machine"), "status": st.get("status"), "outlier": False}
        base["reason"] = st.get("reason")
        if not params:
            rows.append({**base, "parameter": None, "value": None, "std": None})
        for p in params:
            value, std = number(p.get("fitted")), number(p.get("std"))
            rows.append({**base, "parameter": p.get("name"), "value": value, "std": std})
    return rows


def _reason(name: str, value: float, median: float, z: float) -> str:
    if median != 0:
        rel = 100 * (value - median) / abs(median)
        side = "below" if rel < 0 else "above"
        return f"{name} {abs(rel):.0f} % {side} the fleet median ({z:.1f} robust std)"
    return f"{name} = {value:.4g}, the fleet median is 0 ({z:.1f} robust std)"


def _parameter(name: str, rows: list[dict[str, Any]]) -> tuple[dict[str, Any], list[dict]]:
    values = np.array([r["value"] for r in rows], dtype=float)
    med = float(np.median(values))
    mad = float(np.median(np.abs(values - med)))
    spread = max(MAD_TO_STD * mad, REL_SPREAD_FLOOR * abs(med))
    stats = {
        "name": name,
        "n": int(values.size),
        "median": med,
        "mad": mad,
        "robust_std": MAD_TO_STD * mad,
        "robust_rel_spread": MAD_TO_STD * mad / abs(med) if med else None,
        "min": float(values.min()),
        "max": float(values.max()),
    }
    outliers = []
    if values.size >= MIN_MACHINES and spread > 0:
        for r in rows:
            dev = abs(r["value"] - med)
            z = dev / spread
            own = r["std"]
            if z > ROBUST_Z and (own is None or dev > OWN_STD_Z * own):
                r["outlier"] = True
                outliers.append(
                    {
                        "machine": r["machine"],
                        "parameter": name,
                        "value": r["value"],
                        "std": own,
                        "median": med,
                        "deviation_rel": (r["value"] - med) / abs(med) if med else None,
                        "robust_z": z,
                        "reason": _reason(name, r["value"], med, z),
                    }
                )
    return stats, outliers


def _effects(statuses: Iterable[Mapping[str, Any]]) -> dict[str, Any]:
    per_machine: dict[str, Any] = {}
    for st in statuses:
        d = st.get("diagnosis")
        if isinstance(d, Mapping):
            per_machine[str(st.get("machine"))] = dict(d)
    counts = Counter(str(d.get("effect")) for d in per_machine.values())
    return {"per_machine": per_machine, "counts": dict(counts.most_common())}


def aggregate(statuses: Sequence[Mapping[str, Any]], *, diagnose: bool = False) -> FleetStats:
    """Rows (machine × parameter), per-parameter statistics, outliers and effect counts.

    Args:
        statuses: one status record per machine (``status.json`` content).
        diagnose: also count the diagnosis verdicts.
    """
    out = FleetStats(rows=_rows(statuses))
    ok_machines = {st.get("machine") for st in statuses if fit_ok(st)}
    by_name: dict[str, list[dict[str, Any]]] = {}
    for r in out.rows:
        if r["parameter"] is not None and r["value"] is not None and r["machine"] in ok_machines:
            by_name.setdefault(r["parameter"], []).append(r)
    for name in sorted(by_name):
        stats, found = _parameter(name, by_name[name])
        out.parameters.append(stats)
        out.outliers += found
    out.outliers.sort(key=lambda o: (-o["robust_z"], o["machine"]))
    if diagnose:
        out.effects = _effects(statuses)
    return out


def ok_count(statuses: Iterable[Mapping[str, Any]]) -> int:
    """Machines whose status is ok."""
    return sum(1 for st in statuses if st.get("status") == STATUS_OK)
