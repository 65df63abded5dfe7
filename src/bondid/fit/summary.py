"""What ``python -m bondid.fit`` prints: the short summary, and the exit code with its advice.

The status line says whether the fit converged and how: IPOPT's own test, or the stall test
(:mod:`bondid.optim.stall`: the cost, the steps and the projected gradient went flat — a
converged fit with its reason, not a failure). A fit stopped at its iteration limit is told
to raise ``--max-iter`` only when its cost was still falling there; one whose cost had gone
flat is told that more iterations will not help, and why that can be.
"""

from __future__ import annotations

import math
import sys
from typing import Any

from ..cli import EXIT_FAILED, EXIT_OK
from ..optim.stall import STALLED, still_falling
from ..range_ends import range_end
from ..setup.damping import damping_line
from .headline import headline_lines, std_footer

#: IPOPT's status of a solve stopped at its iteration limit
ITERATION_LIMIT = "Maximum_Iterations_Exceeded"


def _fmt(v: float) -> str:
    return "—" if not math.isfinite(v) else f"{v:.6g}"


def status_line(result: Any, wall_s: float, extra: dict[str, Any]) -> str:
    """The summary's first line: converged or not, how, iterations, the search's time
    (``result.wall_s``: every run) and the command's (``wall_s``: reading, the search,
    the results written)."""
    ms = extra.get("multistart") or {}
    its = f"{result.iterations} iterations"
    total = ms.get("iterations_all")
    if ms.get("n_runs", 1) > 1 and total is not None:
        its += f" in the kept search, {total} in all {ms['n_runs']} runs"
    if result.status == STALLED:
        how = "converged: the cost stopped falling (Converged_Stalled)"
    elif result.success:
        how = f"converged ({result.status})"
    elif result.status == "failed":
        how = f"FAILED ({result.solver_status or 'failed'})"
    else:
        how = f"NOT converged ({result.status})"
    return f"bondid.fit: {how}, {its}; {result.wall_s:.1f} s fitting, {wall_s:.1f} s in all"


def merged_notes(notes: list[str], best_start: int) -> list[str]:
    """``notes`` with the ``fallback:`` notes of the kept search and of start 0 (when the kept
    search is a fallback start, each ran its own fallback) told in one note."""
    fb = [n for n in notes if n.startswith("fallback:")]
    if len(fb) < 2:
        return list(notes)
    # the kept search's own note comes first, start 0's (appended by the multistart) last
    said = [f"start {best_start} (kept): {fb[0][len('fallback: ') :]}"]
    said += [f"start 0: {n[len('fallback: ') :]}" for n in fb[1:]]
    first = notes.index(fb[0])
    out = [n for n in notes if n not in fb]
    out.insert(first, "fallback: " + "; ".join(said))
    return out


def summary(result: Any, content: dict[str, Any] | None, extra: dict[str, Any],
            wall_s: float, reduction: Any = None) -> str:  # fmt: skip
    """The short human summary printed on stdout (``wall_s``: the run's time so far;
    ``reduction``: the :class:`~bondid.data.lines.LineReduction` of the lines the fit
    used, or None)."""
    lines = [
        status_line(result, wall_s, extra),
        f"cost ({result.cost_name}): {result.cost_initial:.6g} → {result.cost_final:.6g}",
    ]
    if result.stop_reason:
        lines.insert(1, f"stop: {result.stop_reason}")
    ms = extra.get("multistart") or {}
    if result.cost_start is not None:
        lines[-1] += (
            f" (at the model's values; the kept search started from start"
            f" {ms.get('best_start')} at {result.cost_start:.6g})"
        )
    if content is not None:
        lines[1:1] = headline_lines(content["db_rms"])
    if reduction is not None and reduction.reduced:
        lines.insert(1, reduction.summary_line())
    if ms and ms["n_runs"] > 1:
        lines.append(
            f"multistart: {ms['n_runs']} runs ({ms['n_failed']} failed), final cost min"
            f" {ms['min']:.4g} / median {ms['median']:.4g} / max {ms['max']:.4g};"
            f" best from start {ms['best_start']}"
        )
    for st in extra.get("stages") or ():
        info = st["skipped"] and f"skipped ({st['skipped']})"
        if not info:
            info = f"{st['status']}, cost {st['cost_initial']:.4g} → {st['cost_final']:.4g}"
        lines.append(f"stage {st['name']}: {info}")
    lines += parameter_table(result)
    said = damping_line(extra.get("damping"))
    if said:
        lines.append(said)
    if result.active_constraints:
        lines.append("active constraints: " + "; ".join(result.active_constraints))
    for note in merged_notes(list(getattr(result, "notes", []) or []), ms.get("best_start", 0)):
        lines.append(f"note: {note}")
    return "\n".join(lines)


def parameter_table(result: Any) -> list[str]:
    """The parameter table: the model's value (``initial``), the fitted one, the change and
    the standard deviation (``[bound]``: on a bound; a footer says why a std is "—")."""
    w = max([len("parameter"), *(len(n) for n in result.names)])
    lines = [f"{'parameter':<{w}}  {'initial':>12}  {'fitted':>12}  {'change':>9}  {'std':>10}"]
    n_bound = 0
    for i, n in enumerate(result.names):
        a, b, sd = float(result.initial[i]), float(result.fitted[i]), float(result.std[i])
        ch = f"{100 * (b - a) / abs(a):+.2f} %" if a != 0 else f"{b - a:+.3g}"
        lower, upper = getattr(result, "lower", None), getattr(result, "upper", None)
        ends = () if lower is None or upper is None else (float(lower[i]), float(upper[i]))
        # log scale for a positive range (masses, springs), linear for a CoM or a mix
        bound = bool(ends) and range_end(b, *ends, log=True) is not None
        n_bound += bound
        mark = "  [bound]" if bound else ""
        lines.append(f"{n:<{w}}  {_fmt(a):>12}  {_fmt(b):>12}  {ch:>9}  {_fmt(sd):>10}{mark}")
    footer = std_footer([float(v) for v in result.std], n_bound)
    return lines + ([footer] if footer else [])


def exit_code(result: Any) -> int:
    """0 when the fit converged (IPOPT's test or the stall test), else 1 with one line on
    stderr saying what happened and what to do."""
    if result.status == "failed":
        print(
            f"error: the fit failed ({result.failure}); fit.json keeps the best point reached",
            file=sys.stderr,
        )
        return EXIT_FAILED
    if result.success:
        return EXIT_OK
    history = list(result.cost_history)
    if result.status == ITERATION_LIMIT and still_falling(history):
        advice = "its cost was still falling at the limit: raise --max-iter"
    elif result.status == ITERATION_LIMIT:
        advice = (
            "its cost had stopped falling but its steps or its gradient had not settled (the"
            " stall test): more iterations will not lower it; parameters the data do not"
            " determine (see the std column) can be fixed, bounded or given a --prior"
        )
    else:
        advice = "narrow the problem (fewer free parameters, tighter bounds) or check the start"
    print(
        f"error: the fit did not converge (solver status: {result.status}); {advice}",
        file=sys.stderr,
    )
    return EXIT_FAILED
