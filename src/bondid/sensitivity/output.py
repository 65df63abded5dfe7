"""Results of ``python -m bondid.sensitivity``: ``sensitivity.json``, PNG maps and a summary.

JSON numbers that are not finite (an unidentifiable std, a skipped sweep step) are ``null``.
"""

from __future__ import annotations

import json
import os
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import write_text_atomic
from ..jsonsafe import json_safe
from .identifiability import Identifiability
from .local import LocalSensitivity
from .sweep import SweepResult

#: PNG files written under ``--out``.
PNG_NAMES = {
    "bands": "sensitivity_bands.png",
    "channels": "sensitivity_channels.png",
    "sweep": "sweep.png",
    "sweep_directions": "sweep_directions.png",
}
#: Normalised sensitivities below this are drawn as this value on the log colour scale.
MAP_FLOOR = 1e-3


def _feature(f: Any) -> dict[str, Any]:
    return {"f_hz": f.f_hz, "zeta": f.zeta, "kind": f.kind, "channel": f.channel}


#: the ``units`` entry of sensitivity.json
UNITS = {
    "sensitivity": "RMS residual change per unit relative parameter change "
    "(dB per 100 % for complex_log); parameters with nominal 0: per reference "
    "magnitude `scale`",
    "std": "expected standard deviation relative to `scale`",
    "sweep": "cost = mean square residual (dB² for complex_log)",
}


def result_dict(
    local: LocalSensitivity,
    ident: Identifiability,
    sweep: SweepResult | None,
    *,
    model: str,
    data: Sequence[str],
    cost_name: str,
    n_residuals: int,
    timing: dict[str, float | None],
) -> dict[str, Any]:
    """The content of ``sensitivity.json`` (plain Python types, JSON-ready)."""
    out: dict[str, Any] = {
        "model": model,
        "data": list(data),
        "cost_name": cost_name,
        "cost_nominal": local.cost,
        "n_residuals": n_residuals,
        "units": UNITS,
        "parameters": _parameters(local, ident),
        "features": [_feature(f) for f in local.features],
        "bands": _bands(local),
        "band_sensitivity": {"values": local.band_sens, "normalised": local.band_norm},
        "channels": list(local.channels),
        "channel_sensitivity": {"values": local.channel_sens, "normalised": local.channel_norm},
        "directions": list(local.directions),
        "direction_sensitivity": local.direction_sens,
        "classes": list(local.classes),
        "by_kind": _by_kind(local),
        "identifiability": _identifiability(ident),
        "sweep": None if sweep is None else _sweep(sweep),
        "timing": timing,
    }
    return json_safe(out)


def _parameters(local: LocalSensitivity, ident: Identifiability) -> list[dict[str, Any]]:
    """One entry a parameter: its local sensitivity and its expected std (None where the
    identifiability analysis left it out)."""
    idx = {n: i for i, n in enumerate(ident.names)}
    params = []
    for i, n in enumerate(local.names):
        j = idx.get(n)
        params.append(
            {
                "name": n,
                "kind": local.kinds[i],
                "scale": local.scale[i],
                "zero_nominal": n in local.zero_nominal,
                "overall": local.overall[i],
                "gradient": local.gradient[i],
                "std_alone": None if j is None else ident.std_alone[j],
                "std_all": None if j is None else ident.std_all[j],
                "recommended": n in ident.subset_std,
            }
        )
    return params


def _bands(local: LocalSensitivity) -> list[dict[str, Any]]:
    """One entry a frequency band: its range, class, features and five top parameters."""
    return [
        {
            "label": b.label,
            "f_lo_hz": b.f_lo_hz,
            "f_hi_hz": b.f_hi_hz,
            "class": b.cls,
            "user": b.user,
            "features": [_feature(f) for f in b.features],
            "top": [{"name": n, "sensitivity": v} for n, v in local.top(k, 5)],
        }
        for k, b in enumerate(local.bands)
    ]


def _by_kind(local: LocalSensitivity) -> dict[str, Any]:
    """``{band class: {parameter kind: {share, rms, max, top}}}``."""
    kinds = local.by_kind
    return {
        c: {
            g: {
                "share": kinds.share[c][g],
                "rms": kinds.rms[c][g],
                "max": kinds.max[c][g],
                "top": kinds.top[c][g],
            }
            for g in kinds.share[c]
        }
        for c in local.classes
    }


def _identifiability(ident: Identifiability) -> dict[str, Any]:
    """The identifiability entry: noise, singular values, weak combinations, the subset."""
    return {
        "noise": ident.noise_residual,
        "noise_estimated": ident.noise_estimated,
        "max_rel_std": ident.max_rel_std,
        "singular_values": ident.singular_values,
        "n_identifiable": ident.n_identifiable,
        "n_parameters": len(ident.names),
        "combinations": [
            {"sigma": c.sigma, "std": c.std, "pinned": c.pinned, "terms": c.terms}
            for c in ident.combinations
        ],
        "pivot_order": [ident.names[i] for i in ident.pivot_order],
        "recommended": [{"name": n, "std": s} for n, s in ident.subset_std.items()],
    }


def _sweep(sweep: SweepResult) -> dict[str, Any]:
    """The sweep entry: costs for each parameter and scale (and per direction)."""
    return {
        "parameters": list(sweep.names),
        "scales": sweep.scales,
        "values": sweep.values,
        "costs": sweep.costs,
        "directions": list(sweep.directions),
        "direction_costs": sweep.direction_costs,
        "cost_nominal": sweep.cost_nominal,
        "direction_nominal": sweep.direction_nominal,
        "zero_nominal": list(sweep.zero_nominal),
        "wall_s": sweep.wall_s,
        "workers": sweep.workers,
    }


