"""The report's sections for fit.json, diagnosis.json, fleet.json and modes.json.

Every function takes the parsed JSON (any shape: the files come from other commands and
possibly other versions) and returns :class:`~.blocks.Block` lists with human headings and
units; unexpected shapes degrade to a note, never raise. Sensitivity: :mod:`.sensitivity_section`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..jsonsafe import number
from .blocks import Block, Cell, Row, Table, cells, heading, note, table_block, text
from .headline import at_bound, mapping, records
from .html import fmt, percent

#: the footnote of every table with a ``std`` column (why a std can be "—")
STD_FOOTNOTE = (
    "std: one standard deviation of the fitted value from the data's noise (the linearised,"
    " unconstrained problem). — = not determined by these data: the parameter moves along a"
    " direction the measured FRFs do not see (alone or in a combination with others), so any"
    " value along it fits as well; the fit's prior keeps it near the model's value."
    " A parameter on a bound is marked: its std is that of the unbounded problem, or —."
)


def _value(record: Mapping[str, Any], key: str) -> float | None:
    """The number under ``key`` (NaN and ±inf kept: the report shows them)."""
    return number(record.get(key), finite=False)


def _summary_table(items: list[tuple[str, str]]) -> Block:
    return table_block(Table([], [Row(cells(k, v, left=(0, 1))) for k, v in items], left=(0, 1)))


def fit_section(fit: Any) -> list[Block]:
    """The fit's summary, its channels (used and left out) and the parameter table."""
    if not isinstance(fit, Mapping):
        return [note("fit.json is not a JSON object; skipped")]
    out = [_summary_table(_fit_summary(fit))]
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
    c0, c1 = _value(fit, "cost_initial"), _value(fit, "cost_final")
    if c0 is not None or c1 is not None:
        rows.append((f"cost ({fit.get('cost_name', '?')})", f"{fmt(c0)} → {fmt(c1)}"))
    db = mapping(fit.get("db_rms"))
    if db:
        rows.append(
            (
                f"db_rms, {db.get('weighting', '')}-weighted",
                f"{fmt(_value(db, 'initial'))} dB → {fmt(_value(db, 'final'))} dB",
            )
        )
        rows.append(("noise level of the data", f"{fmt(_value(db, 'noise_level'), 3)} dB"))
        uw = db.get("unweighted")
        if isinstance(uw, Mapping):
            rows.append(
                (
                    "plain RMS over every point (noise-only points included)",
                    f"{fmt(_value(uw, 'initial'))} dB → {fmt(_value(uw, 'final'))} dB",
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
                        fmt(_value(v, "initial"), 3),
                        fmt(_value(v, "final"), 3),
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
        ini, fitted, std = _value(p, "initial"), _value(p, "fitted"), _value(p, "std")
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
            fmt(_value(p, "lower")),
            fmt(_value(p, "upper")),
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


def diagnosis_section(diag: Any) -> list[Block]:
    """Verdict reason, effects (kept and dropped), the gap tables and the candidates."""
    if not isinstance(diag, Mapping):
        return [note("diagnosis.json is not a JSON object; skipped")]
    out: list[Block] = []
    verdict = diag.get("verdict")
    if isinstance(verdict, Mapping) and verdict.get("reason"):
        out.append(text(f"Why: {verdict['reason']}"))
    effects, dropped = records(diag.get("effects")), records(diag.get("dropped"))
    if len(effects) > 1 or dropped:
        rows = [
            Row(
                cells(
                    str(e.get("effect", "?")),
                    fmt(e.get("location")),
                    fmt(e.get("step")),
                    fmt(e.get("db_rms_after")),
                    percent(_value(e, "gap_closed")),
                    left=(0, 1),
                )
            )
            for e in effects
        ]
        head = ["effect", "where", "search step", "gap after [dB]", "gap closed"]
        out += [heading("Effects found, in the order added"), table_block(Table(head, rows))]
    if dropped:
        rows = [
            Row(
                cells(
                    str(d.get("effect", "?")),
                    fmt(d.get("location")),
                    fmt(d.get("step")),
                    fmt(d.get("score_with")),
                    fmt(d.get("score_without")),
                    left=(0, 1),
                )
            )
            for d in dropped
        ]
        head = [
            "effect",
            "where",
            "accepted at step",
            "held-out score with it [dB]",
            "without it [dB]",
        ]
        out += [heading("Accepted, then dropped as redundant"), table_block(Table(head, rows))]
    gap = diag.get("gap")
    if isinstance(gap, Mapping):
        out += _gap_blocks(gap)
    cands = records(diag.get("candidates"))
    if cands:
        out += [heading("Candidates tried (best first)"), table_block(_candidate_table(cands))]
    return out


def _gap_blocks(gap: Mapping[str, Any]) -> list[Block]:
    """The gap after the parameter refit: overall, by channel, by band and by mode."""
    out = []
    db = _value(gap, "db_rms")
    if db is not None:
        out.append(
            text(
                f"Model–measurement gap after the parameter refit: {db:.3g} dB"
                " (information-weighted, all used channels)."
            )
        )
    by_ch = gap.get("by_channel")
    if isinstance(by_ch, Mapping) and by_ch:
        rows = [Row(cells(str(k), fmt(number(v), 3))) for k, v in by_ch.items()]
        foot = ["OUT.IN = the response at OUT to the excitation at IN."]
        out += [heading("Gap by channel"), table_block(Table(["channel", "gap [dB]"], rows, foot))]
    bands = records(gap.get("by_band"))
    if bands:
        rows = [
            Row(cells(*(fmt(_value(b, k), 4) for k in ("f_lo_hz", "f_hi_hz", "db_rms")), left=()))
            for b in bands
        ]
        head = ["from [Hz]", "to [Hz]", "gap [dB]"]
        out += [heading("Gap by frequency band"), table_block(Table(head, rows, left=()))]
    modes = records(gap.get("modes"))
    if modes:
        rows = [
            Row(
                cells(
                    fmt(_value(m, "f_measured_hz"), 5),
                    fmt(_value(m, "f_model_hz"), 5),
                    str(m.get("status", "")),
                    left=(2,),
                ),
                kind="" if m.get("status") == "paired" else "flag",
            )
            for m in modes
        ]
        head = ["measured [Hz]", "model [Hz]", "status"]
        foot = [
            "paired: a model mode matches; missing: measured, not in the model;"
            " spurious: in the model, not measured."
        ]
        out += [heading("Modes: measured and model"), table_block(Table(head, rows, foot, (2,)))]
    return out


def _candidate_table(cands: list[Mapping[str, Any]]) -> Table:
    """One row a candidate effect, in the order of diagnosis.json (best first)."""
    rows = []
    for c in cands:
        params = c.get("parameters")
        shown = fmt(params, 3) if isinstance(params, Mapping) else fmt(params)
        rows.append(
            Row(
                cells(
                    str(c.get("effect", "?")),
                    fmt(c.get("location")),
                    shown,
                    fmt(_value(c, "db_rms_after"), 3),
                    percent(_value(c, "gap_closed")),
                    fmt(_value(c, "heldout_db_rms_after"), 3),
                    fmt(_value(c, "score"), 3),
                    left=(0, 1, 2),
                )
            )
        )
    head = [
        "effect",
        "where",
        "its parameters (SI)",
        "gap after [dB]",
        "gap closed",
        "held-out gap after [dB]",
        "score [dB]",
    ]
    foot = [
        "— in the figures: screened, not refitted (a better candidate of the same step was"
        " refitted instead). score: the held-out gap with a penalty per added parameter."
    ]
    return Table(head, rows, foot, left=(0, 1, 2))


def fleet_section(fleet: Any) -> list[Block]:
    """Counts, per-parameter statistics, outliers, failed machines and effects of fleet.json."""
    if not isinstance(fleet, Mapping):
        return [note("fleet.json is not a JSON object; skipped")]
    out = []
    counts = fleet.get("counts")
    if isinstance(counts, Mapping):
        out.append(_summary_table([(str(k).replace("_", " "), fmt(v)) for k, v in counts.items()]))
    params = records(fleet.get("parameters"))
    if params:
        rows = [
            Row(
                cells(
                    str(p.get("name", "?")),
                    fmt(p.get("n")),
                    fmt(p.get("median")),
                    percent(_value(p, "robust_rel_spread"), ".3g"),
                    fmt(p.get("min")),
                    fmt(p.get("max")),
                )
            )
            for p in params
        ]
        head = ["parameter", "machines", "median", "robust spread", "min", "max"]
        out += [heading("Parameters over the fleet"), table_block(Table(head, rows))]
    out.append(heading("Outliers"))
    if fleet.get("outlier_rule"):
        out.append(note(f"rule: {fleet['outlier_rule']}"))
    rows = [
        Row(
            cells(
                str(o.get("machine")),
                str(o.get("parameter")),
                fmt(o.get("value")),
                str(o.get("reason", "")),
                left=(0, 1, 3),
            )
        )
        for o in records(fleet.get("outliers"))
    ]
    head = ["machine", "parameter", "value", "reason"]
    out.append(table_block(Table(head, rows, left=(0, 1, 3))) if rows else note("no outlier"))
    failed = [m for m in records(fleet.get("machines")) if m.get("status") != "ok"]
    if failed:
        rows = [
            Row(cells(str(m.get("id")), str(m.get("reason") or ""), left=(0, 1))) for m in failed
        ]
        out += [
            heading("Failed machines"),
            table_block(Table(["machine", "reason"], rows, left=(0, 1))),
        ]
    effects = fleet.get("effects")
    if isinstance(effects, Mapping) and isinstance(effects.get("counts"), Mapping):
        rows = [Row(cells(str(k), fmt(v))) for k, v in effects["counts"].items()]
        out += [
            heading("Effects found (diagnosis)"),
            table_block(Table(["effect", "machines"], rows)),
        ]
    return out


def modes_section(modes: Any, modes_dir: Path, out_dir: Path) -> list[Block]:
    """The mode table with relative links to the animation pages found next to modes.json."""
    if not isinstance(modes, Mapping):
        return [note("modes.json is not a JSON object; skipped")]
    out = []
    op = modes.get("operating_point")
    if isinstance(op, Mapping):
        where = ", ".join(f"{k} = {fmt(v)}" for k, v in op.items()) or "neutral (q = 0)"
        out.append(text(f"Operating point: {where}."))
    scene = modes_dir / "modes.html"
    if scene.is_file():
        out.append(
            Block(
                "link", "Mode scene (Meshcat, opens offline): modes.html", href=_rel(scene, out_dir)
            )
        )
    entries = records(modes.get("modes"))
    if not entries:
        return [*out, note("modes.json has no mode list")]
    fitted = modes.get("fitted")
    fmodes = records(fitted.get("modes")) if isinstance(fitted, Mapping) else []
    header = ["#", "frequency [Hz]", "damping ratio ζ", "kind", "main DOF"]
    if fmodes:
        header.append("fitted model [Hz]")
    header.append("animation")
    rows = []
    for i, m in enumerate(entries):
        row = [
            Cell(fmt(m.get("index", i + 1))),
            Cell(fmt(m.get("f_hz"), 6)),
            Cell(fmt(m.get("zeta"))),
            Cell(str(m.get("kind", "")), left=True),
            Cell(str(m.get("dominant_dof", "")), left=True),
        ]
        if fmodes:
            row.append(Cell(fmt(fmodes[i].get("f_hz"), 6) if i < len(fmodes) else "—"))
        link = m.get("html")
        if isinstance(link, str) and (modes_dir / link).is_file():
            row.append(Cell(link, left=True, href=_rel(modes_dir / link, out_dir)))
        else:
            row.append(Cell(f"{link} (missing)" if isinstance(link, str) else "", left=True))
        rows.append(Row(row))
    out.append(table_block(Table(header, rows, left=(3, 4, len(header) - 1))))
    return out


def _rel(target: Path, out_dir: Path) -> str:
    return Path(os.path.relpath(target.resolve(), out_dir.resolve())).as_posix()
