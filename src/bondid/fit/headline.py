"""The figures a fit's summary leads with, worded so that a newcomer reads them right.

The headline is the weighted ``db_rms`` before → after, next to the noise level of the same
data (the weighted ``db_rms`` an exact model would score, :mod:`bondid.cost.noise_level`) and
what the comparison means. The plain RMS over every point comes last, labelled as what it is:
it includes the anti-resonances and weak cross terms under the sensor's noise floor, where
every model errs by tens of dB, so a better fit may even raise it.
"""

from __future__ import annotations

from typing import Any

#: a final db_rms up to this factor times the noise level counts as "at the noise level"
AT_NOISE = 1.1


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


def headline_lines(db: dict[str, Any]) -> list[str]:
    """The db_rms lines of the summary from ``fit.json``'s ``db_rms`` block."""
    if db.get("initial") is None:
        return []
    noise = db.get("noise_level")
    lines = [
        f"db_rms ({db['weighting']}-weighted): {db['initial']:.3f} dB → {db['final']:.3f} dB",
    ]
    if noise is not None:
        lines.append(
            f"noise level of these data: {noise:.2f} dB (the db_rms an exact model would score,"
            f" from the data's estimated noise): {verdict(db['final'], noise)}"
        )
    c = db.get("coherent") or {}
    if c.get("final") is not None and c["fraction"] < 1.0:
        lines.append(
            f"db_rms where coherence ≥ {c['min_coherence']}: {c['initial']:.3f} dB →"
            f" {c['final']:.3f} dB ({100 * c['fraction']:.0f} % of the points)"
        )
    uw = db["unweighted"]
    lines.append(
        f"(plain RMS over all points, noise-only ones included: {uw['initial']:.3f} dB →"
        f" {uw['final']:.3f} dB; a noise figure, not a measure of the fit)"
    )
    return lines
