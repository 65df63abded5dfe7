"""The sections of the report, one function per result file (spec §4 keys only).

Every function takes the parsed JSON (any shape: the files come from other commands and
possibly other versions) and returns HTML; unexpected shapes degrade to a note, never raise.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..jsonsafe import number
from .html import esc, fmt, generic_json, key_values, note, table

FIT_SUMMARY_KEYS = ("status", "cost_name", "cost_initial", "cost_final", "iterations", "wall_s")


def _records(v: Any) -> list[Mapping[str, Any]]:
    return [r for r in v if isinstance(r, Mapping)] if isinstance(v, list) else []


def _value(record: Mapping[str, Any], key: str) -> float | None:
    """The number under ``key``, else None (NaN and ±inf are kept: the report shows them)."""
    return number(record.get(key), finite=False)


def _percent(fraction: float | None, spec: str) -> str:
    """``fraction`` as a percentage formatted with ``spec`` ("—" for None)."""
    return "—" if fraction is None else f"{100 * fraction:{spec}} %"


def fit_section(fit: Any) -> str:
    """Fit summary (status, costs) and the parameter table of ``fit.json``."""
    if not isinstance(fit, Mapping):
        return note("fit.json is not a JSON object; skipped")
    params = _records(fit.get("parameters"))
    table_html = _parameter_table(params) if params else note("fit.json has no parameter list")
    return key_values(_fit_summary(fit)) + table_html


def _fit_summary(fit: Mapping[str, Any]) -> dict[str, Any]:
    """The summary keys first, the cost ratio, then every other scalar entry of fit.json."""
    summary = {k: fit.get(k) for k in FIT_SUMMARY_KEYS if k in fit}
    c0, c1 = _value(fit, "cost_initial"), _value(fit, "cost_final")
    if c0 and c1 is not None and c0 > 0:
        summary["cost_final / cost_initial"] = c1 / c0
    for k, v in fit.items():
        if k not in summary and k != "parameters" and not isinstance(v, (Mapping, list)):
            summary[k] = v
    return summary


PARAMETER_HEADER = ("name", "initial", "fitted", "lower", "upper", "std", "std / fitted", "change")


def _parameter_table(params: list[Mapping[str, Any]]) -> str:
    """The parameter table; rows of parameters that ended at a bound are highlighted."""
    rows, flagged = [], []
    for i, p in enumerate(params):
        row, at_bound = _parameter_row(p)
        rows.append(row)
        if at_bound:
            flagged.append(i)
    out = "<h3>Parameters</h3>"
    out += table([*PARAMETER_HEADER, ""], rows, left=(0, 8), flagged=flagged)
    if flagged:
        out += note(f"{len(flagged)} parameter(s) ended at a bound (highlighted).")
    return out


def _parameter_row(p: Mapping[str, Any]) -> tuple[list[str], bool]:
    """One parameter's table cells and whether it ended at a bound."""
    ini, fitted = _value(p, "initial"), _value(p, "fitted")
    lo, hi, std = _value(p, "lower"), _value(p, "upper"), _value(p, "std")
    change = (fitted / ini - 1) if ini and fitted is not None else None
    rel_std = abs(std / fitted) if std is not None and fitted else None
    at_bound = fitted is not None and any(_at(fitted, b) for b in (lo, hi))
    cells = [esc(p.get("name", "?")), *(fmt(v) for v in (ini, fitted, lo, hi, std))]
    cells += [_percent(rel_std, ".3g"), _percent(change, "+.3g")]
    return [*cells, "at bound" if at_bound else ""], at_bound


def _at(value: float, bound: float | None) -> bool:
    """True when ``value`` equals a finite ``bound`` to a relative 1e-6."""
    if bound is None or not math.isfinite(bound):
        return False
    return abs(value - bound) <= 1e-6 * max(abs(bound), 1e-12)


def diagnosis_section(diag: Any) -> str:
    """Verdict, gap tables (overall, by channel, by band, modes) and candidates."""
    if not isinstance(diag, Mapping):
        return note("diagnosis.json is not a JSON object; skipped")
    verdict, gap = diag.get("verdict"), diag.get("gap")
    if isinstance(verdict, Mapping):
        out = [_verdict_html(verdict)]
    else:
        out = [note("no verdict in diagnosis.json")]
    effects, dropped = _records(diag.get("effects")), _records(diag.get("dropped"))
    if len(effects) > 1 or dropped:
        out.append("<h3>Effects found, in the order added</h3>" + _effect_table(effects))
    if dropped:
        out.append("<h3>Accepted, then dropped as redundant</h3>" + _dropped_table(dropped))
    if isinstance(gap, Mapping):
        out.append(_gap_html(gap))
    cands = _records(diag.get("candidates"))
    if cands:
        out.append("<h3>Candidates (best first)</h3>" + _candidate_table(cands))
    return "".join(out)


