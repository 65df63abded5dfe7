"""The damping model of a command: ``--damping`` and a study's ``damping`` key.

=================  ===========================================================================
``model``          (default) as the model is written: its joint dampers, and its
                   ``<rayleigh_damping>`` element if it has one (fitted only if ``--free``
                   names ``rayleigh.*`` or a group holding them)
``joints``         the joint dampers alone: a ``<rayleigh_damping>`` element is dropped
``rayleigh``       ``D = D_joints + α M + β K``: ``rayleigh.alpha`` and ``rayleigh.beta`` are
                   fitted; the joint dampers keep their values unless ``--free`` names them
                   (by name or glob: a group does not free them)
``rayleigh-only``  ``D = α M + β K``: the joint dampers are set to 0 and stay 0, ``α`` and
                   ``β`` fitted
``structural``     a structural loss factor: the stiffness is ``K (1 + jη)`` and every mode
                   of an elastic structure gets ``ζ = η/2``; the joint dampers are set to 0
                   and stay 0, ``α = β = 0`` held, ``rayleigh.eta`` fitted
=================  ===========================================================================

The start of ``α`` and ``β``, in this order: the values given (a study's ``[damping]`` table
``alpha``, ``beta``), the model's own ``<rayleigh_damping>``, else the least-squares fit of
``ζ_i = α/(2ω_i) + βω_i/2`` to the damping ratios the joint dampers give the model's modes in
the data's band (:func:`bondid.linear.rayleigh.rayleigh_start`). With ``rayleigh`` the joint
dampers stay, so that estimate is scaled by :data:`ADDITIVE_SHARE`: the start then damps a
little more than the model as written, not twice as much. The loss factor starts at the
value given (``[damping]`` ``eta``), the model's own, else twice the median damping ratio of
the model's modes in the band as written (its joint dampers and any ``α·M + β·K``:
:func:`bondid.linear.rayleigh.loss_start`). With ``model``, ``rayleigh`` and
``rayleigh-only`` a loss factor the model declares is kept (fitted only if ``--free`` names
``rayleigh.eta``); ``joints`` drops it with the element.
"""

from __future__ import annotations

import argparse
import fnmatch
from collections.abc import Mapping, Sequence
from typing import Any

from ..exceptions import ConfigError, ModelError
from ..model.document import UrdfDocument
from ..model.parameters import GROUPS, parameter_infos
from ..model.rayleigh import (
    LOSS_NAME,
    RAYLEIGH_NAMES,
    RAYLEIGH_UNITS,
    VISCOUS,
    Rayleigh,
    check_coefficient,
    drop_rayleigh,
    model_rayleigh,
    set_rayleigh,
)

DAMPING_KINDS = ("model", "joints", "rayleigh", "rayleigh-only", "structural")
#: the kinds that set the joint dampers to 0
WITHOUT_DAMPERS = ("rayleigh-only", "structural")
#: with ``--damping rayleigh`` (joint dampers kept), the share of the least-squares estimate
#: that α and β start from
ADDITIVE_SHARE = 0.1


def add_damping_arg(p: argparse.ArgumentParser) -> None:
    """``--damping KIND`` (:data:`DAMPING_KINDS`, module docstring)."""
    p.add_argument(
        "--damping", choices=DAMPING_KINDS, default=None,
        help="damping model: model (default: the model's joint dampers, and its"
        " <rayleigh_damping> if any), joints (dampers only), rayleigh (fit proportional"
        " damping α·M + β·K on top of the joint dampers, which stay as written unless --free"
        " names them), rayleigh-only (joint dampers set to 0, α and β fitted) or structural"
        " (joint dampers set to 0, a loss factor η fitted: stiffness K·(1 + jη), every mode"
        " of an elastic structure damped ζ = η/2)",
    )  # fmt: skip


