"""The report's section for ``fit.json``: the fit's summary, its channels and its parameters.

The file comes from another command, possibly of another version: any shape is read, and
an unexpected one degrades to a note, never raises.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..jsonsafe import number
from .blocks import Block, Row, Table, cells, heading, note, summary_table, table_block
from .headline import at_bound, mapping, records, value_of
from .html import fmt, percent

#: the footnote of every table with a ``std`` column (why a std can be "—")
STD_FOOTNOTE = (
    "std: one standard deviation of the fitted value from the data's noise (the linearised,"
    " unconstrained problem). — = not determined by these data: the parameter moves along a"
    " direction the measured FRFs do not see (alone or in a combination with others), so any"
    " value along it fits as well; the fit's prior keeps it near the model's value."
    " A parameter on a bound is marked: its std is that of the unbounded problem, or —."
)


def fit_section(fit: Any) -> list[Block]:
    """The fit's summary, its channels (used and left out) and the parameter table."""
    if not isinstance(fit, Mapping):
        return [note("fit.json is not a JSON object; skipped")]
    out = [summary_table(_fit_summary(fit))]
    db = fit.get("db_rms")
    if isinstance(db, Mapping):
        out += _channel_table(fit, db)
    params = records(fit.get("parameters"))
    if params:
        out += [heading("Parameters"), table_block(_parameter_table(params))]
    else:
        out.append(note("fit.json has no parameter list"))
    return out


def _fit_summary(fit: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(what, value) rows: solver, figures, files."""
    rows = [("solver status", str(fit.get("status", "?")))]
    if isinstance(fit.get("success"), bool):
        rows.append(("converged", fmt(fit["success"])))
    rows += [
        ("iterations", fmt(fit.get("iterations"))),
        ("wall time", f"{fmt(fit.get('wall_s'), 3)} s"),
    ]
    c0, c1 = value_of(fit, "cost_initial"), value_of(fit, "cost_final")
    if c0 is not None or c1 is not None:
        rows.append((f"cost ({fit.get('cost_name', '?')})", f"{fmt(c0)} → {fmt(c1)}"))
    db = mapping(fit.get("db_rms"))
    if db:
        rows.append(
            (
                f"db_rms, {db.get('weighting', '')}-weighted",
                f"{fmt(value_of(db, 'initial'))} dB → {fmt(value_of(db, 'final'))} dB",
            )
        )
        rows.append(("noise level of the data", f"{fmt(value_of(db, 'noise_level'), 3)} dB"))
        uw = db.get("unweighted")
        if isinstance(uw, Mapping):
            rows.append(
                (
                    "plain RMS over every point (noise-only points included)",
                    f"{fmt(value_of(uw, 'initial'))} dB → {fmt(value_of(uw, 'final'))} dB",
                )
            )
    if fit.get("model_file"):
        rows.append(("model", str(fit["model_file"])))
    files = fit.get("data_files")
    if isinstance(files, list):
        rows.append(("data", ", ".join(str(f) for f in files)))
    if fit.get("study_file"):
        rows.append(("study file", str(fit["study_file"])))
    ms = fit.get("multistart")
    if isinstance(ms, Mapping) and isinstance(ms.get("n_runs"), int) and ms["n_runs"] > 1:
        rows.append(
            (
                "starts",
                f"{ms['n_runs']} ({fmt(ms.get('n_failed'))} failed), final cost min"
                f" {fmt(ms.get('min'))}, median {fmt(ms.get('median'))}",
            )
        )
    return rows


def _left_out_by_file(fit: Mapping[str, Any]) -> dict[str | None, dict[str, Any]]:
    """``{file or None (every file): {channel: median information weight}}`` left out."""
    out: dict[str | None, dict[str, Any]] = {}
    for entry in records(fit.get("channels_by_file")):
        lo = entry.get("left_out")
        if isinstance(lo, Mapping):
            out[str(entry.get("file"))] = dict(lo)
    if not out and isinstance(fit.get("channels_left_out"), Mapping):
        out[None] = dict(fit["channels_left_out"])
    return out


def _channel_table(fit: Mapping[str, Any], db: Mapping[str, Any]) -> list[Block]:
    """db_rms per data file and channel; channels left out of the fit greyed and labelled."""
    left = _left_out_by_file(fit)
    rows = []
    for ds in records(db.get("by_dataset")):
        f = str(ds.get("file") or "?")
        by_ch = mapping(ds.get("by_channel"))
        skipped = {**left.get(None, {}), **left.get(f, {})}
        for ch, v in by_ch.items():
            v = mapping(v)
            rows.append(
                Row(
                    cells(
                        ch,
                        Path(f).name,
                        fmt(value_of(v, "initial"), 3),
                        fmt(value_of(v, "final"), 3),
                        "used",
                        left=(0, 1, 4),
                    )
                )
            )
        for ch, w in skipped.items():
            why = f"left out: median information weight {fmt(number(w), 2)} < 0.5"
            rows.append(Row(cells(ch, Path(f).name, "", "", why, left=(0, 1, 4)), kind="muted"))
    if not rows:
        return []
    foot = [
        "Channel OUT.IN = the response at OUT to the excitation at IN (x.y: response of joint"
        " x to the force on joint y).",
        "db_rms: information-weighted RMS of the complex-log error, dB. A channel is left out"
        " where its median information weight is below 0.5 (mostly below the noise floor);"
        " name it with --channels to fit it anyway.",
    ]
    header = ["channel", "data file", "before [dB]", "after [dB]", "in the fit"]
    return [heading("Channels"), table_block(Table(header, rows, foot, left=(0, 1, 4)))]


PARAMETER_HEADER = [
    "parameter",
    "unit",
    "initial",
    "fitted",
    "change",
    "lower",
    "upper",
    "std",
    "std / fitted",
    "",
]


def _parameter_table(params: list[Mapping[str, Any]]) -> Table:
    """One row a parameter; those that ended on a bound flagged."""
    rows = []
    n_bound = n_undet = 0
    for p in params:
        ini, fitted, std = value_of(p, "initial"), value_of(p, "fitted"), value_of(p, "std")
        change = (fitted / ini - 1) if ini and fitted is not None else None
        rel = abs(std / fitted) if std is not None and fitted else None
        bound = at_bound(p)
        n_bound += bound
        n_undet += std is None
        flag = "on a bound" if bound else ""
        row = [
            str(p.get("name", "?")),
            str(p.get("unit") or ""),
            fmt(ini),
            fmt(fitted),
            percent(change, "+.3g"),
            fmt(value_of(p, "lower")),
            fmt(value_of(p, "upper")),
            fmt(std, 3),
            percent(rel, ".3g"),
            flag,
        ]
        rows.append(Row(cells(*row, left=(0, 1, 9)), kind="flag" if bound else ""))
    foot = [STD_FOOTNOTE]
    if n_undet:
        foot.insert(0, f"{n_undet} of {len(params)} parameters have no std (—).")
    if n_bound:
        foot.insert(0, f"{n_bound} parameter(s) ended on a bound (highlighted).")
    return Table(PARAMETER_HEADER, rows, foot, left=(0, 1, 9))
