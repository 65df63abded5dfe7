"""How the data damp their modes against how the model does: :func:`damping_law`.

Several modes both have, each at its own frequency but damped otherwise in the data, are
seldom several faults: they are one damping *law* the model's dampers cannot follow. A
lightly damped structure (a bar, a plate, a welded frame) loses much the same share of its
energy per cycle at every mode, so its damping ratio hardly changes with frequency, while a
damper on a joint gives each mode whatever its share of that joint's motion is. The law is
read from the modes of the data paired with the model's (:func:`bondid.modal.pairing.
pair_modes`, every data set): the data's damping ratios against frequency, ``ζ ∝ f^b`` by
least squares in logarithms, named by its exponent

* ``|b| ≤ FLAT``: the same ratio at every mode — a structural loss factor
  (``--damping structural``, ``η = 2ζ``);
* ``b ≥ 1 − FLAT``: growing with frequency — stiffness-proportional damping (``β·K``);
* ``b ≤ −(1 − FLAT)``: falling with frequency — mass-proportional damping (``α·M``);
* in between: a mix of the two (``--damping rayleigh-only``).

It is said when at least :data:`MIN_MODES` modes pair, at least :data:`MIN_OFF` of them are
damped otherwise in the data (by more than :data:`DAMPING_FACTOR`, at a frequency within
their bandwidth) and the search claimed a misplaced mode among them. The finding sums up
those claimed modes, so its share is theirs together and it adds no correction of its own;
:meth:`.describe.Remainder.primary` passes over it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import words
from .base import Finding, Location
from .mode_finding import ModeFinding

KIND = "damping_law"
#: paired modes a law needs
MIN_MODES = 3
#: of which damped otherwise in the data
MIN_OFF = 2
#: a mode's damping is "off" when data and model differ by more than this factor
DAMPING_FACTOR = 1.25
#: a mode's damping counts as off only when its frequency moved less than this many
#: half-power bandwidths: a mode that moved is first a stiffness or a mass
MAX_SHIFT_BANDWIDTHS = 1.0
#: exponents within this of 0 (1, −1) read as flat (stiffness-, mass-proportional)
FLAT = 0.3
#: paired modes of several data sets closer than this (relative) are one mode
SAME_MODE = 0.02


@dataclass(frozen=True)
class Pair:
    """A mode of the data and the model's paired with it: frequencies [Hz], damping ratios."""

    f_hz: float
    zeta: float
    f_model_hz: float
    zeta_model: float

    @property
    def off(self) -> bool:
        """Damped otherwise in the data, at much the same frequency (module docstring)."""
        shift = abs(self.f_hz / self.f_model_hz - 1.0)
        width = 2.0 * max(self.zeta, self.zeta_model)
        return shift <= MAX_SHIFT_BANDWIDTHS * width and (
            abs(math.log(self.zeta / self.zeta_model)) > math.log(DAMPING_FACTOR)
        )


@dataclass
class DampingLawFinding(Finding):
    """The damping law of the data's modes against the model's.

    Attributes:
        f_hz: the paired modes' frequencies in the data [Hz] ``(n,)``.
        zeta, zeta_model: their damping ratios in the data and in the model ``(n,)``.
        off: which of them are damped otherwise in the data ``(n,)``.
        exponent: ``b`` of ``ζ ∝ f^b`` fitted to the data's ratios (the model's:
            ``exponent_model``).
        law: ``"constant"``, ``"stiffness-proportional"``, ``"mass-proportional"`` or
            ``"mixed"``.
        damping: the ``--damping`` kind that expresses the law.
    """

    f_hz: list[float] = field(default_factory=list)
    zeta: list[float] = field(default_factory=list)
    zeta_model: list[float] = field(default_factory=list)
    off: list[bool] = field(default_factory=list)
    exponent: float = math.nan
    exponent_model: float = math.nan
    law: str = ""
    damping: str = ""

    def figures(self) -> dict[str, Any]:
        return {
            "f_hz": list(self.f_hz),
            "zeta": list(self.zeta),
            "zeta_model": list(self.zeta_model),
            "off": list(self.off),
            "exponent": self.exponent,
            "exponent_model": self.exponent_model,
            "law": self.law,
            "damping": self.damping,
        }


