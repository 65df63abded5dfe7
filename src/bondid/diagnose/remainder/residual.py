"""The residual of a model against measured data, with each point's noise: :class:`Residual`.

A point is one frequency of one channel of one data set. Its log residual is

    e = ln(H_meas / H_model)         (complex, principal branch: phase in (−π, π])

in natural-log units (``(20/ln 10)·|e|`` is the spec's dB error; note the sign: ``e`` is what
the data have that the model lacks). Under measurement noise ``H_meas = H (1 + u)`` with
``u`` complex Gaussian of variance ``v = N/S``, an exact model leaves ``e = ln(1 + u)``,
whose mean square ``m = E|ln(1 + u)|²`` and the variance ``q`` of ``|e|²`` come from
:mod:`bondid.cost.noise_level`. Each point also has an information weight ``w = S/(S + N)``
in [0, 1] (the diagnosis' weights). Every figure of :mod:`bondid.diagnose.remainder` is
weighted by ``w``.

The noise's log error is not centred: ``E ln|1 + u| = ½ E₁(1/v)`` (``E₁`` the exponential
integral; ``E ln|z|² = ln|μ|² + E₁(|μ|²/σ²)`` for ``z`` complex Gaussian of mean ``μ``),
negligible at a good signal-to-noise ratio, ``½(ln v − γ)`` where the noise swamps the
signal: there the measured magnitude sits above the model's by that much whatever the model.
A finding fitted to such points would take this bias for a gain, a slope or a mode. So the
fits and tests work on the centred residual ``e − μ`` (``μ = ½ E₁(1/v)``) with the noise's
variance ``m − μ²``, and the excess of a set of points over the noise is
``Σ w (|e − μ|² − (m − μ²))``; the dB figures (``db_rms``, ``noise_db``) stay those of ``e``
and ``m``, as the diagnosis' gap and noise level.

Both data and model are held as receptances (a ratio of two FRFs of one quantity does not
depend on the quantity; the drive-point stiffness and mass need receptances).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ...data.measurement import FrfData, channel_mask
from ...data.quantity import convert_quantity
from ...exceptions import DataError


def log_ratio(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``ln(a/b)`` (principal branch), non-finite values as 0 (a few times faster than
    ``np.log`` of a complex array, which matters in the fits' inner loops)."""
    with np.errstate(all="ignore"):
        r = a / b
        out = np.log(np.abs(r)) + 1j * np.angle(r)
    return np.where(np.isfinite(out), out, 0.0)


@dataclass
class SetResidual:
    """One data set's points.

    Attributes:
        freq_hz: ``(n_f,)`` [Hz].
        outputs, inputs: row and column names.
        Hm: measured receptance ``(n_out, n_in, n_f)``.
        Hs: model receptance, same shape (the model the residual is taken against).
        w: information weight of each point, 0 where the point is not used.
        m: ``E|ln(1 + u)|²`` of each point's noise (natural-log units²), 0 where unused.
        q: ``Var|ln(1 + u)|²`` of each point's noise, 0 where unused.
        mu: ``E ln|1 + u|``, the noise's mean log error (real), 0 where unused.
    """

    freq_hz: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    Hm: np.ndarray
    Hs: np.ndarray
    w: np.ndarray
    m: np.ndarray
    q: np.ndarray
    mu: np.ndarray

    @property
    def used(self) -> np.ndarray:
        """Boolean ``(n_out, n_in, n_f)``: the points that count."""
        return self.w > 0

    def e(self, Hs: np.ndarray | None = None) -> np.ndarray:
        """``ln(H_meas / H)`` ``(n_out, n_in, n_f)`` for the model ``H`` (default ``Hs``),
        0 where the point is not used."""
        H = self.Hs if Hs is None else Hs
        used = self.used
        out = np.zeros(self.Hm.shape, complex)
        out[used] = log_ratio(self.Hm[used], H[used])
        return out

    def centred(self, Hs: np.ndarray | None = None) -> np.ndarray:
        """``e − μ`` (module docstring), 0 where unused."""
        return np.where(self.used, self.e(Hs) - self.mu, 0.0)

    @property
    def mc(self) -> np.ndarray:
        """The centred residual's noise variance ``m − μ²`` (≥ 0)."""
        return np.clip(self.m - self.mu**2, 0.0, None)


