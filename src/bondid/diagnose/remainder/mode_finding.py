"""A mode in the remainder (:class:`ModeFinding`): missing in the model, spurious in the model
(absent in the data), or misplaced (both have it, at a different frequency or damping); with
where it shows (which output rows and input columns), and its MAC to the model's modes."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from . import words
from .base import Finding, Location, Significance
from .modal import Nearest


@dataclass(frozen=True)
class Seen:
    """Where a mode shows: the channels whose own residual it lowers clearly
    (:func:`.stats.seen`), among the channels it was fitted on."""

    channels: tuple[str, ...]
    fitted: tuple[str, ...]

    @property
    def outputs(self) -> list[str]:
        return _unique(c.rpartition(".")[0] for c in self.channels)

    @property
    def inputs(self) -> list[str]:
        return _unique(c.rpartition(".")[2] for c in self.channels)

    def confined(self) -> tuple[str, list[str]]:
        """``("output", [row])`` when every channel that shows it lies in one output row and
        other rows were fitted too; ``("input", [column])`` likewise; ``("channel", [c])`` for
        a single channel of several; else ``("spread", [])``."""
        fit_out = _unique(c.rpartition(".")[0] for c in self.fitted)
        fit_in = _unique(c.rpartition(".")[2] for c in self.fitted)
        outs, ins = self.outputs, self.inputs
        single = len(self.channels) == 1 and len(self.fitted) > 1
        if single and len(fit_out) > 1 and len(fit_in) > 1:
            return "channel", list(self.channels)
        if len(outs) == 1 and len(fit_out) > 1 and (len(ins) > 1 or len(fit_in) == 1):
            return "output", outs
        if len(ins) == 1 and len(fit_in) > 1 and (len(outs) > 1 or len(fit_out) == 1):
            return "input", ins
        if len(self.channels) == 1 and len(self.fitted) > 1:
            return "channel", list(self.channels)
        return "spread", []

    def phrase(self) -> str:
        side, which = self.confined()
        n, of = len(self.channels), len(self.fitted)
        if side == "output":
            row = [c for c in self.fitted if c.rpartition(".")[0] == which[0]]
            return f"only in output row {which[0]} ({n} of {len(row)} channels)"
        if side == "input":
            col = [c for c in self.fitted if c.rpartition(".")[2] == which[0]]
            return f"only in input column {which[0]} ({n} of {len(col)} channels)"
        if side == "channel":
            return f"only in channel {which[0]}"
        if not self.channels:
            return "in no single channel clearly"
        return (
            f"in {n} of {of} channels (outputs {words.names(self.outputs)}; "
            f"inputs {words.names(self.inputs)})"
        )


def _unique(items: Any) -> list[str]:
    out: list[str] = []
    for x in items:
        if x not in out:
            out.append(x)
    return out


@dataclass
class ModeFinding(Finding):
    """A mode of the remainder.

    Attributes:
        f_hz, zeta: the mode in the data (missing, misplaced) or in the model (spurious).
        status: ``"missing"``, ``"spurious"`` or ``"misplaced"``.
        form: how it was fitted: ``"additive"`` (a mode term added to every channel),
            ``"output filter"`` / ``"input filter"`` (a resonance multiplying one output row /
            input column), ``"model mode"`` (the model's own mode moved or removed).
        seen: the channels that show it.
        nearest: the model mode nearest it (frequency, MAC).
        f_model_hz, zeta_model: the model's mode (misplaced, spurious).
        scale: the share of the model's mode the data keep (spurious / misplaced: ``|c|``).
    """

    f_hz: float = math.nan
    zeta: float = math.nan
    status: str = "missing"
    form: str = "additive"
    seen: Seen = field(default_factory=lambda: Seen((), ()))
    nearest: Nearest | None = None
    f_model_hz: float | None = None
    zeta_model: float | None = None
    scale: float | None = None

    def figures(self) -> dict[str, Any]:
        side, which = self.seen.confined()
        return {
            "f_hz": self.f_hz,
            "zeta": self.zeta,
            "status": self.status,
            "form": self.form,
            "seen_channels": list(self.seen.channels),
            "fitted_channels": list(self.seen.fitted),
            "seen_outputs": self.seen.outputs,
            "seen_inputs": self.seen.inputs,
            "confined_to": {"side": side, "names": which},
            "nearest_model_mode": None if self.nearest is None else self.nearest.as_dict(),
            "f_model_hz": self.f_model_hz,
            "zeta_model": self.zeta_model,
            "scale": self.scale,
        }


def _mac_phrase(near: Nearest | None) -> str:
    if near is None or near.f_hz is None:
        return "the model has no mode to compare"
    if near.best_mac < 0.3:
        return "no model mode within MAC 0.3 (within ± 20 %)"
    return f"nearest model mode {words.hz(near.f_hz)} (MAC {near.mac:.2f})"


def _where_advice(seen: Seen, form: str) -> tuple[str, str]:
    """``(location side, advice)`` for a missing mode seen as ``seen``, fitted in ``form``.
    A resonance that multiplies a whole row (column) is the sensor's (drive's) own; a mode
    term that only one row's channels show may also be a mode local to where that sensor
    measures, and is said so."""
    side, which = seen.confined()
    whole = form.endswith("filter")
    if side == "output":
        tail = "" if whole else ", or a mode local to where it measures"
        return side, (
            f"look at the {which[0]} sensor's mounting (a read head or bracket on a compliant "
            f"mount){tail}"
        )
    if side == "input":
        tail = "" if whole else ", or a mode local to where it acts"
        return side, (
            f"look at the {which[0]} drive (an amplifier or current-loop resonance, the motor's "
            f"coupling){tail}"
        )
    if side == "channel":
        return side, f"look at the {which[0]} measurement (set-up, a local resonance)"
    return "global", (
        "a structural mode the model lacks (a compliant joint, bracket, base or mount, a "
        "flexible link)"
    )


def missing_mode(
    sig: Significance, f_hz: float, zeta: float, seen: Seen, near: Nearest | None, form: str,
    band_hz: tuple[float, float],
) -> ModeFinding:  # fmt: skip
    """A mode in the data that the model lacks (or, when a model mode pairs with it, that
    the model places elsewhere: ``"misplaced"``)."""
    side, which = seen.confined()
    loc = Location(side if side != "spread" else "global", tuple(which), seen.channels)
    if near is not None and near.paired and near.f_hz is not None:
        text = (
            f"the data's mode at {words.hz(f_hz)} (ζ {100 * zeta:.1f} %) does not match the "
            f"model's at {words.hz(near.f_hz)} ({100 * (near.df_rel or 0.0):+.0f} %, MAC "
            f"{near.mac:.2f}); seen {seen.phrase()}"
        )
        return ModeFinding(
            "misplaced_mode", text, sig.share, loc, band_hz,
            "the stiffness, mass or damping that sets this mode is off in the model", sig,
            f_hz=f_hz, zeta=zeta, status="misplaced", form=form, seen=seen, nearest=near,
            f_model_hz=near.f_hz,
        )  # fmt: skip
    _, advice = _where_advice(seen, form)
    text = (
        f"a mode at {words.hz(f_hz)} (ζ {100 * zeta:.1f} %) is missing in the model; seen "
        f"{seen.phrase()}, {_mac_phrase(near)}: {advice}"
    )
    return ModeFinding(
        "missing_mode", text, sig.share, loc, band_hz, advice, sig, f_hz=f_hz, zeta=zeta,
        status="missing", form=form, seen=seen, nearest=near,
    )  # fmt: skip


def model_mode(
    sig: Significance, f_model: float, zeta_model: float, scale: float,
    moved: tuple[float, float] | None, seen: Seen, band_hz: tuple[float, float],
) -> ModeFinding:  # fmt: skip
    """The model's mode at ``f_model`` absent in the data (``moved`` None: kept at ``scale``
    of its strength) or moved to ``moved = (f, ζ)``."""
    side, which = seen.confined()
    loc = Location(side if side != "spread" else "global", tuple(which), seen.channels)
    if moved is None:
        text = (
            f"the model's mode at {words.hz(f_model)} (ζ {100 * zeta_model:.1f} %) is not in "
            f"the data (they keep {100 * scale:.0f} % of it); seen {seen.phrase()}"
        )
        return ModeFinding(
            "spurious_mode", text, sig.share, loc, band_hz,
            "the model holds a compliance or mass the machine lacks there, or too little "
            "damping", sig, f_hz=f_model, zeta=zeta_model, status="spurious",
            form="model mode", seen=seen, f_model_hz=f_model, zeta_model=zeta_model,
            scale=scale,
        )  # fmt: skip
    f, z = moved
    text = (
        f"the model's mode at {words.hz(f_model)} (ζ {100 * zeta_model:.1f} %) lies at "
        f"{words.hz(f)} (ζ {100 * z:.1f} %, {100 * (f / f_model - 1):+.0f} %) in the data; seen "
        f"{seen.phrase()}"
    )
    return ModeFinding(
        "misplaced_mode", text, sig.share, loc, band_hz,
        "the stiffness, mass or damping that sets this mode is off in the model", sig,
        f_hz=f, zeta=z, status="misplaced", form="model mode", seen=seen,
        f_model_hz=f_model, zeta_model=zeta_model, scale=scale,
    )  # fmt: skip


def seen_from(
    reductions: dict[tuple[int, int, int], tuple[float, float]],
    keys: Sequence[tuple[int, int, int]],
    names: dict[tuple[int, int, int], str],
) -> Seen:
    """:class:`Seen` from the channels ``keys`` that show a finding among those fitted
    (``reductions``' keys), named by ``names``; pooled over data sets."""
    fitted = _unique(names[k] for k in reductions)
    shown = _unique(names[k] for k in keys)
    return Seen(tuple(shown), tuple(fitted))
