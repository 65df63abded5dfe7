"""The FRF fitting problem: residuals and their exact Jacobian over several data sets.

:class:`FrfProblem` ties a model, one or more measured data sets (each at its own operating
point, so one linearisation per pose) and the cost options together. Its decision vector ``x``
is whatever a *parameter model* (:class:`ParameterModel`) maps onto the physical values ``(π
(nb,10), k (nv,), d (nv,))`` with exact derivatives, and optionally onto free transducer gains
``gain.in.X`` / ``gain.out.Y`` (``H = g_out · H_model · g_in``) and the mixes of points with a
second component (:mod:`.mixing`) and the proportional damping's ``α``, ``β``
(``rayleigh_values``). Which points are used is decided by :mod:`bondid.cost.selection`.

The residual vector is scaled so that ``cost = ‖r‖²`` is the weighted mean square over the
selected complex points (for ``complex_log`` that is ``db_rms²``).
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from ..data.io import check_against_model
from ..data.measurement import FrfData
from ..data.weights import check_weighting
from ..exceptions import ConfigError
from ..frf.jacobian import frequency_spans
from ..linear.affine import AffineModel, build_affine_model, model_inputs, model_outputs
from ..linear.coupling import coupling_terms, recouple
from ..model.document import UrdfDocument
from ..threads import thread_limit, thread_map
from .mixing import mix_rows, mixed_affine
from .modifier import FrfModifier
from .residuals import (
    check_kind,
    db_rms,
    parts,
    residual,
)
from .rows import Derivatives, Gains, Rows, gain_arrays
from .selection import CostOptions, DataSelection, select_points, used_points

#: the former private name of :class:`DataSelection` (read by bondid.diagnose)
_Block = DataSelection

__all__ = ["CostOptions", "DataSelection", "FrfProblem", "ParameterModel", "db_rms", "used_points"]


#: selected points per data set from which the data sets are evaluated on parallel threads.
#: Measured on 2 cores: the bundled fit (18 000 points per set) took 6.6–7.9 s on
#: threads against 9.8–11.0 s in one; a diagnosis of 1 350 points per set 143 s against 116 s
#: (the per-call work there is mostly Python, which holds the GIL).
THREADED_MIN_POINTS = 5000


class ParameterModel(Protocol):
    """What :class:`FrfProblem` evaluates the model at: a map from a parameter vector ``x``
    ``(size,)`` to the values of every linearisation's affine model, with exact derivatives.

    Implemented by :class:`bondid.linear.parameter_map.ParameterMap` (named URDF parameters),
    :class:`bondid.optim.layout.Layout` (the fit's decision vector) and
    :class:`bondid.optim.tied.TiedParameters` (named parameters with ties). A model may also
    have transducer gains: ``gain_values(x) -> {name: g}`` and ``gain_jacobian(x) -> {name:
    dg/dx (size,)}`` (optional; without them the gains stay the model's), and proportional
    damping: ``rayleigh_values(x) -> (α, β, η) | None`` and ``rayleigh_jacobian(x) ->
    d(α, β, η)/dx (3, size)`` (optional; None or without them α, β and the loss factor η stay
    the model's), and mimic
    multipliers: ``coupling_values(x) -> {joint: a}`` and ``coupling_jacobian(x) -> {joint:
    da/dx (size,)}`` (optional; :mod:`bondid.linear.coupling`).
    """

    @property
    def size(self) -> int:
        """Length of the parameter vector ``x``."""
        ...

    def values(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(π (nb, 10), stiffness (nv,), damping (nv,))`` at ``x`` (SI units; π in
        Pinocchio's order ``m, m·c, I_o``)."""
        ...

    def jacobian(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(dπ/dx (nb, 10, size), dk/dx (nv, size), dd/dx (nv, size))`` at ``x``."""
        ...


_Values = tuple[np.ndarray, np.ndarray, np.ndarray]
_Gains = Gains


def _free_part(
    pmodel: ParameterModel, x: np.ndarray, part: str, jacobian: bool = False
) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """An optional part of the parameter-model protocol at ``x``: the free values by name
    (``{part}_values``: transducer gains, point mixes, mimic multipliers) and, when asked,
    their ``d/dx`` ``(size,)`` (``{part}_jacobian``); empty when the model has none."""
    fn = getattr(pmodel, f"{part}_values", None)
    values = dict(fn(x)) if fn is not None else {}
    if not values or not jacobian:
        return values, {}
    return values, dict(getattr(pmodel, f"{part}_jacobian")(x))


def _free_rayleigh(
    pmodel: ParameterModel, x: np.ndarray, jacobian: bool = False
) -> tuple[tuple[float, ...] | None, np.ndarray | None]:
    """``(α, β, η)`` of a parameter model with free proportional damping (else None) and,
    when asked, ``d(α, β, η)/dx`` ``(3, size)``."""
    fn = getattr(pmodel, "rayleigh_values", None)
    ab = fn(x) if fn is not None else None
    if ab is None or not jacobian:
        return ab, None
    return ab, np.asarray(pmodel.rayleigh_jacobian(x), dtype=float)  # type: ignore[attr-defined]


def _block_affine(
    b: DataSelection, values: _Values, gains: _Gains, rayleigh: tuple[float, ...] | None = None,
    couplings: dict[str, float] | None = None,
) -> AffineModel:  # fmt: skip
    affine = recouple(b.affine, couplings or {}).with_values(*values)
    if rayleigh is not None:
        affine = affine.with_rayleigh(*rayleigh)
    return affine.with_gains(*gain_arrays(affine, gains)) if gains else affine


class FrfProblem:
    """Residuals of a model against measured FRFs (one linearisation per data set).

    Args:
        doc: the model (its channels and, unless ``affines`` is given, its linearisations).
        datasets: measured FRFs (receptance), each at its operating point.
        options: cost options (default :class:`CostOptions`).
        affines: the linearisations, one per data set (default: built from ``doc``).
        modifier: an FRF modifier ``H ← G(ω; θ) ⊙ (L H R)`` (:mod:`bondid.cost.modifier`); θ comes
            from a parameter model with ``modifier_values(x)`` / ``modifier_jacobian(x)``
            (``(n_θ,)``, ``(n_θ, size)``), else it is held at :attr:`modifier_theta`.

    The residual (``(n_residuals,)``, ``cost = ‖r‖²``) holds ``parts(kind)`` real entries per
    selected point, data set after data set, each block ``(part, point)``-ordered; the points
    are described by :attr:`blocks` (:class:`DataSelection`), :meth:`residual_labels` and
    :meth:`entry_weights`.
    """

    def __init__(
        self,
        doc: UrdfDocument,
        datasets: Sequence[FrfData],
        options: CostOptions | None = None,
        *,
        affines: Sequence[AffineModel] | None = None,
        modifier: FrfModifier | None = None,
    ):
        self.doc = doc
        self.modifier = modifier
        #: the modifier's parameters used when the parameter model has none (``(n_θ,)``)
        self.modifier_theta = None if modifier is None else np.array(modifier.start, float)
        self.options = options or CostOptions()
        check_kind(self.options.kind, self.options.norm)
        check_weighting(self.options.weighting, "cost weighting")
        if not datasets:
            raise ConfigError("no measured data given")
        if affines is None:
            inputs, outputs = model_inputs(doc), model_outputs(doc)
            movable = doc.movable_joint_names
            for ds in datasets:
                check_against_model(ds, inputs=inputs, outputs=outputs, joints=movable)
            affines = [
                build_affine_model(doc, ds.operating_point, outputs=ds.outputs) for ds in datasets
            ]
        self.blocks: list[DataSelection] = [
            select_points(ds, a, self.options) for ds, a in zip(datasets, affines, strict=True)
        ]
        total = sum(float(b.weight.sum()) for b in self.blocks)
        if total <= 0:
            raise ConfigError("the selected channels and bands leave no data to fit")
        self._norm = 1.0 / np.sqrt(total)
        #: whether the data sets are evaluated on parallel threads (each large enough)
        self.threaded = min(b.Hm.size for b in self.blocks) >= THREADED_MIN_POINTS
        self._mix_rows: list | None = None  # per data set, built when a mix is free

    def _mixed(self, i: int, affine: AffineModel, mixes: dict[str, float]) -> AffineModel:
        """``affine`` (data set ``i``'s) with the free ``mixes`` of its points set."""
        if not mixes:
            return affine
        if self._mix_rows is None:
            self._mix_rows = [mix_rows(self.doc, b.affine) for b in self.blocks]
        return mixed_affine(affine, self._mix_rows[i], mixes)

    def _block_affines(
        self, values: _Values, gains: _Gains, ab: tuple[float, ...] | None,
        couplings: dict[str, float], mixes: dict[str, float],
    ) -> list[AffineModel]:  # fmt: skip
        """Every data set's linearisation at the given values (one per data set)."""
        return [self._mixed(i, _block_affine(b, values, gains, ab, couplings), mixes)
                for i, b in enumerate(self.blocks)]  # fmt: skip

    # -- the same linearisations, other selections or values ---------------------------------
    @property
    def datasets(self) -> list[FrfData]:
        """The measured data sets, one per linearisation (in order)."""
        return [b.data for b in self.blocks]

    def with_options(self, options: CostOptions) -> FrfProblem:
        """The same data and linearisations compared with other ``options`` (other bands,
        channels, residual kind or norm); nothing is linearised again."""
        out = FrfProblem(
            self.doc, self.datasets, options, affines=self.affines, modifier=self.modifier
        )
        out.modifier_theta = self.modifier_theta
        return out

    def moved(self, pmodel: ParameterModel, x: np.ndarray, doc: UrdfDocument) -> FrfProblem:
        """The same problem with every linearisation's parameter values set to ``pmodel``'s
        values at ``x`` (``doc``: the model document holding those values). The affine bases
        and the data selections are shared: nothing is linearised or selected again."""
        values, gains = pmodel.values(x), _free_part(pmodel, x, "gain")[0]
        mixes, ab = _free_part(pmodel, x, "mix")[0], _free_rayleigh(pmodel, x)[0]
        couplings = _free_part(pmodel, x, "coupling")[0]
        out = copy.copy(self)
        out.doc = doc
        out.modifier_theta = self._theta(pmodel, x)[0]
        affines = self._block_affines(values, gains, ab, couplings, mixes)
        out.blocks = [dataclasses.replace(b, affine=a)
                      for b, a in zip(self.blocks, affines, strict=True)]  # fmt: skip
        return out

    @property
    def affines(self) -> list[AffineModel]:
        """The linearisations, one per data set."""
        return [b.affine for b in self.blocks]

    @property
    def total_weight(self) -> float:
        """Sum of the point weights of every selected point (the cost's normaliser)."""
        return float(sum(float(b.weight.sum()) for b in self.blocks))

    @property
    def freq_range_hz(self) -> tuple[float, float]:
        """Lowest and highest frequency used (Hz)."""
        return (
            min(float(b.freq_hz.min()) for b in self.blocks),
            max(float(b.freq_hz.max()) for b in self.blocks),
        )

    def entry_weights(self) -> np.ndarray:
        """Per residual entry: its point's weight over :attr:`total_weight`, ``(n_r,)``."""
        k = parts(self.options.kind)
        return np.concatenate([np.tile(b.weight, k) for b in self.blocks]) / self.total_weight

    # -- evaluation -----------------------------------------------------------------------
    @property
    def n_residuals(self) -> int:
        return parts(self.options.kind) * sum(b.Hm.size for b in self.blocks)

    def used_frf(self, pmodel: ParameterModel, x: np.ndarray) -> list[np.ndarray]:
        """Model FRF at each data set's used frequencies, ``(n_out, n_in_model, n_fu)`` each
        (receptance; :func:`bondid.frf.aligned.model_frf` gives it in a data set's layout)."""
        values, gains = pmodel.values(x), _free_part(pmodel, x, "gain")[0]
        mixes, ab = _free_part(pmodel, x, "mix")[0], _free_rayleigh(pmodel, x)[0]
        theta = self._theta(pmodel, x)[0]
        couplings = _free_part(pmodel, x, "coupling")[0]

        tasks = self._tasks()
        affines = self._block_affines(values, gains, ab, couplings, mixes)

        def one(task: tuple[int, slice | None]) -> np.ndarray:
            i, span = task
            b = self.blocks[i]
            return affines[i].linear_model().frf(b.freq_hz if span is None else b.freq_hz[span])

        pieces = thread_map(one, tasks, parallel=self.threaded)
        out = []
        for i, b in enumerate(self.blocks):
            mine = [H for (j, _), H in zip(tasks, pieces, strict=True) if j == i]
            H = mine[0] if len(mine) == 1 else np.concatenate(mine, axis=2)
            if theta is not None:
                assert self.modifier is not None
                H = self.modifier.apply(theta, b.freq_hz, b.affine.outputs, b.affine.inputs, H)
            out.append(H)
        return out

    def _tasks(self, whole: bool = False) -> list[tuple[int, slice | None]]:
        """The (data set, frequency span) jobs of one evaluation, in order.

        Each data set is one job; when there are fewer data sets than threads (one dense
        file), each is cut into spans of whole frequency blocks of at least
        :data:`THREADED_MIN_POINTS` points, so that every core has work. ``whole``: one job
        per data set (a modifier that mixes channels needs the whole grid at once).
        """
        if whole or not self.threaded:
            return [(i, None) for i in range(len(self.blocks))]
        per_set = -(-thread_limit() // len(self.blocks))
        tasks: list[tuple[int, slice | None]] = []
        for i, b in enumerate(self.blocks):
            n = min(per_set, b.Hm.size // THREADED_MIN_POINTS)
            spans = frequency_spans(b.freq_hz.size, n) if n > 1 else [None]
            tasks += [(i, s) for s in spans]
        return tasks

    def _theta(
        self, pmodel: ParameterModel, x: np.ndarray
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The modifier's ``θ`` ``(n_θ,)`` and ``∂θ/∂x`` ``(n_θ, size)`` (None: no modifier;
        no derivative when θ is held)."""
        if self.modifier is None:
            return None, None
        values = getattr(pmodel, "modifier_values", None)
        jacobian = getattr(pmodel, "modifier_jacobian", None)
        if values is None or jacobian is None:
            return self.modifier_theta, None
        return np.asarray(values(x), float), np.asarray(jacobian(x), float)

    def _modifier_at(self, b: DataSelection, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        assert self.modifier is not None
        return self.modifier.at(theta, b.freq_hz, b.affine.outputs, b.affine.inputs)

    def phase_wall_fraction(
        self, pmodel: ParameterModel, x: np.ndarray, limit_rad: float = np.pi / 2
    ) -> float:
        """Share of the total weight on points where the model's phase differs from the
        measured one by more than ``limit_rad`` — where a log cost sits on the far side of a
        sign change (a wall a local method cannot cross). 0 … 1."""
        total = bad = 0.0
        for b, H in zip(self.blocks, self.used_frf(pmodel, x), strict=True):
            Hs = H[b.rows, b.cols, b.fidx]
            dphi = np.abs(np.angle(Hs * np.conj(b.Hm)))
            total += float(b.weight.sum())
            bad += float(b.weight[dphi > limit_rad].sum())
        return bad / total if total > 0 else 0.0

    def residual(self, pmodel: ParameterModel, x: np.ndarray) -> np.ndarray:
        """Scaled residual vector ``(n_residuals,)``; ``cost = ‖r‖²``."""
        rows = self._rows()

        def one(b: DataSelection, H: np.ndarray) -> np.ndarray:
            Hs = H[b.rows, b.cols, b.fidx]
            return rows.weighted(b, residual(self.options.kind, Hs, b.Hm, b.scale))[0]

        frfs = self.used_frf(pmodel, x)
        return np.concatenate([one(b, H) for b, H in zip(self.blocks, frfs, strict=True)])

    def residual_and_jacobian(
        self, pmodel: ParameterModel, x: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``(n_r,)`` and exact Jacobian ``(n_r, pmodel.size)``.

        The data sets (one linearisation each) are evaluated on parallel threads when each is
        large enough (:attr:`threaded`), each writing its rows of the result.
        """
        values = pmodel.values(x)
        gains, dgains = _free_part(pmodel, x, "gain", jacobian=True)
        rows = self._rows()
        mixes, dmixes = _free_part(pmodel, x, "mix", jacobian=True)
        ab, dab = _free_rayleigh(pmodel, x, jacobian=True)
        couplings, dcouplings = _free_part(pmodel, x, "coupling", jacobian=True)
        shared = (*pmodel.jacobian(x), dab)
        dpi = shared[0]
        theta, dtheta = self._theta(pmodel, x)
        n_p, k = dpi.shape[2], parts(self.options.kind)
        sizes = [k * b.Hm.size for b in self.blocks]
        start = np.concatenate([[0], np.cumsum(sizes)])
        r = np.empty(int(start[-1]))
        J = np.empty((int(start[-1]), n_p))

        mod = self.modifier
        mixing = theta is not None and mod is not None and mod.mixing is not None
        # each data set's model once, whatever number of frequency spans it is cut into
        affines = self._block_affines(values, gains, ab, couplings, mixes)
        terms = [coupling_terms(a, dcouplings) if dcouplings else None for a in affines]

        def one(task: tuple[int, slice | None]) -> None:
            i, span = task
            b = self.blocks[i]
            rb = r[start[i] : start[i + 1]]
            Jb = J[start[i] : start[i + 1]].reshape(k, b.Hm.size, n_p)
            affine = affines[i]
            derivatives: Derivatives = (*shared, terms[i])
            if b.flat is None and not gains and not mixes and theta is None:
                rows.grid(b, affine, derivatives, rb, Jb, span)
                return
            mix = (self._mix_rows[i], dmixes) if mixes and self._mix_rows is not None else None
            if mixing:
                assert theta is not None
                rows.mixed(b, affine, derivatives, (gains, dgains), mix, (theta, dtheta), rb, Jb)
                return
            G = None if theta is None else self._modifier_at(b, theta)
            rows.points(b, affine, derivatives, (gains, dgains), mix, (G, dtheta), rb, Jb, span)

        # the jobs write disjoint rows of r and J: their data set's, at their span's lines
        thread_map(one, self._tasks(whole=mixing), parallel=self.threaded)
        return r, J

    def _rows(self) -> Rows:
        """The writer of one data set's residual and Jacobian rows (:mod:`.rows`)."""
        return Rows(self.options, self._norm, self.modifier, self._modifier_at)

    def cost(self, pmodel: ParameterModel, x: np.ndarray) -> float:
        r = self.residual(pmodel, x)
        return float(r @ r)

    # -- labels for per-channel / per-band breakdowns -------------------------------------
    def residual_labels(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per residual entry: (data set index, channel name, frequency Hz), each ``(n_r,)``."""
        k = parts(self.options.kind)
        ds_i, ch, fr = [], [], []
        for i, b in enumerate(self.blocks):
            ds_i.append(np.tile(np.full(b.Hm.size, i), k))
            ch.append(np.tile(b.channel, k))
            fr.append(np.tile(b.freq_hz[b.fidx], k))
        return np.concatenate(ds_i), np.concatenate(ch), np.concatenate(fr)