def damping_from_study(value: Any, where: str) -> tuple[str, tuple[float, ...] | None]:
    """A study's ``damping`` key — ``"rayleigh"`` or a table ``{kind, alpha, beta}`` (``{kind =
    "structural", eta}``) — as ``(kind, start or None)``: the start is ``(α, β)`` or ``(η,)``;
    raises :class:`ConfigError` naming the key."""
    table = {"kind": value} if isinstance(value, str) else value
    if not isinstance(table, Mapping):
        raise ConfigError(
            f"{where}: damping: {value!r} is not a kind or a table {{kind, alpha, beta, eta}}"
        )
    unknown = sorted(set(table) - {"kind", *RAYLEIGH_UNITS})
    if unknown:
        raise ConfigError(
            f"{where}: damping.{unknown[0]}: unknown key; valid: kind, alpha, beta, eta"
        )
    kind = table.get("kind", "rayleigh")
    if kind not in DAMPING_KINDS:
        raise ConfigError(f"{where}: damping.kind {kind!r}; valid: {', '.join(DAMPING_KINDS)}")
    given = [c for c in VISCOUS if c in table]
    if given and len(given) != 2:
        raise ConfigError(f"{where}: damping: give both alpha (1/s) and beta (s), or neither")
    if given and kind not in ("rayleigh", "rayleigh-only"):
        raise ConfigError(
            f"{where}: damping: alpha and beta need kind rayleigh or rayleigh-only, not {kind!r}"
        )
    if "eta" in table:
        if kind != "structural":
            raise ConfigError(f"{where}: damping: eta needs kind structural, not {kind!r}")
        given = ["eta"]
    try:
        start = tuple(check_coefficient(table[c], c, f"{where}: damping") for c in given)
    except ModelError as exc:
        raise ConfigError(str(exc)) from None
    return str(kind), start or None


def declare_damping(
    doc: UrdfDocument,
    kind: str,
    *,
    start: tuple[float, ...] | None = None,
    band_hz: tuple[float, float] | None = None,
    operating_point: Mapping[str, float] | None = None,
) -> str | None:
    """Apply the damping model ``kind`` to ``doc`` (in place; module docstring).

    Args:
        doc: the model.
        kind: one of :data:`DAMPING_KINDS`.
        start: ``(α (1/s), β (s))`` to start from (``(η,)`` for ``structural``; else the
            model's or the estimate).
        band_hz: the data's band (Hz) whose modes the estimate uses (None = every mode).
        operating_point: the pose of the estimate's linearisation (default: neutral).

    Returns:
        How the coefficients start (for the summary and ``fit.json``), or None without them.
    """
    if kind not in DAMPING_KINDS:
        raise ConfigError(f"--damping {kind!r}; valid: {', '.join(DAMPING_KINDS)}")
    if kind == "joints":
        drop_rayleigh(doc)
    if kind in ("model", "joints"):
        return None
    if kind == "structural":
        return _declare_loss(doc, start, band_hz, operating_point)
    own = model_rayleigh(doc)
    if start is not None:
        value = Rayleigh(start[0], start[1], None if own is None else own.eta)
        how = "as given"
    elif own is not None:
        value, how = own, "the model's <rayleigh_damping>"
    else:
        from ..linear.affine import build_affine_model
        from ..linear.rayleigh import rayleigh_start

        est = rayleigh_start(build_affine_model(doc, operating_point or {}), band_hz)
        share = ADDITIVE_SHARE if kind == "rayleigh" and _has_dampers(doc) else 1.0
        value = Rayleigh(share * est.alpha, share * est.beta)
        how = est.how if share == 1.0 else f"{share:.0%} of the {est.how}"
    if kind == "rayleigh-only":
        _drop_dampers(doc)
    set_rayleigh(doc, value)
    return how


def _declare_loss(
    doc: UrdfDocument,
    start: tuple[float, ...] | None,
    band_hz: tuple[float, float] | None,
    operating_point: Mapping[str, float] | None,
) -> str:
    """``--damping structural`` on ``doc`` (in place): the loss factor's start (module
    docstring) estimated before the joint dampers it replaces are set to 0."""
    own = model_rayleigh(doc)
    if start is not None:
        eta, how = float(start[0]), "as given"
    elif own is not None and own.eta is not None:
        eta, how = own.eta, "the model's <rayleigh_damping>"
    else:
        from ..linear.affine import build_affine_model
        from ..linear.rayleigh import loss_start

        eta, how = loss_start(build_affine_model(doc, operating_point or {}), band_hz)
    _drop_dampers(doc)
    set_rayleigh(doc, Rayleigh(0.0, 0.0, eta))
    return how


