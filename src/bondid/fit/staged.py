"""Staged fitting (the seed report's recommendation): bands first, then everything together.

Stages, each a bounded fit of a subset of the free parameters on a subset of the frequencies,
each starting where the previous one ended:

1. ``stiffness`` — the joint springs, below the first parasitic resonance (where the
   response is quasi-static in the parasitic joints, so springs dominate it);
2. ``damping`` — the joint dampers, in narrow bands around the resonances (damping only
   matters near a resonance);
3. ``inertia`` — masses, centres of mass and inertia tensors, from the first parasitic
   resonance up (resonance positions and the mass line above them);
4. ``all`` — every free parameter on all the selected frequencies, from the staged point.

A stage with no free parameter of its kind, or whose bands hold no data, is skipped. Bands come
from the modes of the linearised model (eigenvalues λ of its state matrix, ``f = |λ|/2π``, the
underdamped ones) at the first data set's operating point, or from the user. A resonance is
*parasitic* when most of its modal strain energy sits in springs of joints without a
transmission; if the model has none, the lowest resonance is used.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..cost.problem import CostOptions, FrfProblem
from ..data.measurement import FrfData
from ..exceptions import ConfigError
from ..linear.affine import build_affine_model
from ..linear.parameter_map import ParameterMap
from ..model.document import UrdfDocument
from ..model.parameters import get_parameters, parameter_infos
from .solver import PRESOLVE_ITER
from .study import STAGES

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .result import FitResult

Band = tuple[float, float]
#: Half-width of a damping band around a resonance, as a frequency ratio.
DAMPING_BAND_RATIO = 1.25
#: The stiffness band ends this factor below the first parasitic resonance.
STIFFNESS_BAND_MARGIN = 1.5
#: A band stage is a rough pre-fit: it gets a quarter of ``max_iter`` (at least this many).
STAGE_MIN_ITER = 20
_STAGE_KINDS = {
    "stiffness": ("stiffness",),
    "damping": ("damping",),
    "inertia": ("mass", "com", "inertia"),
}


@dataclass
class Mode:
    """A resonance of the linearised model: ``f_hz = |λ|/2π``, ``zeta = −Re λ/|λ|``;
    ``parasitic`` when most of its spring energy is in joints without a transmission."""

    f_hz: float
    zeta: float
    parasitic: bool


@dataclass
class StageResult:
    """One stage: its name, bands (Hz), free parameters and fit result (None if skipped)."""

    name: str
    bands: list[Band]
    names: list[str]
    result: FitResult | None
    skipped: str | None = None

    def to_json_dict(self) -> dict:
        r = self.result
        return {
            "name": self.name,
            "bands_hz": [list(b) for b in self.bands],
            "parameters": list(self.names),
            "skipped": self.skipped,
            "status": None if r is None else r.status,
            "cost_initial": None if r is None else float(r.cost_initial),
            "cost_final": None if r is None else float(r.cost_final),
            "iterations": None if r is None else int(r.iterations),
            "wall_s": None if r is None else float(r.wall_s),
        }


@dataclass
class StagedResult:
    """The final fit (``result``, reported from the original start) and every stage."""

    result: FitResult
    stages: list[StageResult]


def model_modes(
    doc: UrdfDocument, operating_point: Mapping[str, float] | None = None
) -> list[Mode]:
    """The underdamped modes of ``doc`` at ``operating_point``, lowest first.

    Eigenvalues of the state matrix ``A`` (2nv × 2nv) of the linear model; rigid-body and
    overdamped (real) eigenvalues are left out.
    """
    am = build_affine_model(doc, operating_point)
    lm = am.linear_model()
    A = lm.state_space()[0]
    lam, vec = np.linalg.eig(A)
    nv = lm.nv
    driven = {t.joint for t in doc.transmissions}
    k = np.asarray(am.stiffness, dtype=float)
    para = np.array([d not in driven for d in am.dofs])
    modes: list[Mode] = []
    for i in np.flatnonzero(lam.imag > 1e-9 * np.maximum(1.0, np.abs(lam))):
        phi = vec[:nv, i]
        e = k * np.abs(phi) ** 2  # strain energy per joint spring
        total = float(e.sum())
        parasitic = bool(total > 0 and e[para].sum() > 0.5 * total)
        w = float(abs(lam[i]))
        modes.append(Mode(w / (2 * np.pi), float(-lam[i].real / w), parasitic))
    return sorted(modes, key=lambda m: m.f_hz)


def _merge(bands: list[Band]) -> list[Band]:
    out: list[Band] = []
    for lo, hi in sorted(bands):
        if out and lo <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def _clip(bands: Sequence[Band], limits: Sequence[Band] | None) -> list[Band]:
    """Intersect ``bands`` with the user's ``limits`` (None = no limit)."""
    if not limits:
        return _merge(list(bands))
    out = []
    for lo, hi in bands:
        for a, b in limits:
            c, d = max(lo, a), min(hi, b)
            if c < d:
                out.append((c, d))
    return _merge(out)