def _verdict_html(verdict: Mapping[str, Any]) -> str:
    """The verdict line: effect, location and the share of the gap it closes."""
    text = f"Verdict: <b>{esc(verdict.get('effect', '?'))}</b>"
    loc = verdict.get("location")
    if loc:
        text += f" at <b>{esc(loc)}</b>"
    closed = _value(verdict, "gap_closed")
    if closed is not None:
        text += f" — closes {100 * closed:.1f} % of the gap"
    return f'<p class="verdict">{text}</p>'


def _effect_table(effects: list[Mapping[str, Any]]) -> str:
    """``effects`` of diagnosis.json: each with the gap once it and those before are in."""
    rows = [
        [esc(e.get("effect", "?")), fmt(e.get("location")), fmt(e.get("step")),
         fmt(e.get("db_rms_after")), _percent(_value(e, "gap_closed"), ".1f")]
        for e in effects
    ]  # fmt: skip
    return table(["effect", "location", "search step", "dB rms after", "gap closed"], rows,
                 left=(0, 1))  # fmt: skip


def _dropped_table(dropped: list[Mapping[str, Any]]) -> str:
    """``dropped`` of diagnosis.json: the held-out scores with and without each."""
    rows = [
        [esc(d.get("effect", "?")), fmt(d.get("location")), fmt(d.get("step")),
         fmt(d.get("score_with")), fmt(d.get("score_without"))]
        for d in dropped
    ]  # fmt: skip
    header = ["effect", "location", "accepted at step", "held-out score with it [dB]",
              "without it [dB]"]  # fmt: skip
    return table(header, rows, left=(0, 1))


def _gap_html(gap: Mapping[str, Any]) -> str:
    """The overall gap and its tables by channel, by band and by mode (those present)."""
    out = []
    db = _value(gap, "db_rms")
    if db is not None:
        out.append(f"<p>Model–measurement gap: <b>{db:.3g} dB rms</b> (all channels).</p>")
    by_ch = gap.get("by_channel")
    if isinstance(by_ch, Mapping) and by_ch:
        out.append("<h3>Gap by channel</h3>")
        out.append(table(["channel", "dB rms"], [[esc(k), fmt(v)] for k, v in by_ch.items()]))
    bands = _records(gap.get("by_band"))
    if bands:
        rows = [[fmt(b.get(k)) for k in ("f_lo_hz", "f_hi_hz", "db_rms")] for b in bands]
        out.append("<h3>Gap by band</h3>")
        out.append(table(["f_lo [Hz]", "f_hi [Hz]", "dB rms"], rows, left=()))
    modes = _records(gap.get("modes"))
    if modes:
        out.append("<h3>Modes: measured vs model</h3>" + _mode_pair_table(modes))
    return "".join(out)


def _mode_pair_table(modes: list[Mapping[str, Any]]) -> str:
    """Measured vs model frequencies; modes not paired are highlighted."""
    rows = [
        [fmt(m.get("f_measured_hz")), fmt(m.get("f_model_hz")), esc(m.get("status", ""))]
        for m in modes
    ]
    flagged = [i for i, m in enumerate(modes) if m.get("status") != "paired"]
    return table(["measured [Hz]", "model [Hz]", "status"], rows, left=(2,), flagged=flagged)


CANDIDATE_HEADER = (
    "effect", "location", "parameters", "dB rms after", "gap closed", "held-out dB rms after",
    "score",
)  # fmt: skip


def _candidate_table(cands: list[Mapping[str, Any]]) -> str:
    """One row a candidate, in the order of diagnosis.json (best first)."""
    rows = [
        [
            esc(c.get("effect", "?")),
            *(fmt(c.get(k)) for k in ("location", "parameters", "db_rms_after")),
            _percent(_value(c, "gap_closed"), ".1f"),
            *(fmt(c.get(k)) for k in ("heldout_db_rms_after", "score")),
        ]
        for c in cands
    ]
    return table(list(CANDIDATE_HEADER), rows, left=(0, 1, 2))


