"""Which measured points a cost uses: :class:`CostOptions`, :func:`used_points` and the
public layout of one data set's selection (:class:`DataSelection`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..data.measurement import FrfData
from ..data.weights import information_weights
from ..exceptions import ChannelError
from ..linear.affine import AffineModel


@dataclass
class CostOptions:
    """How model and measurement are compared.

    Attributes:
        kind: residual kind (see :mod:`bondid.cost.residuals`), default ``complex_log``.
        norm: ``l2`` or ``l1`` (smooth pseudo-Huber, ``l1_delta`` in residual units).
        bands: frequency bands (Hz) to use; None = all.
        channels: ``OUT.IN`` names to use; None = every channel in the data.
        channels_by_file: per data file (its ``source``), the ``OUT.IN`` names used there;
            it wins over ``channels`` for that file (the information rule applied file by
            file, :func:`informative_only`).
        channel_weights: extra weight per channel (default 1: the log residuals already
            balance channels whose levels differ by 50 dB).
        use_coherence: False ignores the file's coherence column (``auto`` then weighs by
            the estimated noise alone, ``coherence`` becomes ``none``).
        weighting: the point weights (:mod:`bondid.data.weights`): ``auto`` (default: the
            coherence combined with the noise estimated from the data where the file has a
            coherence, the estimate alone otherwise), ``coherence``, ``estimated`` or
            ``none``. Weights are ``w = Ŝ/(Ŝ + N̂)`` in 0..1, the coherence analogue.
    """

    kind: str = "complex_log"
    norm: str = "l2"
    l1_delta: float = 1.0
    bands: Sequence[tuple[float, float]] | None = None
    channels: Sequence[str] | None = None
    channels_by_file: dict[str, tuple[str, ...]] | None = None
    channel_weights: dict[str, float] = field(default_factory=dict)
    use_coherence: bool = True
    weighting: str = "auto"

    @property
    def name(self) -> str:
        return f"{self.kind}_{self.norm}"

    def channels_for(self, ds: FrfData) -> Sequence[str] | None:
        """The channels used of data set ``ds`` (None = every one present)."""
        if self.channels_by_file and ds.source in self.channels_by_file:
            return self.channels_by_file[ds.source]
        return self.channels

    @property
    def effective_weighting(self) -> str:
        """The weighting applied, after ``use_coherence`` (see the class docstring)."""
        if self.use_coherence:
            return self.weighting
        return {"auto": "estimated", "coherence": "none"}.get(self.weighting, self.weighting)


@dataclass
class DataSelection:
    """The points of one data set a :class:`FrfProblem` uses (its public layout).

    ``n_sel`` selected points (channels × used frequencies with finite data), listed output
    channel, then input, then frequency; the model FRF ``H`` of this data set is
    ``(n_out, n_in_model, n_fu)`` on ``freq_hz`` and ``H[rows, cols, fidx]`` are the modelled
    values of the selected points.

    Attributes:
        data: the measured data set.
        affine: its linearisation (at ``data.operating_point``).
        freq_hz: the frequencies used ``(n_fu,)`` (Hz).
        rows: ``(n_sel,)`` output index into the data's and the model's outputs.
        cols: ``(n_sel,)`` input index into the model's inputs.
        fidx: ``(n_sel,)`` index into ``freq_hz``.
        flat: ``(n_sel,)`` index into the model FRF flattened ``(o, i, f)``; None = all.
        Hm: ``(n_sel,)`` measured values.
        weight: ``(n_sel,)`` point weights (unnormalised, 0…1 times channel weights).
        scale: ``(n_sel,)`` channel RMS magnitude (for ``linear_magnitude``).
        channel: ``(n_sel,)`` channel name ``OUT.IN`` per point.
    """

    data: FrfData
    affine: AffineModel
    freq_hz: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    fidx: np.ndarray
    flat: np.ndarray | None
    Hm: np.ndarray
    weight: np.ndarray
    scale: np.ndarray
    channel: np.ndarray


def used_points(ds: FrfData, options: CostOptions) -> np.ndarray:
    """Boolean ``(n_out, n_in, n_freq)``: the points of ``ds`` a fit with ``options`` uses
    (present channels among ``options.channels``, frequencies in ``options.bands``, finite).

    Raises:
        ChannelError: ``options.channels`` names a channel the data lack.
    """
    chosen = np.array(ds.present)
    names = options.channels_for(ds)
    if names is not None:
        wanted = set(names)
        unknown = wanted - {f"{o}.{i}" for o in ds.outputs for i in ds.inputs}
        if unknown:
            raise ChannelError(
                f"{ds.source or '<data>'}: --channels names {', '.join(sorted(unknown))}, not"
                f" in the data; valid: {', '.join(ds.channels)}"
            )
        for ka, o in enumerate(ds.outputs):
            for kb, i in enumerate(ds.inputs):
                chosen[ka, kb] &= f"{o}.{i}" in wanted
    fmask = np.ones(ds.freq_hz.size, bool)
    if options.bands:
        fmask = np.zeros(ds.freq_hz.size, bool)
        for lo, hi in options.bands:
            fmask |= (ds.freq_hz >= lo) & (ds.freq_hz <= hi)
    return chosen[:, :, None] & fmask[None, None, :] & np.isfinite(ds.H)


def select_points(ds: FrfData, affine: AffineModel, opt: CostOptions) -> DataSelection:
    """The points of ``ds`` a problem with options ``opt`` uses, with their weights and
    channel scales, against the linearisation ``affine`` (:class:`DataSelection`)."""
    col_of = [affine.inputs.index(i) for i in ds.inputs]
    sel = used_points(ds, opt)
    a, b, f = np.nonzero(sel)
    used = np.unique(f)
    fidx = np.searchsorted(used, f)
    Hm = ds.H[a, b, f]
    w = information_weights(ds, opt.effective_weighting)[a, b, f]
    names = np.array([f"{ds.outputs[i]}.{ds.inputs[j]}" for i, j in zip(a, b, strict=True)])
    for ch, cw in opt.channel_weights.items():
        w = np.where(names == ch, w * float(cw), w)
    scale = np.ones(a.size)
    for ch in np.unique(names):
        m = names == ch
        scale[m] = np.sqrt(np.mean(np.abs(Hm[m]) ** 2))
    cols = np.array(col_of, dtype=int)[b]
    n_o, n_i, n_f = len(affine.outputs), len(affine.inputs), used.size
    flat = (a * n_i + cols) * n_f + fidx
    whole = flat.size == n_o * n_i * n_f and np.array_equal(flat, np.arange(flat.size))
    return DataSelection(
        ds, affine, ds.freq_hz[used], a, cols, fidx, None if whole else flat, Hm, w, scale,
        names,
    )  # fmt: skip


def informative_only(
    datasets: Sequence[FrfData], options: CostOptions
) -> tuple[CostOptions, dict[str, dict[str, float]], str]:
    """``options`` limited, file by file, to the informative channels when it names none
    (:func:`bondid.data.weights.informative_channels` applied to each data file alone, so a
    channel informative at one operating point is used there), the channels left out per
    file ``{file: {channel: median information weight}}``, and a note on them ("" when none
    is). A file none of whose channels is informative keeps every one, and the note says
    so."""
    from ..data.weights import informative_by_file, left_out_note

    if options.channels is not None:
        return options, {}, ""
    by_file, left_out, notes = informative_by_file(datasets, options.effective_weighting)
    if not left_out:
        return options, {}, "; ".join(notes)
    union = tuple(dict.fromkeys(c for keep in by_file.values() for c in keep))
    note = "; ".join([left_out_note(left_out), *notes])
    return replace(options, channels=list(union), channels_by_file=by_file), left_out, note


def channels_by_file(
    datasets: Sequence[FrfData], options: CostOptions, left_out: dict[str, dict[str, float]]
) -> tuple[dict[str, float], list[dict[str, object]]]:
    """What a results file says of the channels: ``channels_left_out`` ``{channel: median
    information weight}`` (each channel left out of some file, with its largest median
    there) and ``channels_by_file`` ``[{"file", "used", "left_out"}]``, one entry a data
    set."""
    flat: dict[str, float] = {}
    for chans in left_out.values():
        for c, m in chans.items():
            flat[c] = max(m, flat.get(c, m))
    entries: list[dict[str, object]] = []
    for i, ds in enumerate(datasets):
        key = ds.source or f"data{i}"
        names = options.channels_for(ds)
        used = [c for c in ds.channels if names is None or c in names]
        entries.append({"file": key, "used": used, "left_out": dict(left_out.get(key, {}))})
    return flat, entries
