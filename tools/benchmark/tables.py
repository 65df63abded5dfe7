"""Markdown tables: one row per case, and summaries per design × regime and overall."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from .runner import shows

GOALS = ("goals: class and location ≥ 95 %, 0 effects claimed on 'none' cases; two-effect:"
         " both found ≥ 90 %, no third; final fit at the truth's level (weighted gap ≤ 1.1 ×"
         " the truth's) ≥ 95 %")  # fmt: skip

#: what the last two columns of the summary count
SHOWS = (
    "where it shows: the single-effect cases whose parameter refit is above 1.1 × the"
    " truth model's weighted gap (the effect shows above the noise; elsewhere no candidate"
    " can pass the verdict rule's first condition, the base above the noise level)"
)


def _f(v: Any, fmt: str = ".2f") -> str:
    return "–" if v is None else format(v, fmt)


def _mark(v: bool | None) -> str:
    return "–" if v is None else ("✓" if v else "✗")


def _pct(k: int, n: int) -> str:
    return f"{k / n:.0%} ({k}/{n})" if n else "–"


def time_ratio(r: dict[str, Any]) -> float | None:
    d, f = r.get("diagnosis_s"), r.get("fit_s")
    return d / f if d is not None and f else None


def _fit(r: dict[str, Any]) -> str:
    """The fit's wall time, marked when the fit failed or stopped at its iteration limit."""
    status = str(r.get("fit_status", ""))
    mark = " (failed)" if status.startswith("failed") else ""
    mark = " (max iter)" if "Maximum_Iterations" in status else mark
    return _f(r.get("fit_s"), ".0f") + mark


def case_table(rows: list[dict[str, Any]]) -> str:
    head = ("| case | truth | truth location | claimed (verdict first) | class | loc | extra"
            " | gap refit | final db | truth db | at noise | gap_closed | truth gap_closed"
            " | ratio | screened | diagnose s | fit s | diag/fit |")  # fmt: skip
    lines = [head, "|" + "---|" * 18]
    for r in rows:
        truth = " + ".join(t[0] for t in r["truth"]) or "none"
        where = " + ".join(t[1] for t in r["truth"]) or "–"
        if "error" in r:
            lines.append(f"| {r['case']} | {truth} | {where} | error: {r['error']} |"
                         + " |" * 14)  # fmt: skip
            continue
        got = ", ".join(f"{e}@{loc}" for e, loc in r["claimed"]) or "none"
        lines.append(
            f"| {r['case']} | {truth} | {where} | {got} | {_mark(r['class_ok'])} |"
            f" {_mark(r['location_ok'])} | {r['extra_claims']} | {_f(r['gap_refit'])} |"
            f" {_f(r.get('final_db'))} | {_f(r['db_truth'])} | {_mark(r.get('at_noise'))} |"
            f" {_f(r['gap_closed'])} | {_f(r['truth_gap_closed'])} |"
            f" {_f(r['ratio'])} | {_mark(r['screen_ok'])} | {_f(r.get('diagnosis_s'), '.0f')} |"
            f" {_fit(r)} | {_f(time_ratio(r), '.1f')} |"
        )
    return "\n".join(lines)


def _median(xs: Iterable[float | None]) -> float | None:
    v = [x for x in xs if x is not None]
    return float(np.median(v)) if v else None


def _shows(r: dict[str, Any]) -> bool:
    """The row's ``shows`` (:func:`.runner.shows`), from its gaps when the row predates it."""
    if "shows" in r:
        return bool(r["shows"])
    return bool(shows(r.get("gap_refit"), r.get("db_truth"), len(r["truth"])))


