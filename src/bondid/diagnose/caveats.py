"""What a kept effect's figures do not say: ``caveats`` of an effect in ``diagnosis.json``.

A kept effect passed the rule, yet two things can make its name or its values a weaker
statement than they look, and both can be read off the effect alone:

* **a parameter at the end of its range** (``at_bound``): the refit pushed a parameter onto
  one of the bounds its effect allows (a mount's mode at the lowest frequency it may have, a
  stiffness at its stiffest). The effect then reaches as far as the library lets it and
  stands in for something beyond: its value describes the data, not the machine;
* **one common factor on every channel** (``common_factor``): an FRF modifier that multiplies
  every entry of the FRF matrix by the same function of frequency. Measured FRFs cannot place
  such a factor: ``g(ω)·H`` is the same whether ``g`` sits in the drives (a lag in every
  amplifier), in the sensors or in the acquisition, so the side the effect's name gives is
  the library's choice, not the data's;
* **mixing on either side** (``either_side``): a mixing of the outputs ``(I + E) H`` and a
  mixing of the inputs ``H (I + F)`` give the same FRFs wherever ``E H = H F`` holds for one
  constant ``F`` over the band, as between two axes whose FRFs are in a constant ratio (two
  rigid-body axes below their first mode). Whether that holds is checked on the kept
  model's own FRF: the best constant mixing on the other side is fitted by least squares and
  reproduces the effect's change of the FRF to within :data:`SIDE_SHARE`. The data then do
  not say whether the sensors read across (misalignment) or the drives push across
  (cross-talk).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from ..data.measurement import channel_mask
from ..range_ends import range_end
from .effects import available
from .effects.base import Candidate

#: frequencies [Hz] at which a modifier's factor is compared across channels (any spread
#: of values: a factor common to every channel is common at every frequency)
PROBE_HZ = (3.0, 30.0, 300.0, 3000.0)
#: relative spread across channels below which a factor counts as common to all
COMMON_RTOL = 1e-9
#: the other side's best constant mixing leaves less than this share of the effect's change
#: of the FRF (in the fit's relative measure, on the channels the data inform): the sides
#: are one to the data
SIDE_SHARE = 0.1
#: a point's size in the relative measure is floored this far below its channel's RMS, so
#: that a cross channel's zero does not weigh without limit (60 dB: below any sensor's range)
REL_FLOOR = 1e-3
#: each data set's ``(outputs, inputs)``
Channels = Sequence[tuple[Sequence[str], Sequence[str]]]


@dataclass(frozen=True)
class Caveat:
    """One caveat of a kept effect.

    Attributes:
        kind: ``at_bound``, ``common_factor`` or ``either_side`` (module docstring).
        text: the caveat in words, for the summary and the report.
        parameter: the parameter at its bound (``at_bound``), else None.
        side: ``lower`` or ``upper`` (``at_bound``), else None.
    """

    kind: str
    text: str
    parameter: str | None = None
    side: str | None = None

    def as_dict(self) -> dict[str, str | None]:
        return asdict(self)


def at_bound(cand: Candidate, values: Sequence[float]) -> list[Caveat]:
    """The parameters of ``cand`` at ``values`` (SI, in the candidate's order) that sit on a
    bound of their range, one caveat each."""
    out = []
    for p, v in zip(cand.parameters, values, strict=True):
        # on a log scale for a positive parameter, the scale its refit moves it on
        side = range_end(float(v), p.lower, p.upper, log=not p.signed)
        if side is None:
            continue
        unit = "" if p.unit in ("", "1") else f" {p.unit}"
        out.append(Caveat(
            "at_bound",
            f"{p.name} = {v:.4g}{unit} is at the {side} end of the range this effect allows"
            f" ({p.lower:.4g}–{p.upper:.4g}{unit}): the effect stands in for something"
            " beyond it; its value describes the data, not the machine",
            parameter=p.name, side=side,
        ))  # fmt: skip
    return out


def is_common_factor(
    cand: Candidate, values: Sequence[float], outputs: Sequence[str], inputs: Sequence[str]
) -> bool:
    """Does the FRF-modifier ``cand`` at ``values`` multiply every entry of an
    ``(n_out, n_in)`` FRF by one common factor (no mixing; the same ``G`` in every entry at
    every probe frequency)? False for a structural candidate."""
    cls = available().get(cand.effect)
    if cls is None or not cls.is_modifier or not outputs or not inputs:
        return False
    effect = cls()
    theta = np.asarray(values, float)
    outs, ins = tuple(outputs), tuple(inputs)
    if effect.mixes and effect.mixing(cand, theta, outs, ins) is not None:
        return False
    G, _ = effect.modifier(cand, theta, np.asarray(PROBE_HZ, float), outs, ins)
    G = np.asarray(G).reshape(len(outs) * len(ins), len(PROBE_HZ))
    if np.allclose(G, 1.0, rtol=0.0, atol=COMMON_RTOL):
        return False  # the effect is absent at these values: nothing to place
    spread = np.abs(G - G[:1]).max(axis=0)
    return bool(np.all(spread <= COMMON_RTOL * np.abs(G[0]).clip(min=1e-300)))


def common_factor(cand: Candidate, values: Sequence[float], channels: Channels) -> list[Caveat]:
    """The ``common_factor`` caveat when ``cand`` at ``values`` is one factor on every
    channel of every data set (``channels``: each set's ``(outputs, inputs)``)."""
    if not channels or not all(is_common_factor(cand, values, o, i) for o, i in channels):
        return []
    return [Caveat(
        "common_factor",
        "it multiplies every channel by one common factor: to FRF data such a factor in the"
        " drives, in the sensors or in the acquisition looks the same, so the data do not"
        " say on which side it is",
    )]  # fmt: skip


def other_side_share(
    H: np.ndarray, M: np.ndarray, left: bool, used: np.ndarray | None = None
) -> float:
    """How much of a mixing's change of the FRF the other side's best constant mixing leaves.

    Args:
        H: the FRF with the mixing in, ``(n_out, n_in, n_freq)``, any quantity.
        M: the mixing, ``(n_out, n_out)`` on the outputs (``left``) or ``(n_in, n_in)`` on
            the inputs.
        left: the mixing acts on the outputs (``M H0``), else on the inputs (``H0 M``).
        used: ``(n_out, n_in)`` bool, the channels the data inform (None: all); a channel
            left out of the fit cannot tell the sides apart.

    Returns:
        ``‖H0 F − D‖ / ‖D‖`` (``D = H − H0`` the mixing's change, ``F`` the least-squares
        constant mixing on the other side) in the fit's relative measure: every point of a
        used channel weighed by ``1/|H|`` there, ``|H|`` floored :data:`REL_FLOOR` below the
        channel's RMS; 1.0 where the change is zero or nothing is used.
    """
    H = np.asarray(H, complex)
    if H.ndim != 3 or H.shape[2] == 0:
        return 1.0
    mask = np.ones(H.shape[:2], bool) if used is None else np.asarray(used, bool)
    Hf = np.moveaxis(H, 2, 0)  # (n_freq, n_out, n_in)
    if not left:  # H = H0 M is Hᵀ = Mᵀ H0ᵀ: an output mixing of the transposed FRF
        Hf, M, mask = Hf.transpose(0, 2, 1), M.T, mask.T
    H0 = np.linalg.solve(M, Hf)
    size_f = np.abs(Hf)
    rms = np.sqrt(np.mean(size_f**2, axis=0))
    floor = np.maximum(size_f, REL_FLOOR * rms[None])
    w = np.divide(1.0, floor, out=np.zeros_like(floor), where=(floor > 0.0) & mask[None])
    D = Hf - H0
    left_over = size = 0.0
    # column j of F is fitted on column j of D, every point weighed as the cost weighs it
    for j in range(Hf.shape[2]):
        A = (H0 * w[:, :, j, None]).reshape(-1, H0.shape[2])
        b = (D[:, :, j] * w[:, :, j]).reshape(-1)
        f, *_ = np.linalg.lstsq(A, b, rcond=None)
        left_over += float(np.linalg.norm(A @ f - b)) ** 2
        size += float(np.linalg.norm(b)) ** 2
    if not size > 0.0:
        return 1.0
    return math.sqrt(left_over / size)


def either_side(
    cand: Candidate, values: Sequence[float], channels: Channels,
    frfs: Sequence[np.ndarray] | None, used: Sequence[Collection[str]] | None = None,
) -> list[Caveat]:  # fmt: skip
    """The ``either_side`` caveat when the mixing ``cand`` at ``values`` is reproduced by a
    constant mixing on the other side in every data set (``frfs``: the kept model's FRF of
    each, ``(n_out, n_in, n_freq)``, in the order of ``channels``; ``used``: each data set's
    channels ``OUT.IN`` the fit used, None: all)."""
    cls = available().get(cand.effect)
    if cls is None or not cls.mixes or not frfs or len(frfs) != len(channels):
        return []
    effect, theta = cls(), np.asarray(values, float)
    shares: list[float] = []
    names = [None] * len(channels) if used is None else list(used)
    for (outs, ins), H, use in zip(channels, frfs, names, strict=True):
        mix = effect.mixing(cand, theta, tuple(outs), tuple(ins))
        if mix is None or np.shape(H)[:2] != (len(outs), len(ins)):
            return []
        left = mix.left is not None
        M = np.asarray(mix.left if left else mix.right, complex)
        if np.allclose(M, np.eye(len(M))):
            return []  # no mixing at these values: nothing to place
        try:
            mask = None if use is None else channel_mask(outs, ins, use)
            shares.append(other_side_share(np.asarray(H), M, left, mask))
        except np.linalg.LinAlgError:  # a singular mixing or FRF: nothing can be said
            return []
    if not shares or max(shares) >= SIDE_SHARE:
        return []
    other = "the drives pushing across" if left else "the sensors reading across"
    return [Caveat(
        "either_side",
        f"a constant mixing on the other side ({other}) reproduces its change of the FRF to"
        f" {100 * max(shares):.1f} %: between these channels the FRFs are in a constant"
        " ratio, so the data do not say on which side the mixing is",
    )]  # fmt: skip


def caveats(
    cand: Candidate,
    values: Mapping[str, float] | Sequence[float],
    channels: Channels,
    frfs: Sequence[np.ndarray] | None = None,
    used: Sequence[Collection[str]] | None = None,
) -> list[dict[str, str | None]]:
    """Every caveat of the kept effect ``cand`` at its fitted ``values`` (SI; a mapping in the
    candidate's parameter order, or a sequence), as ``diagnosis.json`` lists them;
    ``frfs``: the kept model's FRF of each data set, ``(n_out, n_in, n_freq)`` (None: the
    caveats that need it are not looked for); ``used``: each data set's channels ``OUT.IN``
    the fit used (None: all)."""
    vals = [float(v) for v in (values.values() if isinstance(values, Mapping) else values)]
    if len(vals) != len(cand.parameters):
        return []
    found = [*at_bound(cand, vals), *common_factor(cand, vals, channels),
             *either_side(cand, vals, channels, frfs, used)]  # fmt: skip
    return [c.as_dict() for c in found]
