"""The first screen of the report: what a person came for, from ``fit.json`` and
``diagnosis.json``.

* :class:`FitHeadline` — the weighted ``db_rms`` before → after, the noise level of the same
  data and whether the fit is at it, iterations, parameters that ended on a bound, the
  channels left out;
* :class:`DiagnosisHeadline` — the verdict (``verdict.outcome`` when the file has one:
  ``explained``, ``partly_explained`` or ``unexplained``), its figures (gap before → after,
  share closed), where the gap lies (worst channels and bands), and the ``remainder``
  findings when present.

Both read any JSON shape and degrade to fewer lines, never raise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..jsonsafe import number
from ..range_ends import range_end
from .html import fmt

#: a final db_rms up to this factor times the noise level counts as "at the noise level"
#: (the rule of ``bondid.fit``'s printed summary)
AT_NOISE = 1.1

OUTCOMES = {
    "explained": ("Explained", "ok"),
    "partly_explained": ("Partly explained", "part"),
    "unexplained": ("Not explained", "bad"),
}


def _num(record: Any, key: str) -> float | None:
    return number(record.get(key)) if isinstance(record, Mapping) else None


def value_of(record: Mapping[str, Any], key: str) -> float | None:
    """The number under ``key`` (NaN and ±inf kept: the report shows them)."""
    return number(record.get(key), finite=False)


def mapping(v: Any) -> Mapping[str, Any]:
    """``v`` when it is a JSON object, else an empty one."""
    return v if isinstance(v, Mapping) else {}


def records(v: Any) -> list[Mapping[str, Any]]:
    """The mappings of a JSON list (anything else: none)."""
    return [r for r in v if isinstance(r, Mapping)] if isinstance(v, list) else []


def at_bound(p: Mapping[str, Any]) -> bool:
    """True when a parameter entry's ``fitted`` lies at an end of its finite range
    (``lower``, ``upper``; :func:`bondid.range_ends.range_end`)."""
    x, lo, hi = _num(p, "fitted"), _num(p, "lower"), _num(p, "upper")
    if x is None or lo is None or hi is None:
        return False
    return range_end(x, lo, hi, log=True) is not None


@dataclass
class FitHeadline:
    """The fit's figures for the first screen (dB; None when fit.json lacks them)."""

    before: float | None
    after: float | None
    noise: float | None
    weighting: str
    status: str
    converged: bool | None
    iterations: int | None
    wall_s: float | None
    n_params: int
    on_bound: list[str]
    left_out: list[str]
    no_figure: list[str] = field(default_factory=list)

    @property
    def ratio(self) -> float | None:
        """``after / noise`` (None when either is missing)."""
        if self.after is None or not self.noise:
            return None
        return self.after / self.noise

    @property
    def at_noise(self) -> bool | None:
        r = self.ratio
        return None if r is None else r <= AT_NOISE

    @property
    def meaning(self) -> str:
        """One sentence on what the final figure means."""
        r = self.ratio
        if r is None:
            return "no noise level in fit.json: compare the figures with the Bode plots"
        if r <= AT_NOISE:
            return (
                "the fit is at the noise level: what remains is the measurement's own noise;"
                " the model explains the data"
            )
        return (
            f"{r:.1f}× the noise level: the model (or this fit's free parameters) misses"
            " something the data show; the diagnosis says what"
        )


def fit_headline(fit: Any) -> FitHeadline | None:
    """The headline of ``fit.json`` (None when it is not a JSON object)."""
    if not isinstance(fit, Mapping):
        return None
    db = mapping(fit.get("db_rms"))
    params = records(fit.get("parameters"))
    left_out = _left_out(fit)
    conv = fit.get("success")
    iters = fit.get("iterations")
    h = FitHeadline(
        before=_num(db, "initial"),
        after=_num(db, "final"),
        noise=_num(db, "noise_level"),
        weighting=str(db.get("weighting") or "information"),
        status=str(fit.get("status", "?")),
        converged=conv if isinstance(conv, bool) else None,
        iterations=iters if isinstance(iters, int) else None,
        wall_s=_num(fit, "wall_s"),
        n_params=len(params),
        on_bound=[str(p.get("name", "?")) for p in params if at_bound(p)],
        left_out=left_out,
    )
    listed = db.get("no_figure")
    h.no_figure = [str(x) for x in listed] if isinstance(listed, list) else _no_figure(db)
    return h


def _left_out(fit: Mapping[str, Any]) -> list[str]:
    """The channels left out of the fit: those left out of every data file by name, the
    others with the files they were left out of (``channels_by_file``)."""
    files = records(fit.get("channels_by_file"))
    if not files:
        left = fit.get("channels_left_out")
        return [str(c) for c in left] if isinstance(left, Mapping | list) else []
    where: dict[str, list[str]] = {}
    for entry in files:
        for c in mapping(entry.get("left_out")):
            where.setdefault(str(c), []).append(Path(str(entry.get("file", "?"))).name)
    return [c if len(w) == len(files) else f"{c} in {', '.join(w)}" for c, w in where.items()]


