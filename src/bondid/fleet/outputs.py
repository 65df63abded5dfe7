"""The fleet's results: ``fleet.json``, ``fleet.csv`` and the strip plot, written atomically."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..atomic import write_text_atomic
from ..jsonsafe import json_safe
from .aggregate import RULE, FleetStats, fit_ok
from .plot import STRIP_PNG, plot_strip

FLEET_JSON, FLEET_CSV = "fleet.json", "fleet.csv"
CSV_COLUMNS = ("machine", "parameter", "value", "std", "status", "outlier", "reason")


def machine_summary(st: Mapping[str, Any]) -> dict[str, Any]:
    """One machine's line of ``fleet.json``."""
    fit = st.get("fit") if isinstance(st.get("fit"), Mapping) else None
    return {
        "id": st.get("machine"),
        "status": st.get("status"),
        "reason": st.get("reason"),
        "fit_status": None if fit is None else fit.get("status"),
        "cost_final": None if fit is None else fit.get("cost_final"),
        "in_statistics": fit_ok(st),
        "attempt": st.get("attempt"),
        "wall_s": st.get("wall_s"),
        "diagnosis": st.get("diagnosis"),
        "results": f"machines/{st.get('machine')}",
    }


def fleet_document(
    statuses: Sequence[Mapping[str, Any]], stats: FleetStats, header: Mapping[str, Any]
) -> dict[str, Any]:
    """The ``fleet.json`` content."""
    n_ok = sum(1 for st in statuses if st.get("status") == "ok")
    doc: dict[str, Any] = {
        **header,
        "counts": {"machines": len(statuses), "ok": n_ok, "failed": len(statuses) - n_ok},
        "outlier_rule": RULE,
        "machines": [machine_summary(st) for st in statuses],
        "parameters": stats.parameters,
        "outliers": stats.outliers,
        "rows": stats.rows,
    }
    if stats.effects is not None:
        doc["effects"] = stats.effects
    return json_safe(doc)


def _csv_text(rows: Sequence[Mapping[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in rows:
        cells = []
        for c in CSV_COLUMNS:
            v = r.get(c)
            if isinstance(v, float):
                v = repr(v) if math.isfinite(v) else ""
            elif isinstance(v, bool):
                v = "yes" if v else "no"
            cells.append("" if v is None else v)
        w.writerow(cells)
    return buf.getvalue()


def write_fleet_outputs(
    out: Path,
    statuses: Sequence[Mapping[str, Any]],
    stats: FleetStats,
    header: Mapping[str, Any],
    *,
    plots: bool = True,
) -> list[Path]:
    """Write ``fleet.json``, ``fleet.csv`` and (with values to show) ``fleet_strip.png``.

    Returns:
        The written paths.
    """
    written = []
    if plots and stats.parameters:
        written.append(plot_strip(stats.parameters, stats.rows, out / STRIP_PNG))
    written.append(write_text_atomic(out / FLEET_CSV, _csv_text(stats.rows)))
    content = fleet_document(statuses, stats, header)
    content["outputs"] = [p.name for p in written] + [FLEET_JSON]
    written.append(write_text_atomic(out / FLEET_JSON, json.dumps(content, indent=2) + "\n"))
    return written