def write_json(path: str | os.PathLike[str], content: dict[str, Any]) -> Path:
    return write_text_atomic(path, json.dumps(content, indent=1, allow_nan=False) + "\n")


def write_plots(
    out_dir: Path, local: LocalSensitivity, sweep: SweepResult | None, *, title: str
) -> list[Path]:
    """Heat maps (parameter × band, parameter × channel) and the sweep plots; returns paths."""
    from ..plots import plot_heatmap, plot_sweep

    written = []
    label = f"sensitivity / largest in the column (log, floored at {MAP_FLOOR:g})"
    written.append(
        plot_heatmap(
            np.maximum(local.band_norm, MAP_FLOOR),
            row_labels=local.names,
            col_labels=[b.label for b in local.bands],
            path=out_dir / PNG_NAMES["bands"],
            title=f"{title}: parameter × band (R = resonances, A = anti-resonances)",
            cbar_label=label,
            log=True,
        )
    )
    written.append(
        plot_heatmap(
            np.maximum(local.channel_norm, MAP_FLOOR),
            row_labels=local.names,
            col_labels=list(local.channels),
            path=out_dir / PNG_NAMES["channels"],
            title=f"{title}: parameter × channel",
            cbar_label=label,
            log=True,
        )
    )
    if sweep is not None:
        written.append(
            plot_sweep(
                sweep.scales,
                sweep.costs,
                param_names=sweep.names,
                path=out_dir / PNG_NAMES["sweep"],
                title=f"{title}: cost, each parameter scaled alone (one-at-a-time sweep)",
            )
        )
        written.append(
            plot_sweep(
                sweep.scales,
                sweep.direction_costs,
                param_names=sweep.names,
                path=out_dir / PNG_NAMES["sweep_directions"],
                title=f"{title}: cost per response direction, each parameter scaled alone",
                direction_names=[f"response {d}" for d in sweep.directions],
                top=10,
            )
        )
    return written


def _rel_std(v: float) -> str:
    """A relative std (a fraction) in %, or "not determined" when it is infinite or NaN."""
    return f"{100 * v:.3g}\u00a0%" if np.isfinite(v) else "not\u00a0determined"


def summary_lines(
    local: LocalSensitivity,
    ident: Identifiability,
    sweep: SweepResult | None,
    *,
    top: int = 3,
    cost_kind: str = "complex_log",
) -> list[str]:
    """A short human summary."""
    unit = "per 100 % change"
    unit_r = "dB" if cost_kind == "complex_log" or cost_kind == "log_magnitude" else ""
    lines = [f"nominal cost {local.cost:.4g}; Jacobian {local.jacobian_s:.2f} s"]
    lines.append(
        f"top parameters per band (RMS residual change {unit}; R = a band around resonances,"
        " A = around anti-resonances, at the frequencies given):"
    )
    for k, b in enumerate(local.bands):
        tops = ", ".join(f"{n} {v:.3g}" for n, v in local.top(k, top) if np.isfinite(v))
        lines.append(f"  {b.label:<30s} {tops or '(no data in band)'}")
    lines.append("by kind and band class (share of squared sensitivity; strongest parameter):")
    for c in local.classes:
        parts = [
            f"{g} {local.by_kind.share[c][g]:.0%} ({local.by_kind.top[c][g]})"
            for g in local.by_kind.share[c]
        ]
        lines.append(f"  {c:<10s} " + ", ".join(parts))
    noise_src = "estimated from the data" if ident.noise_estimated else "given"
    lines.append(
        f"identifiable combinations: {ident.n_identifiable} of {len(ident.names)} "
        f"(expected relative std ≤ {_rel_std(ident.max_rel_std)}; noise {ident.noise_residual:.3g} "
        f"{unit_r} per residual part, {noise_src})"
    )
    lines.append(
        f"recommended subset ({len(ident.subset)}), expected std in % of the parameter's"
        " reference value, the subset freed together:"
    )
    items = [f"{n} {_rel_std(v)}" for n, v in sorted(ident.subset_std.items(), key=lambda t: t[1])]
    lines += textwrap.wrap(", ".join(items), width=96, initial_indent="  ", subsequent_indent="  ")
    left = [n for n in ident.names if n not in ident.subset_std]
    if left:
        lines.append(
            f"not recommended ({len(left)}), expected std in % if freed alone"
            " (not determined = the data do not see it):"
        )
        idx = {n: i for i, n in enumerate(ident.names)}
        items = [f"{n} {_rel_std(ident.std_alone[idx[n]])}" for n in left]
        lines += textwrap.wrap(
            ", ".join(items), width=96, initial_indent="  ", subsequent_indent="  "
        )
    weak = [c for c in ident.combinations if not c.pinned][-3:]
    if weak:
        lines.append("least determined combinations:")
        lines += [f"  std {_rel_std(c.std)}: {c.label}" for c in reversed(weak)]
    if sweep is not None:
        order = np.argsort(-np.nan_to_num(sweep.spread(), nan=-1.0))[:5]
        lines.append(
            "sweep (one at a time: each parameter scaled alone from"
            f" {100 * sweep.scales.min():.0f} % to {100 * sweep.scales.max():.0f} %, the others"
            f" held; {len(sweep.names)} parameters × {sweep.scales.size} scales, "
            f"{sweep.workers} processes, {sweep.wall_s:.1f} s); largest cost range: "
            + ", ".join(f"{sweep.names[i]} {sweep.spread()[i]:.3g}" for i in order)
        )
        if sweep.zero_nominal:
            lines.append(
                "  swept over an absolute range (nominal 0): " + ", ".join(sweep.zero_nominal)
            )
    return lines
