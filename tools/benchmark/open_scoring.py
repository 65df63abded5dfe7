"""The open-world scores of a case: is the answer honest, and does the description of the
remainder point where the withheld cause lives?

* ``honest``: a case whose cause is not among the candidates (its class left out, or outside
  the library) must not come out *explained* (``diagnosis.json``'s ``verdict.outcome``);
* ``remainder_ok``: one of the first two findings of ``remainder`` (or its ``primary``) matches
  one of the case's expected remainders (:func:`.truth.expected_remainder`):

  - ``missing_mode``: a mode finding (missing or misplaced) inside the expected band;
  - ``output_row`` / ``input_column``: a finding on that side naming one of the rows /
    columns (a delay, lag, gain, mode or confinement of that row or column);
  - ``low_frequency``: a drive finding (a spring or mass at a drive), or any finding of the
    expected rows or columns whose band starts below the expected band's top;
  - ``cross_talk``: a leakage finding naming the expected row or column;
  - ``delay``: a delay (or a lag: the data cannot always tell them) on the expected rows.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .truth import Remainder

MODE_KINDS = ("missing_mode", "misplaced_mode")
#: findings read from the remainder, first first
TOP = 2


def _findings(diag: dict[str, Any]) -> list[dict[str, Any]]:
    rem = diag.get("remainder") or {}
    out = [f for f in (rem.get("findings") or []) if isinstance(f, dict)][:TOP]
    prim = rem.get("primary")
    if isinstance(prim, dict) and prim.get("kind"):
        band = (prim.get("bands_hz") or [None])[0]
        out.append({"kind": prim["kind"], "location": {"side": prim.get("side"),
                                                       "names": prim.get("names") or []},
                    "band_hz": band})  # fmt: skip
    return out


def _names(f: dict[str, Any]) -> set[str]:
    loc = f.get("location") or {}
    names = set(loc.get("names") or [])
    for ch in loc.get("channels") or []:
        names |= set(str(ch).split("."))
    return names


def _in_band(f: dict[str, Any], band: tuple[float, float] | None) -> bool:
    if band is None:
        return True
    fb = f.get("band_hz")
    figs = f.get("figures") or {}
    hz = figs.get("f_hz")
    if isinstance(hz, int | float):
        return band[0] <= float(hz) <= band[1]
    if isinstance(fb, list | tuple) and len(fb) == 2:
        return float(fb[0]) <= band[1] and float(fb[1]) >= band[0]
    return False


def matches(f: dict[str, Any], e: Remainder) -> bool:
    """Does finding ``f`` (``diagnosis.json`` form) point where ``e`` says?"""
    kind = f.get("kind")
    side = (f.get("location") or {}).get("side")
    names = _names(f)
    if e.kind == "missing_mode":
        rows_ok = not e.rows or bool(names & set(e.rows)) or side == "global"
        return kind in MODE_KINDS and _in_band(f, e.band_hz) and rows_ok
    if e.kind == "output_row":
        return side == "output" and bool(names & set(e.rows))
    if e.kind == "input_column":
        return side == "input" and bool(names & set(e.columns))
    if e.kind == "low_frequency":
        if kind in ("stiffness_offset", "mass_offset"):
            return not (e.rows or e.columns) or bool(names & set(e.rows + e.columns))
        top = e.band_hz[1] if e.band_hz else float("inf")
        fb = f.get("band_hz")
        low = isinstance(fb, list | tuple) and len(fb) == 2 and float(fb[0]) <= top
        return low and bool(names & set(e.rows + e.columns))
    if e.kind == "cross_talk":
        return kind == "leakage" and bool(names & set(e.rows + e.columns))
    if e.kind == "delay":
        return kind in ("delay", "lag") and (not e.rows or bool(names & set(e.rows))
                                             or side == "global")  # fmt: skip
    return False


def remainder_ok(diag: dict[str, Any], expected: Sequence[Remainder]) -> bool | None:
    """Does the description of the remainder point where one of ``expected`` says (module
    docstring)? None without an expectation."""
    if not expected:
        return None
    found = _findings(diag)
    return any(matches(f, e) for f in found for e in expected)


def honest(diag: dict[str, Any], left_out: bool) -> bool | None:
    """A case whose cause no candidate can name (``left_out``) must not be *explained*; None
    for a case whose class is among the candidates."""
    if not left_out:
        return None
    return (diag.get("verdict") or {}).get("outcome") != "explained"
