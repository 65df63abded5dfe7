"""The settings of one fit, whichever way they were given: :class:`StudySettings`.

A study file (:mod:`.study`) and the command line (:mod:`.options`) fill the same record, the
command line's values winning; the model-side keys are read by :mod:`.model_setup`. The record
itself reads nothing, so every reader can import it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..model.points import Point
from .defaults import DEFAULT_FREE, DEFAULT_WIDTH

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..modes.bands import Span as Band


@dataclass
class StudySettings:
    """Every setting of a fit (defaults = the command line's defaults).

    Attributes:
        model: URDF path, or None (then ``--model`` must give it).
        data: measured-data paths.
        free, fixed: parameter names, globs or groups (``fixed`` wins).
        prior: relative width τ of the prior toward the model's values
            (:mod:`bondid.optim.prior`); 0 = none.
        rel_bounds: key (kind, name or glob) -> relative fraction of |value|.
        abs_bounds: key (name or glob) -> (lo, hi), SI units.
        cost, norm: residual kind and norm (see :mod:`bondid.cost.residuals`).
        bands: frequency bands (Hz) to fit, None = all.
        channels: ``OUT.IN`` channels to fit, None = all present.
        channel_weights: extra weight per channel.
        coherence: use the file's coherence column in the weights where present.
        weighting: point weights (:data:`bondid.data.weights.WEIGHTINGS`), default auto.
        lines: the lines per file the fit uses (:func:`bondid.data.lines.parse_lines`):
            ``auto`` (default), ``all`` or a count.
        multistart: number of starts (1 = the URDF values only).
        seed: seed of the Latin hypercube.
        workers: parallel processes for the multistart.
        staged: fit by bands first (stiffness, damping, inertia), then everything.
        stage_bands: stage -> bands (Hz); a missing stage takes bands from the modes.
        continuation: number of bands of a band continuation (growing band from the lowest
            frequencies, :mod:`bondid.optim.schedules`); 0 = off. Not with ``staged``.
        max_iter: IPOPT iteration limit per fit.
        presolve: IPOPT iterations on the normalised complex error before a log-cost fit
            (:data:`bondid.fit.solver.PRESOLVE_ITER`; 0 = none).
        fallback: bands of the band continuation the fit tries (with the staged schedule)
            when a direct or staged search ends above the noise level
            (:meth:`bondid.optim.schedules.Strategy.starts`); 0 = off.
        fallback_starts: after those, up to ``fallback_starts - 1`` random starts while the
            fit is above the noise level and a restart still improves
            (:func:`bondid.optim.multistart.keep_best`); 0 or 1 = off. Only for a
            single-start search.
        source: the study file, or None.
        points, gains: measurement points and transducer gains declared in the study
            (:mod:`bondid.model.points`); points_file: a TOML file with more of them.
        package_path: folders searched first for ``package://`` meshes.
        floating_base: add a floating joint above the root (a free-free structure).
        uff_map: channel name -> (node, direction) of UFF58 records.
        operating_points: data file -> its operating point (joint -> m or rad), for files
            that state none (:mod:`bondid.setup.operating_points`).
        ties: tie name -> the names and globs of its joint parameters (one value each tie;
            :mod:`bondid.model.ties`).
        damping, damping_start: the damping model and the (α, β) (a loss factor: (η,)) to
            start from, or None
            (:mod:`bondid.setup.damping`).
    """

    model: Path | None = None
    data: list[Path] = field(default_factory=list)
    free: list[str] = field(default_factory=lambda: list(DEFAULT_FREE))
    fixed: list[str] = field(default_factory=list)
    prior: float = DEFAULT_WIDTH
    rel_bounds: dict[str, float] = field(default_factory=dict)
    abs_bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    cost: str = "complex_log"
    norm: str = "l2"
    bands: list[Band] | None = None
    channels: list[str] | None = None
    channel_weights: dict[str, float] = field(default_factory=dict)
    coherence: bool = True
    weighting: str = "auto"
    lines: str = "auto"
    multistart: int = 1
    seed: int = 0
    workers: int = 2
    staged: bool = False
    stage_bands: dict[str, list[Band]] = field(default_factory=dict)
    continuation: int = 0
    max_iter: int = 200
    presolve: int = 60
    fallback: int = 8
    fallback_starts: int = 4
    source: Path | None = None
    points: list[Point] = field(default_factory=list)
    gains: dict[str, float] = field(default_factory=dict)
    points_file: Path | None = None
    package_path: list[Path] = field(default_factory=list)
    floating_base: bool = False
    uff_map: dict[str, tuple[int, int]] = field(default_factory=dict)
    operating_points: dict[str, dict[str, float]] = field(default_factory=dict)
    ties: dict[str, list[str]] = field(default_factory=dict)
    damping: str = "model"
    damping_start: tuple[float, ...] | None = None

    def to_json_dict(self) -> dict[str, Any]:
        """The settings as plain JSON values (paths as strings)."""
        return {
            "study": None if self.source is None else str(self.source),
            "model": None if self.model is None else str(self.model),
            "data": [str(p) for p in self.data],
            "free": list(self.free),
            "fixed": list(self.fixed),
            "prior": self.prior,
            "bounds_relative": dict(self.rel_bounds),
            "bounds_absolute": {k: list(v) for k, v in self.abs_bounds.items()},
            "cost": self.cost,
            "norm": self.norm,
            "bands": None if self.bands is None else [list(b) for b in self.bands],
            "channels": None if self.channels is None else list(self.channels),
            "channel_weights": dict(self.channel_weights),
            "coherence": self.coherence,
            "weighting": self.weighting,
            "lines": self.lines,
            "multistart": self.multistart,
            "seed": self.seed,
            "workers": self.workers,
            "staged": self.staged,
            "stage_bands": {k: [list(b) for b in v] for k, v in self.stage_bands.items()},
            "continuation": self.continuation,
            "max_iter": self.max_iter,
            "presolve": self.presolve,
            "fallback": self.fallback,
            "fallback_starts": self.fallback_starts,
            "points": [vars(p) for p in self.points],
            "gains": dict(self.gains),
            "points_file": None if self.points_file is None else str(self.points_file),
            "package_path": [str(p) for p in self.package_path],
            "floating_base": self.floating_base,
            "uff_map": {k: list(v) for k, v in self.uff_map.items()},
            "operating_points": {k: dict(v) for k, v in self.operating_points.items()},
            "ties": {k: list(v) for k, v in self.ties.items()},
            "damping": {"kind": self.damping, "start": _pair(self.damping_start)},
        }


def _pair(v: tuple[float, ...] | None) -> list[float] | None:
    return None if v is None else list(v)


def add_bound(settings: StudySettings, key: str, bound: float | tuple[float, float]) -> None:
    """Record a bound (relative or absolute) for ``key``, replacing any earlier one."""
    settings.rel_bounds.pop(key, None)
    settings.abs_bounds.pop(key, None)
    if isinstance(bound, tuple):
        settings.abs_bounds[key] = bound
    else:
        settings.rel_bounds[key] = bound