def automatic_stage_bands(
    modes: Sequence[Mode], f_min: float, f_max: float
) -> dict[str, list[Band]]:
    """Stage bands (Hz) from the model's modes within the data range ``[f_min, f_max]``.

    ``stiffness``: ``[f_min, f_p / 1.5]``, ``damping``: ``[f/1.25, f·1.25]`` around every
    resonance, ``inertia``: ``[f_p, f_max]``, where ``f_p`` is the first parasitic resonance
    (the lowest resonance if none is parasitic). Stages without a usable band are absent.
    """
    inside = [m for m in modes if f_min <= m.f_hz <= f_max]
    out: dict[str, list[Band]] = {}
    para = [m for m in inside if m.parasitic] or inside
    if not para:
        return out
    fp = para[0].f_hz
    if fp / STIFFNESS_BAND_MARGIN > f_min:
        out["stiffness"] = [(f_min, fp / STIFFNESS_BAND_MARGIN)]
    out["damping"] = _merge(
        [(m.f_hz / DAMPING_BAND_RATIO, m.f_hz * DAMPING_BAND_RATIO) for m in inside]
    )
    out["inertia"] = [(fp, f_max)]
    return out


def cost_at(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    names: Sequence[str],
    x: np.ndarray,
    options: CostOptions | None = None,
) -> float:
    """The fit cost ``‖r‖²`` of :class:`~bondid.cost.FrfProblem` at parameter values ``x``."""
    problem = FrfProblem(doc, datasets, options)
    pmap = ParameterMap(doc, problem.affines[0], names)
    # ParameterModel declares `size` as a plain attribute; ParameterMap has a property
    return problem.cost(pmap, np.asarray(x, dtype=float))