def _group(rows: list[dict[str, Any]]) -> dict[str, Any]:
    ok = [r for r in rows if "error" not in r]
    single = [r for r in ok if len(r["truth"]) <= 1]
    eff = [r for r in single if r["truth"]]
    none = [r for r in single if not r["truth"]]
    double = [r for r in ok if len(r["truth"]) > 1]
    screened = [r["screen_ok"] for r in ok if r["screen_ok"] is not None]
    noise = [r["at_noise"] for r in ok if r.get("at_noise") is not None]
    final = [r["final_fit_at_noise"] for r in ok if r.get("final_fit_at_noise") is not None]
    tied = [r["named_or_tied"] for r in ok if r.get("named_or_tied") is not None]
    visible = [r for r in eff if _shows(r)]
    return {
        "n": len(rows), "failed": len(rows) - len(ok),
        "class": _pct(sum(r["class_ok"] for r in single), len(single)),
        "loc": _pct(sum(bool(r["location_ok"]) for r in eff), len(eff)),
        "class_vis": _pct(sum(r["class_ok"] for r in visible), len(visible)),
        "loc_vis": _pct(sum(bool(r["location_ok"]) for r in visible), len(visible)),
        "extra1": f"{sum(r['extra_claims'] > 0 for r in eff)}/{len(eff)}",
        "none": f"{sum(bool(r['claimed']) for r in none)}/{len(none)}",
        "both": _pct(sum(bool(r["location_ok"]) for r in double), len(double)),
        "third": f"{sum(r['extra_claims'] > 0 for r in double)}/{len(double)}",
        "ratio": _f(_median(r["ratio"] for r in eff)),
        "diag_s": _f(_median(r.get("diagnosis_s") for r in ok), ".0f"),
        "fit_s": _f(_median(r.get("fit_s") for r in ok), ".0f"),
        "t_ratio": _f(_median(time_ratio(r) for r in ok), ".1f"),
        "recall": f"{sum(screened)}/{len(screened)}" if screened else "n/a",
        "at_noise": _pct(sum(noise), len(noise)),
        "final_fit": _pct(sum(final), len(final)) if final else "–",
        "tied": _pct(sum(tied), len(tied)),
    }  # fmt: skip


def summary_table(rows: list[dict[str, Any]]) -> str:
    """One line per design × regime present, then per design, per regime and overall."""
    head = ("| design | regime | cases (failed) | class right | location right | claimed on"
            " none | two-effect both found | third claimed | median ratio | median diagnose s"
            " | median fit s | median diag/fit | screening recall"
            " | final model at noise | final fit at noise | named or tied"
            " | class right where it shows | location right where it shows"
            " | single-effect, second claimed |")  # fmt: skip
    lines = [head, "|" + "---|" * 19]
    designs = list(dict.fromkeys(r["design"] for r in rows))
    regimes = list(dict.fromkeys(r["regime"] for r in rows))
    groups = [((d, g), [r for r in rows if r["design"] == d and r["regime"] == g])
              for d in designs for g in regimes]  # fmt: skip
    groups += [((d, "all"), [r for r in rows if r["design"] == d]) for d in designs]
    groups += [(("all", g), [r for r in rows if r["regime"] == g]) for g in regimes]
    groups.append((("all", "all"), rows))
    for (d, g), rs in groups:
        if not rs:
            continue
        s = _group(rs)
        lines.append(
            f"| {d} | {g} | {s['n']} ({s['failed']}) | {s['class']} | {s['loc']} | {s['none']} |"
            f" {s['both']} | {s['third']} | {s['ratio']} | {s['diag_s']} | {s['fit_s']} |"
            f" {s['t_ratio']} | {s['recall']} | {s['at_noise']} | {s['final_fit']} |"
            f" {s['tied']} | {s['class_vis']} | {s['loc_vis']} | {s['extra1']} |"
        )
    return "\n".join(lines) + "\n\n" + GOALS + "\n\n" + SHOWS


def open_table(rows: list[dict[str, Any]]) -> str:
    """One line per withheld cause and one for all: with the cause's class among the
    candidates, is it named at the right place; with it left out (outside the library, or
    removed by ``--leave-one-out``), how did the answer come out, was it honest (never
    *explained*), and does the description of the remainder point where the cause lives."""
    head = (
        "| cause | cases (failed) | class offered: class right | location right"
        " | left out: explained / partly / unexplained | honest | remainder right |"
    )
    lines = [head, "|" + "---|" * 7]
    causes = list(dict.fromkeys(r["truth"][0][0] for r in rows if r["truth"]))
    groups = [(c, [r for r in rows if r["truth"] and r["truth"][0][0] == c]) for c in causes]
    for name, rs in [*groups, ("**all**", [r for r in rows if r["truth"]])]:
        ok = [r for r in rs if "error" not in r]
        offered = [r for r in ok if not r.get("left_out")]
        out = [r for r in ok if r.get("left_out")]
        answers = [sum(r.get("outcome") == o for r in out)
                   for o in ("explained", "partly_explained", "unexplained")]  # fmt: skip
        judged = [r["remainder_ok"] for r in out if r.get("remainder_ok") is not None]
        lines.append(
            f"| {name} | {len(rs)} ({len(rs) - len(ok)}) |"
            f" {_pct(sum(r['class_ok'] for r in offered), len(offered))} |"
            f" {_pct(sum(bool(r['location_ok']) for r in offered), len(offered))} |"
            f" {' / '.join(map(str, answers)) if out else '–'} |"
            f" {_pct(sum(bool(r['honest']) for r in out), len(out))} |"
            f" {_pct(sum(judged), len(judged))} |"
        )
    return "\n".join(lines)
