"""Units of a Bode plot's magnitude axis: a channel's SI unit from its joints' units, and the
axis label in the plotted quantity (receptance, mobility or accelerance)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..exceptions import DataError

# response unit -> excitation unit (the generalised force dual), and the reverse
_DUAL = {"m": "N", "rad": "N·m", "N": "m", "N·m": "rad", "N*m": "rad", "Nm": "rad"}
_RESPONSE = {"m", "rad"}


def _unit_pair(units: Mapping[str, Any], joint: str) -> tuple[str, str] | None:
    """(response unit, excitation unit) of ``joint`` from a user ``units`` mapping."""
    if joint not in units:
        return None
    val = units[joint]
    if isinstance(val, tuple | list) and len(val) == 2:
        return str(val[0]), str(val[1])
    val = str(val)
    if val in _RESPONSE:
        return val, _DUAL[val]
    if val in _DUAL:
        return _DUAL[val], "N·m" if _DUAL[val] == "rad" else "N"
    raise DataError(
        f"units[{joint!r}] = {val!r} is not a unit; valid: 'm', 'rad', 'N', 'N·m' "
        "or a (response, excitation) pair"
    )


def channel_unit(
    units: Mapping[str, Any] | None, out: str, inp: str, quantity: str = "receptance"
) -> str | None:
    """The SI unit of channel ``out.inp`` of ``quantity``, e.g. ``'m/N'``, or None if unknown."""
    if not units:
        return None
    ro = _unit_pair(units, out)
    ri = _unit_pair(units, inp)
    if ro is None or ri is None:
        return None
    num, den = ro[0], ri[1]
    if quantity == "mobility":
        num = f"({num}/s)"
    elif quantity == "accelerance":
        num = f"({num}/s²)"
    if "·" in den or "*" in den:
        den = f"({den})"
    return f"{num}/{den}"


#: what a magnitude axis shows, per quantity
QUANTITY_WORDS = {
    "receptance": "receptance",
    "mobility": "mobility",
    "accelerance": "accelerance",
}


def magnitude_label(quantity: str, unit: str | None) -> str:
    """The magnitude axis label: the quantity and ``dB re 1 UNIT`` (or ``[dB]``)."""
    word = QUANTITY_WORDS.get(quantity, quantity)
    return f"{word} [dB re 1 {unit}]" if unit else f"|{word}| [dB]"
