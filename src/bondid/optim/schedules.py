"""The search strategies as schedules of :class:`~.search.Step` (run by
:func:`~.search.run_search`).

Direct (:func:`direct`): one step over everything, with the presolve of a log cost.

Staged (:func:`staged`): bands first, then everything
together. Each stage fits a subset of the free parameters on a subset of the frequencies:

1. ``stiffness`` — the joint springs, below the first parasitic resonance (where the
   response is quasi-static in the parasitic joints, so springs dominate it);
2. ``damping`` — the joint dampers, in narrow bands around the resonances;
3. ``inertia`` — masses, centres of mass and inertia tensors, from the first parasitic
   resonance up (resonance positions and the mass line above them);
4. ``all`` — every free parameter on all the selected frequencies, with the presolve.

A stage with no free parameter of its kind, or whose bands hold no data, is skipped; a band
stage gets a quarter of ``max_iter`` (at least :data:`STAGE_MIN_ITER`): it only prepares the
start of the last one. Bands come from the model's resonances at the first data set's operating
point, read from the problem's linearisation (:func:`bondid.modes.bands.resonances`,
:func:`~bondid.modes.bands.stage_bands`), or from the user, within the user's bands.

Band continuation (:func:`continuation`): a local fit of lightly damped modes from far away
(±30 % on every parameter) lands in the wrong basin when a model resonance has to move past a
measured one, or two modes have to swap order. Below the lowest resonance the response is a
smooth function of the parameters, and each widening of the band brings in only the next few
modes, by then close to their measured frequencies. So the continuation fits the band
``[f_min, f_1]``, then ``[f_min, f_2]``, ... ``[f_min, f_{n-1}]`` (``f_k`` evenly spaced in log
frequency from ``f_min·(f_max/f_min)^FIRST_BAND_SHARE`` towards ``f_max``), each a short fit on
the normalised complex error (bounded, smooth where a cross term changes sign) from where the
previous one ended, then all the selected frequencies with the user's cost and the presolve.
A parameter without an upper bound is capped in a band step at :data:`BAND_CAP` times its
current value; a band step whose solver fails, or that ends above its starting cost, is
recorded as skipped and the next starts from the same point.

Measured on the bonder (22 parameters: the 16 parasitic and 6 inertial ones, every one
started ±30 % off with random signs, noise-free data 1–4000 Hz at two poses): the direct fit
reached the truth (1e-6 relative) from 2 of 6 starts, the staged fit from 1 of 4, the
continuation (8 bands of 60 iterations) from all 18 starts tried (random-sign seeds 5–22), in
6–11 s each; with 8 bands of 30 iterations from 9 of 10, with 4 bands from 5 of 10. It is an
option, not the default: on the bundled measurements, whose model also has wrong fixed
parameters, it ended at a higher cost than the direct fit (57.07 vs 25.95 with the parasitic
parameters free).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..exceptions import ConfigError
from ..model.document import UrdfDocument
from ..modes.bands import Span, clip_spans, resonances, stage_bands
from .problem import FitProblem
from .search import PRESOLVE_ITER, PRESOLVE_KIND, Step

#: Stages of the staged fit, in the order they run.
STAGES = ("stiffness", "damping", "inertia")

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .multistart import Start

#: A band stage is a rough pre-fit: it gets a quarter of ``max_iter`` (at least this many).
STAGE_MIN_ITER = 20
_STAGE_KINDS = {
    "stiffness": ("stiffness", "multiplier"),
    "damping": ("damping", "rayleigh"),
    "inertia": ("mass", "com", "inertia"),
}
#: Number of bands (the last one is the full fit), the default of ``--continuation``.
CONTINUATION_BANDS = 8
#: IPOPT iterations of each band step (a band step only prepares the next one).
BAND_ITER = 60
#: The first band's upper edge, as a share of the data's log-frequency span.
FIRST_BAND_SHARE = 0.4
#: A band step caps a parameter with no upper bound at this multiple of its current value: a
#: spring whose mode lies above the band is not seen by it and would otherwise run off.
BAND_CAP = 4.0
#: relative width of the random starts of a fit without a prior (the prior's default width)
RANDOM_WIDTH = 0.25
#: the fit's loop over its starts may spend this many full searches' iterations in all
BUDGET = 6


def direct(presolve_iter: int = PRESOLVE_ITER) -> list[Step]:
    """One step over everything (``presolve_iter``: the presolve of a log cost, 0 = none)."""
    return [Step("all", presolve=presolve_iter)]


def staged(
    problem: FitProblem,
    stage_bands_hz: Mapping[str, Sequence[Span]] | None = None,
    *,
    max_iter: int = 200,
    presolve_iter: int = PRESOLVE_ITER,
) -> list[Step]:
    """The staged schedule (module docstring) for ``problem``.

    Args:
        problem: the fit problem (its names, data and bands).
        stage_bands_hz: bands (Hz) per stage name (``stiffness``, ``damping``, ``inertia``);
            a stage missing here takes its bands from the model's resonances.
        max_iter: the last step's iteration limit (band stages get a quarter of it).
        presolve_iter: the presolve of the last step.

    Raises:
        ConfigError: an unknown stage name.
    """
    user = dict(stage_bands_hz or {})
    for key in user:
        if key not in STAGES:
            raise ConfigError(f"staged fit: unknown stage {key!r}; valid: {', '.join(STAGES)}")
    f_min, f_max = problem.data_span_hz
    auto: dict[str, list[Span]] = {}
    if any(s not in user for s in STAGES):
        driven = {t.joint for t in problem.doc.transmissions}
        auto = stage_bands(resonances(problem.frf.affines[0], driven), f_min, f_max)
    stage_iter = min(max_iter, max(STAGE_MIN_ITER, max_iter // 4))
    steps = []
    for stage in STAGES:
        names = tuple(i.name for i in problem.infos if i.kind in _STAGE_KINDS[stage])
        bands = clip_spans(user.get(stage, auto.get(stage, [])), problem.options.bands)
        skip = None
        if not names:
            skip = "no free parameter of this kind"
        elif not bands:
            skip = "no band within the data and the selected bands"
        steps.append(Step(stage, names, bands, max_iter=stage_iter, skip=skip))
    return [*steps, Step("all", presolve=presolve_iter)]


def continuation_tops(f_min: float, f_max: float, n_bands: int) -> list[float]:
    """Upper edges (Hz) of the ``n_bands − 1`` band steps between ``f_min`` and ``f_max``."""
    if n_bands < 2:
        return []
    first = f_min * (f_max / f_min) ** FIRST_BAND_SHARE
    return [float(t) for t in np.geomspace(first, f_max, n_bands)[:-1]]


def _within(top: Span, user: Sequence[Span] | None) -> list[Span]:
    if not user:
        return [top]
    lo, hi = top
    return [(max(a, lo), min(b, hi)) for a, b in user if min(b, hi) > max(a, lo)]


def continuation(
    problem: FitProblem,
    n_bands: int = CONTINUATION_BANDS,
    *,
    band_iter: int = BAND_ITER,
    presolve_iter: int = PRESOLVE_ITER,
) -> list[Step]:
    """The band-continuation schedule (module docstring): ``n_bands − 1`` growing bands of
    ``band_iter`` iterations on the normalised complex error, then the full fit.

    Raises:
        ConfigError: ``n_bands < 2`` or ``band_iter < 1``.
    """
    if n_bands < 2 or band_iter < 1:
        raise ConfigError(
            f"band continuation: {n_bands} band(s) of {band_iter} iteration(s); valid: at "
            "least 2 bands (the last is the full fit) and at least 1 iteration"
        )
    f_min, f_max = problem.data_span_hz
    user = problem.options.bands
    if user:
        f_min = max(f_min, min(b[0] for b in user))
        f_max = min(f_max, max(b[1] for b in user))
    steps = []
    for top in continuation_tops(f_min, f_max, n_bands):
        bands = _within((f_min, top), user)
        skip = None if bands else "no band within the selected bands"
        steps.append(
            Step(
                f"up to {top:.4g} Hz", None, bands, kind=PRESOLVE_KIND, norm="l2",
                max_iter=band_iter, cap=BAND_CAP, keep_if_lower=True, skip=skip,
            )
        )  # fmt: skip
    return [*steps, Step("all", presolve=presolve_iter)]


@dataclass(frozen=True)
class Strategy:
    """Which schedule a search runs (what ``python -m bondid.fit``'s options choose).

    Attributes:
        staged: the staged schedule (with ``stage_bands``, Hz per stage name).
        continuation: the band continuation with this many bands (0 = off).
        presolve_iter: the presolve of the last step.
        max_iter: IPOPT iterations of the last step (band stages: see :func:`staged`).
        prior_width: relative width of the prior toward the model's values
            (:mod:`bondid.optim.prior`) in every step of every schedule; 0 = none.
        fallback: bands of the band continuation the fit's loop tries when a direct or
            staged search ends above the noise level (:meth:`starts`; 0 = no fallback
            schedule; a continuation strategy has none).
    """

    staged: bool = False
    continuation: int = 0
    stage_bands: Mapping[str, Sequence[Span]] | None = None
    presolve_iter: int = PRESOLVE_ITER
    max_iter: int = 200
    prior_width: float = 0.0
    fallback: int = CONTINUATION_BANDS

    @property
    def fallback_bands(self) -> int:
        """Bands of the noise-level fallback of this strategy (0 = none)."""
        return 0 if self.continuation else self.fallback

    def extra_rows(self, nominal: UrdfDocument) -> Callable[[FitProblem], Any] | None:
        """The ``extra_rows`` of the search's :class:`FitProblem`: the prior toward
        ``nominal``'s values (None without one)."""
        from .prior import prior_rows

        return prior_rows(nominal, self.prior_width)

    def ipopt_options(self, options: dict[str, Any] | None = None) -> dict[str, Any] | None:
        """IPOPT options of the search (``options`` plus the prior's, when it is on)."""
        from .prior import with_prior_ipopt

        return with_prior_ipopt(self.prior_width, options)

    def starts(self, problem: FitProblem, n_random: int = 0, seed: int = 0) -> list[Start]:
        """The fit's starts in the order :func:`.multistart.keep_best` tries them: the
        model's values under this strategy's schedule; then, when the strategy has a
        fallback, the same values under the band continuation (its growing bands cross
        basins a direct fit cannot) and under the staged schedule (each kind of parameter
        in the bands where it acts); then ``n_random`` random starts in the box the prior
        trusts (:func:`.multistart.random_starts`, width: the prior's, else
        :data:`RANDOM_WIDTH`)."""
        from .multistart import Start, random_starts

        starts = [Start("model values", steps=self.steps)]
        if self.fallback_bands >= 2:
            bands, pre, it = self.fallback_bands, self.presolve_iter, self.max_iter
            starts.append(Start(f"band continuation ({bands} bands)", steps=lambda p: (
                continuation(p, bands, presolve_iter=pre))))  # fmt: skip
            if not self.staged:
                starts.append(Start("staged schedule", steps=lambda p: (
                    staged(p, max_iter=it, presolve_iter=pre))))  # fmt: skip
        width = self.prior_width if self.prior_width > 0 else RANDOM_WIDTH
        return starts + random_starts(problem, n_random, width=width, seed=seed)

    def budget(self, n_starts: int = 1) -> int:
        """IPOPT iterations the fit's loop may spend over all its starts: :data:`BUDGET`
        times ``max_iter`` (at least one full search per start the user asked for)."""
        return max(BUDGET, n_starts) * (self.max_iter + self.presolve_iter)

    def steps(self, problem: FitProblem) -> list[Step]:
        """The schedule for ``problem``."""
        if self.staged and self.continuation:
            raise ConfigError("choose one search strategy: staged or continuation, not both")
        if self.staged:
            return staged(
                problem, self.stage_bands, max_iter=self.max_iter,
                presolve_iter=self.presolve_iter,
            )  # fmt: skip
        if self.continuation:
            return continuation(problem, self.continuation, presolve_iter=self.presolve_iter)
        return direct(self.presolve_iter)