def _drop_dampers(doc: UrdfDocument) -> None:
    for j in doc.movable_joint_names:
        doc.set_damping(j, 0.0)


def _has_dampers(doc: UrdfDocument) -> bool:
    return any(doc.damping(j) != 0.0 for j in doc.movable_joint_names)


def damping_free(
    doc: UrdfDocument, kind: str, free: Sequence[str], fixed: Sequence[str]
) -> tuple[list[str], list[str]]:
    """``(free, fixed)`` of a fit under the damping model ``kind``: with ``rayleigh`` and
    ``rayleigh-only`` the Rayleigh coefficients join ``free``, with ``structural`` the loss
    factor (α and β join ``fixed`` unless ``free`` names them); with ``rayleigh`` every joint
    damper that no name or glob of ``free`` matches (only a group) joins ``fixed``, with
    ``rayleigh-only`` and ``structural`` every joint damper (they stay 0)."""
    free, fixed = list(free), list(fixed)
    if kind not in ("rayleigh", *WITHOUT_DAMPERS):
        return free, fixed
    dampers = [p.name for p in parameter_infos(doc) if p.kind == "damping"]
    tokens = [t for item in free for t in item.replace(",", " ").split()]
    named = {d for t in tokens if t not in GROUPS for d in fnmatch.filter(dampers, t)}
    if kind in WITHOUT_DAMPERS:
        named = set()
    coefficients = [LOSS_NAME] if kind == "structural" else list(RAYLEIGH_NAMES)
    free += [n for n in coefficients if n not in tokens]
    fixed += [d for d in dampers if d not in named]
    if kind == "structural":  # α and β stay 0 unless named
        fixed += [n for n in RAYLEIGH_NAMES if n not in tokens]
    return free, fixed


def data_band(
    datasets: Sequence[Any], bands: Sequence[tuple[float, float]] | None = None
) -> tuple[float, float]:
    """The band (Hz) the data cover (``freq_hz`` of each), within the selected ``bands``."""
    lo = min(float(d.freq_hz.min()) for d in datasets)
    hi = max(float(d.freq_hz.max()) for d in datasets)
    if bands:
        lo, hi = max(lo, min(b[0] for b in bands)), min(hi, max(b[1] for b in bands))
    return lo, hi


def damping_json(kind: str, how: str | None, doc: UrdfDocument, result: Any) -> dict[str, Any]:
    """``fit.json``'s ``damping``: the damping model, how its coefficients started, and their
    values in the fitted model (``result``: the fit, its ``names`` and ``fitted``; null
    without proportional damping; ``eta`` null without a loss factor)."""
    own = model_rayleigh(doc)
    fitted = dict(zip(result.names, (float(v) for v in result.fitted), strict=True))
    values: dict[str, float | None] = {c: None for c in RAYLEIGH_UNITS}
    if own is not None:
        values = {c: fitted.get(f"rayleigh.{c}", own.get(c)) for c in own.components}
        values.setdefault("eta", None)
    return {"kind": kind, "start": how, **values}


def damping_line(damping: Mapping[str, Any] | None) -> str | None:
    """The summary's line on proportional damping (None without it)."""
    if not damping or damping.get("alpha") is None:
        return None
    start = f" started from {damping['start']}" if damping.get("start") else ""
    if damping["kind"] == "structural":
        eta = damping.get("eta") or 0.0
        return (
            f"damping (structural): stiffness K·(1 + jη), η = {eta:.6g} (ζ = {eta / 2:.3%} at"
            f" every mode of an elastic structure){';' + ' η' + start if start else ''}"
        )
    form = "α·M + β·K" if damping["kind"] == "rayleigh-only" else "joint dampers + α·M + β·K"
    line = f"damping ({damping['kind']}): {form}, α = {damping['alpha']:.6g} 1/s,"
    line += f" β = {damping['beta']:.6g} s"
    if damping.get("eta"):
        line += f", loss factor η = {damping['eta']:.6g}"
    return line + (f"; α, β{start}" if start else "")
