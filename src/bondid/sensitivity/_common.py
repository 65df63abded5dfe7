"""Shared set-up of the sensitivity analyses: the problem, the parameter map and the scales.

Every analysis of this package works in *relative* parameter units: a parameter ``p`` with
nominal value ``p0 ≠ 0`` is moved as ``p = p0·(1 + ε)``, so ``ε = 0.1`` is a 10 % change. A
parameter whose nominal value is exactly 0 has no relative scale; it gets a *reference
magnitude* instead (see :func:`reference_scales`), and ``ε`` is then measured in units of that
reference (an absolute range, reported as such).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..cost import CostOptions, FrfProblem
from ..cost.residuals import parts
from ..data.measurement import FrfData
from ..exceptions import ParameterError
from ..linear.parameter_map import RAYLEIGH_COMPONENTS, ParameterMap
from ..model.document import UrdfDocument
from ..model.parameters import link_inertial, parameter_infos, select_parameters

#: Aggregated parameter kinds: URDF kinds mass/com/inertia all count as ``inertial``.
KIND_GROUPS: tuple[str, ...] = ("stiffness", "damping", "inertial")


def kind_group(kind: str) -> str:
    """``mass``/``com``/``inertia`` → ``inertial``; ``stiffness``/``damping`` unchanged."""
    return "inertial" if kind in ("mass", "com", "inertia") else kind


@dataclass
class Setup:
    """A problem ready for sensitivity analysis.

    Attributes:
        problem: the cost (residual scaled so ``cost = ‖r‖²``).
        pmap: the named-parameter model, ``pmap.p0`` = URDF values ``(n_p,)``. (mypy: the
            cost's ``ParameterModel`` protocol declares ``size`` as a settable attribute while
            ``ParameterMap.size`` is a property, hence the ``type: ignore`` at the calls.)
        names: parameter names ``(n_p,)``; kinds: URDF kind per parameter.
        scale: relative unit per parameter ``(n_p,)``: ``p0`` (signed), or the (positive)
            reference magnitude where ``p0 = 0``; ``p = p0 + ε·scale``.
        zero_nominal: names whose nominal value is 0 (absolute scale, see module doc).
        dataset, channel, freq_hz: per residual entry ``(n_r,)`` (from ``residual_labels``).
        direction: per residual entry, the response (output) joint of its channel ``(n_r,)``.
        weight: per residual entry, the share of its frequency point in the cost ``(n_r,)``:
            ``Σ weight`` over a set of entries, divided by the residual parts per point
            (2 for complex kinds), is the denominator that turns ``Σ r²`` over that set into
            the set's own mean-square cost. Over all entries it equals 1.
        total_weight: ``Σ`` of the point weights (``1/total_weight`` is the square of the
            problem's residual normalisation: a raw residual of std σ per real part gives
            scaled entries of std ``σ/√total_weight``).
    """

    problem: FrfProblem
    pmap: ParameterMap
    names: tuple[str, ...]
    kinds: tuple[str, ...]
    scale: np.ndarray
    zero_nominal: tuple[str, ...]
    dataset: np.ndarray
    channel: np.ndarray
    freq_hz: np.ndarray
    direction: np.ndarray
    weight: np.ndarray
    total_weight: float

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def parts(self) -> int:
        return parts(self.problem.options.kind)

    def mean_square(self, r2: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """Mean-square cost of a subset of entries from squared residuals.

        Args:
            r2: squared (scaled) residuals ``(n_r, ...)``.
            mask: boolean ``(n_r,)``; None = every entry (then the result is ``Σ r2``).

        Returns:
            ``Σ_mask r2 / W_mask`` with shape ``r2.shape[1:]``; NaN when the subset is empty.
        """
        if mask is None:
            return np.asarray(r2.sum(axis=0))
        W = float(self.weight[mask].sum()) / self.parts
        if W <= 0:
            return np.full(r2.shape[1:], np.nan)
        return np.asarray(r2[mask].sum(axis=0) / W)


def entry_weights(problem: FrfProblem) -> np.ndarray:
    """Per residual entry: its point's weight over the total weight, ``(n_r,)``."""
    return problem.entry_weights()


