"""The report's section for ``sensitivity.json``: what the data determine, in readable tables.

Expected standard deviations are shown in % of the parameter's reference value (``scale``);
band labels ``R …``/``A …`` are spelled out (a band around resonances / anti-resonances).
Files of other shapes degrade to notes (the keys are not fixed by the spec).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..jsonsafe import number
from .blocks import Block, Row, Table, cells, heading, note, table_block, text
from .headline import mapping, records
from .html import fmt, percent

BAND_CLASSES = {
    "below": "below the first mode",
    "resonance": "around resonances or anti-resonances",
    "between": "between modes",
    "above": "above the last mode",
}


def _std_text(v: Any) -> str:
    """A relative std (fraction) in %, or why there is none."""
    x = number(v, finite=False)
    if x is None or math.isinf(x):
        return "not determined (no sensitivity)"
    return percent(x, ".3g")


def band_name(band: Mapping[str, Any]) -> str:
    """A band's label with its R/A tag spelled out."""
    label = str(band.get("label", "?"))
    tag, _, rest = label.partition(" ")
    if tag == "R":
        return f"resonance {rest}"
    if tag == "A":
        return f"anti-resonance {rest}"
    return label


def sensitivity_section(sens: Any) -> list[Block]:
    """Summary, recommended subset, the rest, bands with their top parameters, the least
    determined combinations and the sweep's largest cost ranges."""
    if not isinstance(sens, Mapping):
        return [note("sensitivity.json is not a JSON object; skipped")]
    out: list[Block] = []
    ident = mapping(sens.get("identifiability"))
    if ident:
        n_id, n_p = ident.get("n_identifiable"), ident.get("n_parameters")
        noise = number(ident.get("noise"))
        src = "estimated from the data" if ident.get("noise_estimated") else "given"
        out.append(
            text(
                f"The data determine {fmt(n_id)} independent combinations of the {fmt(n_p)}"
                f" parameters to an expected relative std of at most"
                f" {percent(number(ident.get('max_rel_std')), '.3g')}"
                f" (noise {fmt(noise, 3)} dB per residual part, {src})."
            )
        )
    out += _subset_blocks(sens, ident)
    out += _band_blocks(sens)
    combos = [c for c in records(ident.get("combinations")) if not c.get("pinned")][-3:]
    if combos:
        rows = [
            Row(cells(_terms(c.get("terms")), _std_text(c.get("std")), left=(0,)))
            for c in reversed(combos)
        ]
        foot = [
            "A combination moves several parameters at once, with the weights shown; its"
            " std is relative (in % of the parameters' reference values)."
        ]
        out += [
            heading("Least determined combinations"),
            table_block(Table(["combination", "expected std"], rows, foot)),
        ]
    out += _sweep_blocks(sens)
    return out or [note("sensitivity.json holds nothing this report knows how to show")]


def _terms(terms: Any) -> str:
    if isinstance(terms, Mapping):
        return " ".join(f"{number(w) or 0:+.2f}·{n}" for n, w in terms.items())
    if isinstance(terms, list):
        parts = []
        for t in terms:
            if isinstance(t, list | tuple) and len(t) == 2:
                parts.append(f"{number(t[1]) or 0:+.2f}·{t[0]}")
            else:
                parts.append(fmt(t))
        return " ".join(parts)
    return fmt(terms)


def _subset_blocks(sens: Mapping[str, Any], ident: Mapping[str, Any]) -> list[Block]:
    """The recommended subset and the other parameters with their expected stds (%)."""
    params = records(sens.get("parameters"))
    if not params:
        return []
    rec = [p for p in params if p.get("recommended")]
    rest = [p for p in params if not p.get("recommended")]
    out: list[Block] = []
    if rec:
        best = {str(r.get("name")): r.get("std") for r in records(ident.get("recommended"))}
        rows = [
            Row(
                cells(
                    str(p.get("name")),
                    str(p.get("kind", "")),
                    _std_text(best.get(str(p.get("name")), p.get("std_all"))),
                    fmt(number(p.get("overall")), 3),
                    left=(0, 1),
                )
            )
            for p in rec
        ]
        head = ["parameter", "kind", "expected std (subset freed)", "sensitivity [dB per 100 %]"]
        out += [
            heading(f"Recommended free parameters ({len(rec)})"),
            table_block(Table(head, rows, left=(0, 1))),
        ]
    if rest:
        rows = [
            Row(
                cells(
                    str(p.get("name")),
                    str(p.get("kind", "")),
                    _std_text(p.get("std_alone")),
                    fmt(number(p.get("overall")), 3),
                    left=(0, 1),
                ),
                kind="muted",
            )
            for p in rest
        ]
        head = ["parameter", "kind", "expected std if freed alone", "sensitivity [dB per 100 %]"]
        foot = [
            "Expected std in % of the parameter's reference value. Not recommended: its std"
            " exceeds the limit even freed alone, or it only moves together with others."
        ]
        out += [
            heading(f"Not recommended ({len(rest)})"),
            table_block(Table(head, rows, foot, left=(0, 1))),
        ]
    return out


def _band_blocks(sens: Mapping[str, Any]) -> list[Block]:
    """One row a frequency band: its range, class and the parameters it is most sensitive to."""
    bands = records(sens.get("bands"))
    if not bands:
        return []
    rows = []
    for b in bands:
        tops = ", ".join(
            f"{t.get('name')} ({fmt(number(t.get('sensitivity')), 3)})"
            for t in records(b.get("top"))
            if number(t.get("sensitivity")) is not None
        )
        rows.append(
            Row(
                cells(
                    band_name(b),
                    fmt(number(b.get("f_lo_hz")), 4),
                    fmt(number(b.get("f_hi_hz")), 4),
                    BAND_CLASSES.get(str(b.get("class")), str(b.get("class", ""))),
                    tops or "no data in this band",
                    left=(0, 3, 4),
                )
            )
        )
    head = [
        "band",
        "from [Hz]",
        "to [Hz]",
        "kind of band",
        "most sensitive parameters [dB per 100 %]",
    ]
    foot = [
        "Sensitivity: the RMS change of the residual (dB) for a 100 % change of the"
        " parameter, from the local derivative. R = a band around resonances, A = around"
        " anti-resonances."
    ]
    return [heading("Frequency bands"), table_block(Table(head, rows, foot, left=(0, 3, 4)))]


def _sweep_blocks(sens: Mapping[str, Any]) -> list[Block]:
    """The one-at-a-time sweep's largest cost ranges."""
    sw = sens.get("sweep")
    if not isinstance(sw, Mapping):
        return []
    names, costs = sw.get("parameters"), sw.get("costs")
    if not isinstance(names, list) or not isinstance(costs, list) or len(names) != len(costs):
        return []
    spread = []
    for n, row in zip(names, costs, strict=True):
        vals = [number(v) for v in row] if isinstance(row, list) else []
        finite = [v for v in vals if v is not None]
        if finite:
            spread.append((str(n), max(finite) - min(finite)))
    spread.sort(key=lambda t: -t[1])
    scales = [number(s) for s in sw.get("scales") or []]
    rng = [s for s in scales if s is not None]
    span = f" from {percent(min(rng), '.0f')} to {percent(max(rng), '.0f')}" if rng else ""
    rows = [Row(cells(n, fmt(v, 3))) for n, v in spread[:8]]
    foot = [
        "One-at-a-time sweep: each parameter alone is scaled"
        f"{span} of its nominal value, the others held; cost = mean square residual (dB²)."
    ]
    return [
        heading("Sweep: largest cost ranges"),
        table_block(Table(["parameter", "cost range [dB²]"], rows, foot)),
    ]