def _no_figure(db: Mapping[str, Any]) -> list[str]:
    """Channels whose db_rms has no finite figure (fit.json writes null for them), each
    with the reason."""
    out = []
    by_ch = db.get("by_channel")
    if isinstance(by_ch, Mapping):
        for ch, row in by_ch.items():
            if isinstance(row, Mapping) and (
                _num(row, "initial") is None or _num(row, "final") is None
            ):
                why = row.get("no_figure") or "the model or the data is zero or not finite there"
                out.append(f"{ch}: {why}")
    return out


@dataclass
class DiagnosisHeadline:
    """The diagnosis's verdict and figures for the first screen."""

    outcome: str
    title: str
    tone: str
    effect: str | None
    location: str | None
    gap_before: float | None
    gap_after: float | None
    gap_closed: float | None
    nominal: float | None
    reason: str
    worst_channels: list[tuple[str, float]]
    worst_bands: list[tuple[float, float, float]]
    remainder: list[tuple[str, str]]
    over_noise: float | None = None
    #: every kept effect ``(effect, location)`` in the order added (the verdict's first)
    effects: list[tuple[str, str | None]] = field(default_factory=list)


def diagnosis_headline(diag: Any) -> DiagnosisHeadline | None:
    """The headline of ``diagnosis.json`` (None when it has no verdict)."""
    if not isinstance(diag, Mapping) or not isinstance(diag.get("verdict"), Mapping):
        return None
    v: Mapping[str, Any] = diag["verdict"]
    gap = mapping(diag.get("gap"))
    effect = v.get("effect")
    effect = None if effect in (None, "none") else str(effect)
    outcome = str(v.get("outcome") or _outcome_without_field(diag, effect))
    title, tone = OUTCOMES.get(outcome, (outcome.replace("_", " ").capitalize(), "part"))
    if effect is None and outcome == "explained":
        title = "Explained by the model's parameters"
    before = _num(gap, "db_rms")
    closed = _num(v, "gap_closed")
    where = v.get("where") if isinstance(v.get("where"), Mapping) else gap
    after = _num(where, "db_rms") if where is not gap else None
    if after is None and before is not None and closed is not None and effect is not None:
        after = before * (1 - closed)
    kept = [e for e in records(diag.get("effects")) if e.get("effect")]
    last = _num(kept[-1], "db_rms_after") if len(kept) > 1 else None
    if last is not None and before:
        # several effects: the answer is the model with all of them, not the first alone
        after, closed = last, 1.0 - last / before
    stages = mapping(diag.get("stages"))
    nominal = _num(stages.get("nominal"), "db_rms") if isinstance(stages, Mapping) else None
    return DiagnosisHeadline(
        outcome=outcome,
        title=title,
        tone=tone,
        effect=effect,
        location=None if v.get("location") is None else str(v["location"]),
        gap_before=before,
        gap_after=after,
        gap_closed=closed,
        nominal=nominal,
        reason=str(v.get("reason") or ""),
        worst_channels=_worst_channels(where),
        worst_bands=_worst_bands(where),
        remainder=[
            (str(r.get("kind", "finding")).replace("_", " "), str(r.get("text", fmt(r))))
            for r in _remainder_findings(diag.get("remainder") or v.get("remainder"))
        ],
        over_noise=number(_first_step(diag).get("base_over_noise")),
        effects=[_effect_location(e) for e in kept],
    )


def _effect_location(e: Mapping[str, Any]) -> tuple[str, str | None]:
    """``(effect, location)`` of one entry of ``diagnosis.json``'s ``effects``."""
    return str(e["effect"]), None if e.get("location") is None else str(e["location"])


def _remainder_findings(rem: Any) -> list[Mapping[str, Any]]:
    """The findings of ``diagnosis.json``'s ``remainder`` (an object with ``findings``; a
    bare list of findings is read too)."""
    if isinstance(rem, Mapping):
        return records(rem.get("findings"))
    return records(rem)


def _first_step(diag: Mapping[str, Any]) -> Mapping[str, Any]:
    """The first search step's test (``scoring.steps[0]``), or an empty mapping."""
    steps = records(mapping(diag.get("scoring")).get("steps"))
    return steps[0] if steps else {}


def _outcome_without_field(diag: Mapping[str, Any], effect: str | None) -> str:
    """The outcome of a diagnosis.json without ``verdict.outcome``: an effect found =
    explained; none found = explained when the parameter refit is at the noise level
    (``scoring.steps[0].base_above_noise`` false), unexplained when it is above it."""
    if effect is not None:
        return "explained"
    if _first_step(diag).get("base_above_noise") is False:
        return "explained"
    return "unexplained"


def _worst_channels(gap: Any, n: int = 3) -> list[tuple[str, float]]:
    by_ch = gap.get("by_channel") if isinstance(gap, Mapping) else None
    if not isinstance(by_ch, Mapping):
        return []
    vals = [(str(k), float(v)) for k, v in by_ch.items() if number(v) is not None]
    return sorted(vals, key=lambda t: -t[1])[:n]


def _worst_bands(gap: Any, n: int = 2) -> list[tuple[float, float, float]]:
    out = []
    for b in records(gap.get("by_band") if isinstance(gap, Mapping) else None):
        lo, hi, db = _num(b, "f_lo_hz"), _num(b, "f_hi_hz"), _num(b, "db_rms")
        if lo is not None and hi is not None and db is not None and math.isfinite(db):
            out.append((lo, hi, db))
    return sorted(out, key=lambda t: -t[2])[:n]