def reference_scales(
    doc: UrdfDocument, pmap: ParameterMap, problem: FrfProblem
) -> tuple[np.ndarray, tuple[str, ...]]:
    """Relative unit of each parameter: ``p0``, or a reference magnitude where ``p0 = 0``.

    References for zero-valued parameters (so that one unit is a clearly visible change):

    * ``JOINT.stiffness``: ``M_jj·(2π f_lo)²``, the spring whose impedance equals the joint's
      own inertial impedance at the lowest used frequency ``f_lo`` (N/m or N·m/rad);
    * ``JOINT.damping``: ``M_jj·2π f_lo`` (same idea for a damper);
    * ``LINK.com.*``: 10 % of the link's RMS mass radius ``√(tr I_c / 2m)`` (m);
    * ``LINK.inertia.*``: 10 % of the link's mean principal moment (kg·m²);
    * ``LINK.mass``: 1 % of the heaviest moving link (kg);
    * ``rayleigh.alpha`` / ``.beta`` / ``.eta``: the model's reference coefficient
      (:func:`bondid.linear.rayleigh.reference`).

    Returns:
        ``(scale (n_p,), names of the zero-valued parameters)``.
    """
    infos = {p.name: p for p in parameter_infos(doc)}
    p0 = pmap.p0
    scale = np.array(p0, dtype=float)
    zero = []
    f_lo = problem.freq_range_hz[0]
    w_lo = 2.0 * np.pi * f_lo
    affine = problem.affines[0]
    M = affine.mass_matrix()
    for i, name in enumerate(pmap.names):
        if p0[i] != 0.0:
            continue
        zero.append(name)
        info = infos[name]
        if info.kind in ("stiffness", "damping"):
            mjj = float(M[affine.dofs.index(info.owner), affine.dofs.index(info.owner)])
            scale[i] = mjj * w_lo**2 if info.kind == "stiffness" else mjj * w_lo
        elif info.kind == "mass":
            scale[i] = 0.01 * max(float(pi[0]) for pi in affine.pi)
        elif info.kind == "rayleigh":
            from ..linear.rayleigh import reference

            scale[i] = reference(affine)[RAYLEIGH_COMPONENTS.index(str(info.component))]
        else:
            m, _, Ic = link_inertial(doc, info.owner)
            tr = float(np.trace(Ic))
            if info.kind == "com":
                scale[i] = 0.1 * np.sqrt(tr / (2.0 * m)) if m > 0 else 0.01
            else:
                scale[i] = 0.1 * tr / 3.0
        if not scale[i] > 0:
            scale[i] = 1.0
    return scale, tuple(zero)


def channel_output(channel: str) -> str:
    """The response joint of a channel ``OUT.IN``."""
    return channel.rpartition(".")[0]


def make_setup(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    options: CostOptions | None = None,
    free: Sequence[str] = ("all",),
    fixed: Sequence[str] = (),
) -> Setup:
    """Build the problem, the parameter map of ``free`` minus ``fixed`` (names, globs,
    groups; see :func:`bondid.model.select_parameters`) and the relative scales."""
    problem = FrfProblem(doc, datasets, options)
    names = select_parameters(doc, free, fixed)
    if not names:
        raise ParameterError(f"{doc.source or '<URDF>'}: no parameter selected (free minus fixed)")
    pmap = ParameterMap(doc, problem.affines[0], names)
    scale, zero = reference_scales(doc, pmap, problem)
    infos = {p.name: p for p in parameter_infos(doc)}
    ds_i, ch, fr = problem.residual_labels()
    direction = np.array([channel_output(str(c)) for c in ch])
    return Setup(
        problem=problem,
        pmap=pmap,
        names=tuple(names),
        kinds=tuple(infos[n].kind for n in names),
        scale=scale,
        zero_nominal=zero,
        dataset=ds_i,
        channel=ch,
        freq_hz=fr,
        direction=direction,
        weight=entry_weights(problem),
        total_weight=problem.total_weight,
    )


def label_masks(labels: np.ndarray) -> tuple[tuple[str, ...], np.ndarray]:
    """The distinct ``labels`` of the residuals (in order of first use) and, for each, the
    mask of its residuals, shape ``(n_labels, n_residuals)``."""
    names = tuple(dict.fromkeys(str(x) for x in labels))
    return names, np.array([labels == x for x in names]).reshape(len(names), -1)