@dataclass
class Points:
    """A selection of points, flattened (each array ``(N,)``): data set ``k``, row ``a``,
    column ``b``, frequency index ``j``; ``s = jω`` [rad/s]; ``Hm``, ``Hs``, ``w`` as in
    :class:`SetResidual`; ``m`` the noise variance of the centred residual ``m − μ²`` and
    ``mu`` the noise's mean log error (the fits work on ``e − μ``, module docstring)."""

    k: np.ndarray
    a: np.ndarray
    b: np.ndarray
    j: np.ndarray
    s: np.ndarray
    Hm: np.ndarray
    Hs: np.ndarray
    w: np.ndarray
    m: np.ndarray
    mu: np.ndarray

    @property
    def size(self) -> int:
        return int(self.k.size)

    @property
    def f_hz(self) -> np.ndarray:
        return self.s.imag / (2 * np.pi)

    def e(self, H: np.ndarray | None = None) -> np.ndarray:
        """The centred residual ``ln(H_meas / H) − μ`` at the points (default ``H = Hs``)."""
        return log_ratio(self.Hm, self.Hs if H is None else H) - self.mu

    def sq(self, H: np.ndarray | None = None) -> float:
        """``Σ w |ln(H_meas / H) − μ|²`` over the points."""
        return float(np.sum(self.w * np.abs(self.e(H)) ** 2))

    def subset(self, keep: np.ndarray) -> Points:
        return Points(*(getattr(self, n)[keep] for n in _FIELDS))

    def thinned(self, most: int = 800) -> Points:
        """Every k-th point, at most ``most`` of them (for the grids that find a fit's start:
        a cost's shape over a grid shows on fewer points)."""
        step = max(1, -(-self.size // most))
        return self if step == 1 else self.subset(np.arange(0, self.size, step))

    def channel_keys(self) -> np.ndarray:
        """One integer per point naming its (data set, row, column)."""
        return (self.k * 10_000 + self.a) * 10_000 + self.b


_FIELDS = ("k", "a", "b", "j", "s", "Hm", "Hs", "w", "m", "mu")

#: a selection: ``select(k, set) -> bool (n_out, n_in, n_f)``, and-ed with the used points
Selector = Callable[[int, SetResidual], np.ndarray]


@dataclass
class Residual:
    """The points of every data set (:class:`SetResidual`) and the channels used."""

    sets: list[SetResidual]
    channels: list[str]

    @property
    def outputs(self) -> list[str]:
        """Output names over all data sets, first-seen order."""
        return _union(s.outputs for s in self.sets)

    @property
    def inputs(self) -> list[str]:
        return _union(s.inputs for s in self.sets)

    @property
    def weight(self) -> float:
        """``Σ w`` over every used point."""
        return float(sum(np.sum(s.w) for s in self.sets))

    def points(self, select: Selector | None = None) -> Points:
        """The used points where ``select`` holds (all used points by default)."""
        parts = []
        for k, st in enumerate(self.sets):
            mask = st.used if select is None else st.used & select(k, st)
            a, b, j = np.nonzero(mask)
            parts.append(
                (np.full(a.size, k), a, b, j, 2j * np.pi * st.freq_hz[j], st.Hm[a, b, j],
                 st.Hs[a, b, j], st.w[a, b, j], st.mc[a, b, j], st.mu[a, b, j])
            )  # fmt: skip
        return Points(*(np.concatenate([p[n] for p in parts]) for n in range(len(_FIELDS))))

    def with_model(self, Hs: Sequence[np.ndarray]) -> Residual:
        """The same points against another model ``Hs`` (one array per data set)."""
        sets = [
            SetResidual(s.freq_hz, s.outputs, s.inputs, s.Hm, H, s.w, s.m, s.q, s.mu)
            for s, H in zip(self.sets, Hs, strict=True)
        ]
        return Residual(sets, self.channels)

    def corrected(self, pts: Points, H_new: np.ndarray) -> list[np.ndarray]:
        """Every data set's model with ``H_new`` written at the points ``pts``."""
        out = [s.Hs.copy() for s in self.sets]
        for k, H in enumerate(out):
            sel = pts.k == k
            H[pts.a[sel], pts.b[sel], pts.j[sel]] = H_new[sel]
        return out

    def excess(self, select: Selector | None = None) -> float:
        """``Σ w (|e − μ|² − (m − μ²))`` over the used points where ``select`` holds
        (natural units)."""
        total = 0.0
        for k, st in enumerate(self.sets):
            mask = st.used if select is None else st.used & select(k, st)
            total += float(np.sum((st.w * (np.abs(st.centred()) ** 2 - st.mc))[mask]))
        return total


def _union(groups: object) -> list[str]:
    out: list[str] = []
    for g in groups:  # type: ignore[attr-defined]
        out += [n for n in g if n not in out]
    return out


def build_residual(
    data: Sequence[FrfData],
    model_H: Sequence[np.ndarray],
    channels: Sequence[str] | None = None,
    *,
    noise_to_signal: Sequence[np.ndarray] | None = None,
    weights: Sequence[np.ndarray] | None = None,
) -> Residual:
    """The residual of the model FRFs ``model_H`` against ``data``, with each point's noise.

    Args:
        data: measured data sets; ``coherence``, where given, is taken as the information
            weights ``w`` (as in the diagnosis).
        model_H: the model FRF of each data set, ``(n_out, n_in, n_f)`` complex, in the data
            set's quantity.
        channels: ``OUT.IN`` names to use (default every channel present in any data set).
        noise_to_signal: per data set, ``N/S`` of every point ``(n_out, n_in, n_f)`` (NaN
            where unknown: the point is left out); default ``1/w − 1`` where the weights come
            from the data's coherence, else the data's noise estimate
            (:func:`bondid.data.weights.noise_to_signal`, ``"auto"``, the basis of the
            weights: its level comes out 10–20 % high, a cautious reference for claims).
        weights: per data set, information weights ``(n_out, n_in, n_f)`` in [0, 1];
            default the coherence, else ``1/(1 + N/S)``.

    Returns:
        :class:`Residual` against the model.

    Raises:
        DataError: shapes differ, or no point is usable.
    """
    from scipy.special import exp1

    from ...cost.noise_level import expected_log_error, log_error_variance

    if not data or len(model_H) != len(data):
        raise DataError(
            f"describe_remainder: {len(data)} data set(s) but {len(model_H)} model FRF array(s)"
        )
    present: list[str] = _union(d.channels for d in data)
    use = list(channels) if channels is not None else present
    sets: list[SetResidual] = []
    for k, d in enumerate(data):
        where = d.source or f"data set {k + 1}"
        Hs = np.asarray(model_H[k], dtype=complex)
        if Hs.shape != d.H.shape:
            raise DataError(f"{where}: model FRF has shape {Hs.shape}, expected {d.H.shape}")
        v, w = _noise(d, k, noise_to_signal, weights)
        chan = channel_mask(d.outputs, d.inputs, use)
        Hm = convert_quantity(d.H, d.freq_hz, d.quantity, "receptance")
        Hr = convert_quantity(Hs, d.freq_hz, d.quantity, "receptance")
        with np.errstate(invalid="ignore"):
            ok = (
                chan[:, :, None] & np.isfinite(Hm) & np.isfinite(Hr) & (Hm != 0) & (Hr != 0)
                & np.isfinite(v) & np.isfinite(w) & (w > 0)
            )  # fmt: skip
        v0 = np.where(ok, v, 0.0)
        with np.errstate(divide="ignore"):
            mu = np.where(ok & (v0 > 0), 0.5 * exp1(1.0 / np.where(v0 > 0, v0, 1.0)), 0.0)
        sets.append(
            SetResidual(
                d.freq_hz.copy(), tuple(d.outputs), tuple(d.inputs), Hm, Hr,
                np.where(ok, np.clip(w, 0.0, 1.0), 0.0),
                np.where(ok, expected_log_error(v0), 0.0),
                np.where(ok, log_error_variance(v0), 0.0), mu,
            )
        )  # fmt: skip
    res = Residual(sets, use)
    if res.weight <= 0:
        raise DataError(
            "describe_remainder: no usable point (finite data and model, a known noise level "
            f"and a positive weight) in the channels {', '.join(use)}"
        )
    return res


def _noise(
    d: FrfData, k: int, ns: Sequence[np.ndarray] | None, ws: Sequence[np.ndarray] | None
) -> tuple[np.ndarray, np.ndarray]:
    """``(N/S, w)`` of data set ``d`` (number ``k``) by the rules of :func:`build_residual`."""
    from ...data.weights import noise_to_signal

    shape = d.H.shape
    w = None if ws is None else np.asarray(ws[k], dtype=float)
    v = None if ns is None else np.asarray(ns[k], dtype=float)
    if w is None and d.coherence is not None:
        w = np.where(np.isfinite(d.coherence), np.clip(d.coherence, 0.0, 1.0), np.nan)
    if v is None:
        if w is not None:
            with np.errstate(divide="ignore"):
                v = np.where(w > 0, 1.0 / np.where(w > 0, w, 1.0) - 1.0, np.inf)
        else:
            v = noise_to_signal(d, "auto", prediction=False)
    if w is None:
        w = 1.0 / (1.0 + v)
    for name, arr in (("noise_to_signal", v), ("weights", w)):
        if arr.shape != shape:
            raise DataError(
                f"{d.source or f'data set {k + 1}'}: {name} has shape {arr.shape}, expected {shape}"
            )
    return v, w