def fleet_section(fleet: Any) -> str:
    """Counts, per-parameter statistics, outliers, failed machines and effects of fleet.json."""
    if not isinstance(fleet, Mapping):
        return note("fleet.json is not a JSON object; skipped")
    out = []
    counts = fleet.get("counts")
    if isinstance(counts, Mapping):
        out.append(key_values(dict(counts)))
    params = _records(fleet.get("parameters"))
    if params:
        out.append("<h3>Parameters over the fleet</h3>")
        rows = []
        for p in params:
            spread = _percent(_value(p, "robust_rel_spread"), ".3g")
            row = [esc(p.get("name", "?")), fmt(p.get("n")), fmt(p.get("median")), spread]
            rows.append([*row, fmt(p.get("min")), fmt(p.get("max"))])
        head = ["parameter", "machines", "median", "robust spread", "min", "max"]
        out.append(table(head, rows))
    outliers = _records(fleet.get("outliers"))
    out.append("<h3>Outliers</h3>")
    if fleet.get("outlier_rule"):
        out.append(note(f"rule: {fleet['outlier_rule']}"))
    rows = [
        [esc(o.get(k)) for k in ("machine", "parameter")] + [fmt(o.get("value"))]
        + [esc(o.get("reason", ""))]
        for o in outliers
    ]  # fmt: skip
    head = ["machine", "parameter", "value", "reason"]
    out.append(table(head, rows, left=(0, 1, 3)) if rows else note("no outlier"))
    failed = [m for m in _records(fleet.get("machines")) if m.get("status") != "ok"]
    if failed:
        out.append("<h3>Failed machines</h3>")
        rows = [[esc(m.get("id")), esc(m.get("reason") or "")] for m in failed]
        out.append(table(["machine", "reason"], rows, left=(0, 1)))
    effects = fleet.get("effects")
    if isinstance(effects, Mapping) and isinstance(effects.get("counts"), Mapping):
        out.append("<h3>Effects found (diagnosis)</h3>")
        out.append(
            table(["effect", "machines"], [[esc(k), fmt(v)] for k, v in effects["counts"].items()])
        )
    return "".join(out)


def sensitivity_section(sens: Any) -> str:
    """``sensitivity.json`` rendered generically (its keys are not fixed by the spec)."""
    return generic_json(sens)


def modes_section(modes: Any, modes_dir: Path, out_dir: Path) -> str:
    """The mode table with relative links to the animation pages found next to modes.json."""
    if not isinstance(modes, Mapping):
        return note("modes.json is not a JSON object; skipped")
    out = []
    op = modes.get("operating_point")
    if isinstance(op, Mapping):
        text = ", ".join(f"{k} = {fmt(v)}" for k, v in op.items()) or "neutral (q = 0)"
        out.append(f"<p>Operating point: {text}.</p>")
    scene = modes_dir / "modes.html"
    if scene.is_file():
        out.append(
            f'<p>Mode scene: <a href="{esc(_rel(scene, out_dir))}">modes.html</a>'
            " (Meshcat, opens offline).</p>"
        )
    entries = _records(modes.get("modes"))
    if not entries:
        return "".join(out) + note("modes.json has no mode list")
    fitted = modes.get("fitted")
    fmodes = _records(fitted.get("modes")) if isinstance(fitted, Mapping) else []
    header = ["#", "f [Hz]", "ζ", "kind", "main DOF"]
    if fmodes:
        header.append("fitted f [Hz]")
    header.append("animation")
    rows = []
    for i, m in enumerate(entries):
        row = [
            fmt(m.get("index", i + 1)),
            fmt(m.get("f_hz"), 6),
            fmt(m.get("zeta")),
            esc(m.get("kind", "")),
            esc(m.get("dominant_dof", "")),
        ]
        if fmodes:
            row.append(fmt(fmodes[i].get("f_hz"), 6) if i < len(fmodes) else "—")
        link = m.get("html")
        if isinstance(link, str) and (modes_dir / link).is_file():
            row.append(f'<a href="{esc(_rel(modes_dir / link, out_dir))}">{esc(link)}</a>')
        elif isinstance(link, str):
            row.append(esc(f"{link} (missing)"))
        else:
            row.append("")
        rows.append(row)
    out.append(table(header, rows, left=(3, 4, len(header) - 1)))
    return "".join(out)


def _rel(target: Path, out_dir: Path) -> str:
    return Path(os.path.relpath(target.resolve(), out_dir.resolve())).as_posix()