def staged_fit(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    names: Sequence[str],
    *,
    lower: np.ndarray,
    upper: np.ndarray,
    options: CostOptions | None = None,
    start: np.ndarray | None = None,
    max_iter: int = 200,
    stage_bands: Mapping[str, Sequence[Band]] | None = None,
    progress: Callable[[int, float], None] | None = None,
    on_stage: Callable[[StageResult], None] | None = None,
    presolve_iter: int = PRESOLVE_ITER,
) -> StagedResult:
    """Fit in stages (see the module docstring), then all parameters together.

    Args:
        doc: the model (not modified); ``start`` (``(p,)``) overrides its values of ``names``.
        datasets: measured FRFs.
        names: all free parameters, length ``p``.
        lower, upper: their bounds, ``(p,)`` each (a stage uses its parameters' slice).
        options: cost options; the user's bands limit every stage's bands.
        max_iter: IPOPT iteration limit of the final stage; each band stage gets a quarter of
            it (at least :data:`STAGE_MIN_ITER`): it only prepares the start of the final one.
        stage_bands: bands (Hz) per stage name (``stiffness``, ``damping``, ``inertia``);
            a stage missing here takes its bands from the modes.
        progress: per-iteration callback ``(iteration, cost)`` passed to every stage.
        on_stage: called after each stage.
        presolve_iter: normalised-complex presolve iterations of the final fit (band stages
            have none).

    Returns:
        :class:`StagedResult`: ``result`` is the final all-parameter fit, with ``initial``,
        ``cost_initial``, ``iterations`` and ``wall_s`` covering the whole staged run.
    """

    t0 = time.perf_counter()
    opts = options or CostOptions()
    names = list(names)
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    x = get_parameters(doc, names) if start is None else np.asarray(start, dtype=float).copy()
    x_start = x.copy()
    user = dict(stage_bands or {})
    for key in user:
        if key not in STAGES:
            raise ConfigError(f"staged fit: unknown stage {key!r}; valid: {', '.join(STAGES)}")
    f_min = min(float(ds.freq_hz.min()) for ds in datasets)
    f_max = max(float(ds.freq_hz.max()) for ds in datasets)
    auto: dict[str, list[Band]] = {}
    if any(s not in user for s in STAGES):
        auto = automatic_stage_bands(model_modes(doc, datasets[0].operating_point), f_min, f_max)
    kinds = {p.name: p.kind for p in parameter_infos(doc)}
    stage_iter = min(max_iter, max(STAGE_MIN_ITER, max_iter // 4))
    current = doc
    stages: list[StageResult] = []
    iterations = 0
    for stage in STAGES:
        idx = [i for i, n in enumerate(names) if kinds[n] in _STAGE_KINDS[stage]]
        bands = _clip(user.get(stage, auto.get(stage, [])), opts.bands)
        sub = [names[i] for i in idx]
        skip = None
        if not idx:
            skip = "no free parameter of this kind"
        elif not bands:
            skip = "no band within the data and the selected bands"
        res = None
        if skip is None:
            res, skip = stage_fit(
                current, datasets, sub, dataclasses.replace(opts, bands=bands), lo[idx],
                hi[idx], x[idx], stage_iter, progress,
            )  # fmt: skip
        if res is not None:
            x[idx] = res.fitted
            current = res.document
            iterations += int(res.iterations)
        st = StageResult(stage, bands, sub, res, skip)
        stages.append(st)
        if on_stage is not None:
            on_stage(st)
    return finish_stages(
        doc, current, datasets, names, opts, lo, hi, x_start, x, max_iter, progress,
        presolve_iter, stages, on_stage, iterations, t0, (f_min, f_max),
    )  # fmt: skip


def stage_fit(
    current: UrdfDocument,
    datasets: Sequence[FrfData],
    names: list[str],
    options: CostOptions,
    lower: np.ndarray,
    upper: np.ndarray,
    start: np.ndarray,
    max_iter: int,
    progress: Callable[[int, float], None] | None,
) -> tuple[FitResult | None, str | None]:
    """One preparatory stage (no presolve): ``(result, None)``, or ``(None, reason)`` when its
    bands hold no data. Other errors propagate."""
    from .solver import fit

    try:
        res = fit(
            current, list(datasets), names, options=options, lower=lower, upper=upper,
            start=start, max_iter=max_iter, progress=progress, presolve_iter=0,
        )  # fmt: skip
    except ConfigError as exc:
        if "no data" not in str(exc):
            raise
        return None, f"no data: {exc}"
    return res, None


def finish_stages(
    doc: UrdfDocument,
    current: UrdfDocument,
    datasets: Sequence[FrfData],
    names: list[str],
    options: CostOptions,
    lower: np.ndarray,
    upper: np.ndarray,
    x_start: np.ndarray,
    x: np.ndarray,
    max_iter: int,
    progress: Callable[[int, float], None] | None,
    presolve_iter: int,
    stages: list[StageResult],
    on_stage: Callable[[StageResult], None] | None,
    iterations: int,
    t0: float,
    span: Band,
) -> StagedResult:
    """The final all-parameter fit from the stages' point ``x`` (``current``), appended as
    stage ``all``; the result reports the whole run from ``x_start`` on ``doc`` (iterations
    of every stage, wall time since ``t0``). ``span``: the data's band (Hz) when the user
    selected none."""
    from .solver import fit

    final = fit(
        current, list(datasets), names, options=options, lower=lower, upper=upper, start=x,
        max_iter=max_iter, progress=progress, presolve_iter=presolve_iter,
    )  # fmt: skip
    last = StageResult("all", list(options.bands or [span]), names, final)
    stages.append(last)
    if on_stage is not None:
        on_stage(last)
    overall = dataclasses.replace(
        final,
        initial=x_start,
        cost_initial=cost_at(doc, datasets, names, x_start, options),
        iterations=iterations + int(final.iterations),
        wall_s=time.perf_counter() - t0,
    )
    return StagedResult(overall, stages)
