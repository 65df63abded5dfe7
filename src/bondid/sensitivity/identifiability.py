"""Identifiability: which parameters (and combinations) the data can determine.

From the relative Jacobian ``J = ∂r/∂ε`` (columns in units of each parameter's nominal value,
see :mod:`bondid.sensitivity._common`) and the noise ``s`` of one scaled residual entry, the
Fisher information is ``F = JᵀJ / s²`` and the expected (Cramér–Rao, Gauss–Newton) standard
deviation of the freed parameters is ``s·sqrt(diag((J_Sᵀ J_S)⁻¹))`` — relative to the nominal
value (for a parameter with nominal 0: in units of its reference magnitude).

* The singular values ``σ_k`` of ``J`` with right singular vectors ``v_k``: along ``v_k`` the
  data determine the relative parameter change with std ``s/σ_k``. Directions with
  ``s/σ_k ≤ max_rel_std`` are *pinned down*; the others are not.
* The recommended subset: columns in the order of a QR factorisation with column pivoting
  (``scipy.linalg.qr(J, pivoting=True)``: most informative and least redundant first); each
  is added when the subset then still has every expected relative std ``≤ max_rel_std``.
* The noise ``s`` is estimated from the data unless given: the robust (median-based) standard
  deviation of second differences along frequency of the nominal residual of each channel,
  divided by √6 (smooth model error cancels in second differences, white noise does not).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..cost import CostOptions
from ..data.measurement import FrfData
from ..exceptions import ConfigError
from ..model.document import UrdfDocument
from ._common import Setup, make_setup
from .local import Linearisation, linearise_cost

#: A singular value below this fraction of the largest counts as zero (rank deficiency).
RANK_RTOL = 1e-10


@dataclass
class Combination:
    """A right singular direction: ``sigma`` (singular value), expected relative ``std``
    along it, ``pinned`` (std ≤ threshold) and its dominant ``terms`` ``{name: weight}``."""

    sigma: float
    std: float
    pinned: bool
    terms: dict[str, float]

    @property
    def label(self) -> str:
        return " ".join(f"{w:+.2f}·{n}" for n, w in self.terms.items())


@dataclass
class Identifiability:
    """Result of :func:`analyse_identifiability`.

    Attributes:
        names: candidate parameters ``(n_p,)``; scale: their relative units ``(n_p,)``.
        noise: noise std of one scaled residual entry ``s``; noise_residual: the same in
            residual units per real part (dB for ``complex_log``); noise_estimated: True if
            taken from the data.
        singular_values: of the relative Jacobian, descending ``(n_p,)``.
        vt: right singular vectors as rows ``(n_p, n_p)``.
        combinations: one :class:`Combination` per singular value.
        n_identifiable: how many combinations are pinned down.
        std_alone: expected relative std of each parameter freed alone ``(n_p,)``.
        std_all: expected relative std with every candidate freed ``(n_p,)`` (inf if singular).
        pivot_order: QR column-pivoting order (indices into ``names``).
        subset: recommended names (candidate order); subset_std: their relative stds.
        max_rel_std: the threshold used.
    """

    names: tuple[str, ...]
    scale: np.ndarray
    noise: float
    noise_residual: float
    noise_estimated: bool
    singular_values: np.ndarray
    vt: np.ndarray
    combinations: list[Combination]
    n_identifiable: int
    std_alone: np.ndarray
    std_all: np.ndarray
    pivot_order: np.ndarray
    subset: list[str]
    subset_std: dict[str, float]
    max_rel_std: float


def estimate_noise(setup: Setup, residual: np.ndarray) -> float:
    """Noise std of one scaled residual entry from second differences along frequency.

    Args:
        setup: the labels of the residual entries.
        residual: scaled residual at the nominal parameters ``(n_r,)``.

    Returns:
        ``s ≥ 0`` (0 for data that the model matches exactly).
    """
    k = setup.parts
    part = np.zeros(residual.size, dtype=int)
    for d in np.unique(setup.dataset):
        idx = np.flatnonzero(setup.dataset == d)
        part[idx] = np.arange(idx.size) * k // idx.size
    diffs = []
    for d in np.unique(setup.dataset):
        for ch in np.unique(setup.channel[setup.dataset == d]):
            for p in range(k):
                idx = np.flatnonzero((setup.dataset == d) & (setup.channel == ch) & (part == p))
                if idx.size < 3:
                    continue
                idx = idx[np.argsort(setup.freq_hz[idx], kind="stable")]
                diffs.append(np.diff(residual[idx], 2))
    if not diffs:
        return 0.0
    dd = np.concatenate(diffs)
    return float(1.4826 * np.median(np.abs(dd)) / np.sqrt(6.0))


def _subset_std(R: np.ndarray, cols: Sequence[int], s: float) -> np.ndarray:
    """Relative stds ``(len(cols),)`` of the parameters ``cols`` freed together."""
    A = R[:, list(cols)]
    sv, vt = np.linalg.svd(A, full_matrices=False)[1:]
    if sv.size == 0:
        return np.zeros(0)
    if sv[-1] <= RANK_RTOL * max(sv[0], np.finfo(float).tiny):
        return np.full(len(cols), np.inf)
    return np.asarray(s * np.sqrt(np.sum((vt / sv[:, None]) ** 2, axis=0)))


def _terms(v: np.ndarray, names: Sequence[str], cover: float = 0.8, most: int = 4) -> dict:
    order = np.argsort(-np.abs(v), kind="stable")
    out: dict[str, float] = {}
    acc = 0.0
    for i in order[:most]:
        out[names[i]] = round(float(v[i]), 3)
        acc += float(v[i] ** 2)
        if acc >= cover:
            break
    return out


def analyse_identifiability(
    lin: Linearisation, *, max_rel_std: float = 0.1, noise: float | None = None
) -> Identifiability:
    """Identifiability from a :class:`Linearisation` (see the module docstring).

    Args:
        lin: nominal residual and relative Jacobian.
        max_rel_std: largest acceptable expected relative std (0.1 = 10 %).
        noise: noise std per real residual part in residual units (dB for ``complex_log``;
            relative complex noise ``rel`` gives about ``8.69·rel/√2`` dB); None = estimate.
    """
    if not max_rel_std > 0:
        raise ConfigError(f"max_rel_std {max_rel_std}: must be > 0")
    setup = lin.setup
    norm = 1.0 / np.sqrt(setup.total_weight)
    s, estimated = _noise_level(lin, noise, norm)
    import scipy.linalg

    J = lin.jacobian
    n_p = J.shape[1]
    # J = Q·Rt with a small (n_p × n_p) factor: the same Gram matrix JᵀJ = RtᵀRt. Pivoting the
    # small factor gives the pivots of J itself at a fraction of the cost of geqp3 on J.
    Rt = np.asarray(np.linalg.qr(J, mode="r"))
    R, piv = scipy.linalg.qr(Rt, mode="r", pivoting=True)
    sv, vt = np.linalg.svd(Rt, full_matrices=False)[1:]
    rank_tol = RANK_RTOL * max(float(sv[0]) if sv.size else 0.0, np.finfo(float).tiny)
    with np.errstate(divide="ignore"):
        comb_std = np.where(sv > rank_tol, s / np.where(sv > 0, sv, 1.0), np.inf)
    combos = [
        Combination(float(sv[k]), float(comb_std[k]), bool(comb_std[k] <= max_rel_std),
                    _terms(vt[k], setup.names))
        for k in range(sv.size)
    ]  # fmt: skip
    colnorm = np.linalg.norm(Rt, axis=0)
    with np.errstate(divide="ignore"):
        std_alone = np.where(colnorm > 0, s / np.where(colnorm > 0, colnorm, 1.0), np.inf)
    chosen_sorted = sorted(_greedy_subset(Rt, np.abs(np.diag(R)), piv, rank_tol, s, max_rel_std))
    sub_std = _subset_std(Rt, chosen_sorted, s)
    return Identifiability(
        names=setup.names,
        scale=setup.scale,
        noise=s,
        noise_residual=s / norm,
        noise_estimated=estimated,
        singular_values=sv,
        vt=vt,
        combinations=combos,
        n_identifiable=int(np.sum(comb_std <= max_rel_std)),
        std_alone=std_alone,
        std_all=_subset_std(Rt, list(range(n_p)), s),
        pivot_order=np.asarray(piv),
        subset=[setup.names[i] for i in chosen_sorted],
        subset_std={setup.names[i]: float(v) for i, v in zip(chosen_sorted, sub_std, strict=True)},
        max_rel_std=float(max_rel_std),
    )


def _noise_level(lin: Linearisation, noise: float | None, norm: float) -> tuple[float, bool]:
    """``(noise std in normalised residual units, whether it was estimated)``; ``noise`` is
    in residual units (None: estimate it from the nominal residual)."""
    if noise is None:
        return estimate_noise(lin.setup, lin.residual), True
    if not noise >= 0:
        raise ConfigError(f"noise {noise}: must be ≥ 0")
    return float(noise) * norm, False


def _greedy_subset(
    Rt: np.ndarray,
    diag: np.ndarray,
    piv: np.ndarray,
    rank_tol: float,
    s: float,
    max_rel_std: float,
) -> list[int]:
    """Columns taken in pivot order ``piv`` while each keeps every expected relative std of
    the subset within ``max_rel_std``; stops at the first pivot whose ``|R_kk|`` (``diag``)
    is at or below ``rank_tol``."""
    chosen: list[int] = []
    for pos, c in enumerate(piv):
        if diag[pos] <= rank_tol:
            break  # the remaining columns are (numerically) dependent on the chosen ones
        trial = [*chosen, int(c)]
        if np.all(_subset_std(Rt, trial, s) <= max_rel_std):
            chosen = trial
    return chosen


def identifiability(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    options: CostOptions | None = None,
    *,
    candidates: Sequence[str] = ("all",),
    max_rel_std: float = 0.1,
    noise: float | None = None,
) -> Identifiability:
    """Identifiability of ``candidates`` (names, globs, groups) at the URDF values.

    See :func:`analyse_identifiability` for ``max_rel_std`` and ``noise``. A token ``auto``
    among the candidates (as in ``--free auto``) stands for ``all``.
    """
    tokens = [t for c in candidates for t in c.replace(",", " ").split() if t != "auto"]
    setup = make_setup(doc, datasets, options, tokens or ["all"])
    return analyse_identifiability(linearise_cost(setup), max_rel_std=max_rel_std, noise=noise)


def recommend_subset(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    options: CostOptions | None = None,
    *,
    candidates: Sequence[str] = ("all",),
    max_rel_std: float = 0.1,
) -> list[str]:
    """The parameters to free (``--free auto``): a subset of ``candidates`` whose expected
    relative std from these data (noise estimated from them) is at most ``max_rel_std``.

    Args:
        doc: the model at its current (nominal) values.
        datasets: measured FRFs.
        options: cost options (bands, channels, residual kind); default CostOptions().
        candidates: names, glob patterns or groups to choose from.
        max_rel_std: threshold on each chosen parameter's expected relative std.

    Returns:
        Parameter names, a subset of the candidates, in model order.
    """
    return identifiability(
        doc, datasets, options, candidates=candidates, max_rel_std=max_rel_std
    ).subset
