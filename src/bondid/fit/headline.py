"""The figures a fit's summary leads with, worded so that a newcomer reads them right.

The headline is the weighted ``db_rms`` before → after, next to the noise level of the same
data (the weighted ``db_rms`` an exact model would score, :mod:`bondid.cost.noise_level`) and
what the comparison means. The plain RMS over every point comes last, labelled as what it is:
it includes the anti-resonances and weak cross terms under the sensor's noise floor, where
every model errs by tens of dB, so a better fit may even raise it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ..optim.noise import AT_LEVEL

#: a final db_rms up to this factor times the noise level counts as "at the noise level"
#: (the one ratio every search and rule uses, :mod:`bondid.optim.noise`)
AT_NOISE = AT_LEVEL


def verdict(final: float, noise: float | None) -> str:
    """How the final weighted db_rms compares with the noise level (both dB)."""
    if noise is None or not noise > 0:
        return ""
    if final <= AT_NOISE * noise:
        return "the fit is at the noise level"
    return (
        f"{final / noise:.1f}× the noise level: the model (or this fit's free parameters)"
        " misses something the data show; see bondid.diagnose"
    )


def _db(value: Any) -> str:
    """``value`` dB to 3 decimals, or "no finite figure" (never ``nan`` or ``inf``)."""
    if isinstance(value, int | float) and math.isfinite(value):
        return f"{value:.3f} dB"
    return "no finite figure"


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and math.isfinite(value)


def headline_lines(db: dict[str, Any]) -> list[str]:
    """The db_rms lines of the summary from ``fit.json``'s ``db_rms`` block. A figure that
    is not finite is written as such, with the channels that have none and why
    (``db["no_figure"]``)."""
    if db.get("initial") is None and db.get("final") is None and not db.get("no_figure"):
        return []
    noise: Any = db.get("noise_level")
    final: Any = db.get("final")
    lines = [f"db_rms ({db['weighting']}-weighted): {_db(db.get('initial'))} → {_db(final)}"]
    if _finite(noise) and _finite(final):
        lines.append(
            f"noise level of these data: {noise:.2f} dB (the db_rms an exact model would score,"
            f" from the data's estimated noise): {verdict(final, noise)}"
        )
    for why in db.get("no_figure") or ():
        lines.append(f"no finite figure for {why}")
    c = db.get("coherent") or {}
    if _finite(c.get("final")) and _finite(c.get("fraction")) and c["fraction"] < 1.0:
        lines.append(
            f"db_rms where coherence ≥ {c['min_coherence']}: {_db(c.get('initial'))} →"
            f" {_db(c['final'])} ({100 * c['fraction']:.0f} % of the points)"
        )
    uw = db.get("unweighted") or {}
    lines.append(
        f"(plain RMS over all points, noise-only ones included: {_db(uw.get('initial'))} →"
        f" {_db(uw.get('final'))}; a noise figure, not a measure of the fit)"
    )
    return lines


#: why a std can be undefined, the footer of every parameter table with a std column
STD_FOOTER = (
    "std —: not determined by these data: the parameter moves along a direction the measured"
    " FRFs do not see (alone or in a combination with others), so any value along it fits as"
    " well and the prior keeps it near the model's value; a parameter on a bound is marked"
    " [bound] (its std is that of the unbounded problem)"
)


def std_footer(stds: Sequence[float], n_on_bound: int = 0) -> str:
    """The footer line under the parameter table ("" when every std is defined and no
    parameter is on a bound)."""
    n_undef = sum(1 for v in stds if not math.isfinite(float(v)))
    if not n_undef and not n_on_bound:
        return ""
    counts = f"{n_undef} of {len(stds)} std undefined"
    if n_on_bound:
        counts += f", {n_on_bound} on a bound"
    return f"{counts}. {STD_FOOTER}"
