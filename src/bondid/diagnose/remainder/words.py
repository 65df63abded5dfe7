"""Figures in words: frequencies, times, stiffnesses, shares, and the names of rows and
columns as a test engineer reads them."""

from __future__ import annotations

import math
from collections.abc import Sequence


def hz(f: float) -> str:
    """``1.10 kHz``, ``164 Hz``, ``2.5 Hz``."""
    if not math.isfinite(f):
        return "? Hz"
    if f >= 1000:
        return f"{f / 1000:.2f} kHz"
    if f >= 100:
        return f"{f:.0f} Hz"
    if f >= 10:
        return f"{f:.1f} Hz"
    return f"{f:.2g} Hz"


def band(lo: float, hi: float) -> str:
    """``900–1400 Hz`` or ``1.2–3.0 kHz``."""
    if lo >= 1000:
        return f"{lo / 1000:.1f}–{hi / 1000:.1f} kHz"
    return f"{_short(lo)}–{_short(hi)} Hz"


def _short(f: float) -> str:
    return f"{f:.0f}" if f >= 10 else f"{f:.2g}"


def seconds(t: float) -> str:
    """``85 µs``, ``1.2 ms``."""
    a = abs(t)
    if a < 1e-3:
        return f"{t * 1e6:.3g} µs"
    if a < 1.0:
        return f"{t * 1e3:.3g} ms"
    return f"{t:.3g} s"


def si(value: float, unit: str) -> str:
    """``4.1 kN/m``, ``350 N/m``, ``2.3 MN/m`` (3 significant digits)."""
    a = abs(value)
    for scale, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if a >= scale:
            return f"{value / scale:.3g} {prefix}{unit}"
    if a >= 1 or a == 0:
        return f"{value:.3g} {unit}"
    for scale, prefix in ((1e-3, "m"), (1e-6, "µ")):
        if a >= scale:
            return f"{value / scale:.3g} {prefix}{unit}"
    return f"{value:.3g} {unit}"


def pct(share: float) -> str:
    """``23 %``."""
    return f"{100 * share:.0f} %" if math.isfinite(share) else "? %"


def db(x: float) -> str:
    return f"{x:+.2f} dB" if math.isfinite(x) else "? dB"


def names(items: Sequence[str]) -> str:
    """``x``, ``x and y``, ``x, y and z``."""
    items = list(items)
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def side_phrase(side: str, which: Sequence[str]) -> str:
    """``output row y``, ``input columns x and z``, ``channel y.x``."""
    plural = "s" if len(which) > 1 else ""
    word = {"output": "output row", "input": "input column", "channel": "channel",
            "drive": "drive"}.get(side, side)  # fmt: skip
    return f"{word}{plural} {names(which)}" if which else "every channel"


#: where to look, by the side a finding lives on
ADVICE = {
    "output": "sensor side: look at the {0} sensor (its mounting, calibration, alignment)",
    "input": "actuator side: look at the {0} drive (amplifier, current loop, force constant)",
    "channel": "one channel: look at the {0} measurement (its cabling and set-up)",
}


def advice(side: str, which: Sequence[str]) -> str:
    """Where to look for something confined to ``side`` (``output``/``input``/``channel``)."""
    tpl = ADVICE.get(side)
    return tpl.format(names(which)) if tpl else ""