def pairs_of(rows: Sequence[Sequence[dict[str, Any]]]) -> list[Pair]:
    """The paired modes of :func:`bondid.modal.pairing.pair_modes` ``rows`` (one list per data
    set) with both damping ratios > 0, those of several data sets within :data:`SAME_MODE`
    merged (geometric means), by frequency."""
    found = sorted(
        (Pair(r["f_measured_hz"], r["zeta_measured"], r["f_model_hz"], r["zeta_model"])
         for rs in rows for r in rs
         if r["status"] == "paired" and (r["zeta_measured"] or 0) > 0
         and (r["zeta_model"] or 0) > 0),
        key=lambda p: p.f_hz,
    )  # fmt: skip
    groups: list[list[Pair]] = []
    for p in found:
        if groups and p.f_hz <= groups[-1][0].f_hz * (1.0 + SAME_MODE):
            groups[-1].append(p)
        else:
            groups.append([p])
    return [Pair(*(_geometric_mean([getattr(p, a) for p in g]) for a in FIELDS)) for g in groups]


#: the fields of a :class:`Pair`, in order
FIELDS = ("f_hz", "zeta", "f_model_hz", "zeta_model")


def _geometric_mean(values: Sequence[float]) -> float:
    return float(np.exp(np.mean(np.log(values))))


def _exponent(f_hz: np.ndarray, zeta: np.ndarray) -> float:
    """``b`` of the least-squares line ``ln ζ = a + b ln f``."""
    return float(np.polyfit(np.log(f_hz), np.log(zeta), 1)[0])


def _law(b: float) -> tuple[str, str, str]:
    """``(law, --damping kind, words)`` for the exponent ``b``."""
    if abs(b) <= FLAT:
        return "constant", "structural", "the same ratio at every mode, as a structural loss factor"
    if b >= 1.0 - FLAT:
        return "stiffness-proportional", "rayleigh-only", "a ratio growing with frequency, as β·K"
    if b <= -(1.0 - FLAT):
        return "mass-proportional", "rayleigh-only", "a ratio falling with frequency, as α·M"
    return "mixed", "rayleigh-only", "a ratio that neither stays nor follows α·M or β·K alone"


def _pct(zeta: np.ndarray) -> str:
    """``"0.98–1.04 %"``: the range of damping ratios ``zeta`` in per cent."""
    lo, hi = 100 * zeta.min(), 100 * zeta.max()
    return f"{lo:.2f}–{hi:.2f} %" if hi < 10 else f"{lo:.1f}–{hi:.1f} %"


def _power(b: float) -> str:
    """An exponent to one decimal, never ``-0.0``."""
    return f"{round(b, 1) + 0.0:.1f}"


def _claimed(findings: Sequence[Finding], off: Sequence[Pair]) -> list[Finding]:
    """The misplaced modes among ``findings`` at one of the ``off`` modes (within a
    bandwidth of its frequency)."""
    return [
        f for f in findings
        if isinstance(f, ModeFinding) and f.status == "misplaced"
        and any(abs(f.f_hz / p.f_hz - 1.0) <= 2.0 * max(p.zeta, p.zeta_model) for p in off)
    ]  # fmt: skip


def damping_law(findings: Sequence[Finding], pairs: Sequence[Pair]) -> DampingLawFinding | None:
    """The damping law of the paired modes ``pairs`` (:func:`pairs_of`), given the claimed
    ``findings`` (module docstring), or None when it is not to be said."""
    off = [p for p in pairs if p.off]
    claimed = _claimed(findings, off)
    if len(pairs) < MIN_MODES or len(off) < MIN_OFF or not claimed:
        return None
    f = np.array([p.f_hz for p in pairs])
    z = np.array([p.zeta for p in pairs])
    zm = np.array([p.zeta_model for p in pairs])
    b, bm = _exponent(f, z), _exponent(f, zm)
    law, kind, phrase = _law(b)
    lo, hi = float(f.min()), float(f.max())
    zbar = float(np.exp(np.mean(np.log(z))))
    hint = f"η ≈ {2 * zbar:.3g}" if kind == "structural" else "α and β fitted"
    text = (
        f"the data damp their {len(pairs)} paired modes ({words.band(lo, hi)}) by {phrase} (ζ "
        f"{_pct(z)}, ζ ∝ f^{_power(b)}), where the model's are {_pct(zm)} (ζ ∝ f^"
        f"{_power(bm)}; {len(off)} differ by more than {100 * (DAMPING_FACTOR - 1):.0f} %): a "
        f"damping law its dampers cannot follow; try --damping {kind} ({hint})"
    )
    channels = tuple(sorted({c for m in claimed for c in m.location.channels}))
    return DampingLawFinding(
        KIND, text, float(sum(m.share for m in claimed)), Location("global", (), channels),
        (lo, hi), f"--damping {kind}", None,
        f_hz=f.tolist(), zeta=z.tolist(), zeta_model=zm.tolist(), off=[p.off for p in pairs],
        exponent=b, exponent_model=bm, law=law, damping=kind,
    )  # fmt: skip
