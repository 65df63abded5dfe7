"""Study files: the settings of a fit in TOML, with the same meaning as the command line.

A study file holds what ``python -m bondid.fit`` takes as options; options given on the
command line override it. Relative paths (``model``, ``data``) are relative to the study file.
Every section and key is optional::

    model = "../urdf/bonder.urdf"            # --model
    data = ["pose_a.csv", "pose_b.csv"]      # --data

    [parameters]
    free = ["parasitic", "x_stage.mass"]     # --free (names, globs, groups, "auto")
    fixed = ["*.damping"]                    # --fixed (wins over free)
    prior = 0.25                             # --prior (relative width; 0 = none)

    [bounds]                                 # --bound KEY=VALUE
    mass = 0.3                               # a number: relative fraction of |value|
    "x_stage.*" = 0.5                        # keys: a kind, a parameter name or a glob
    "x_guide_ry.stiffness" = [1e3, 1e6]      # a pair: absolute [lo, hi] in SI units

    [cost]
    kind = "complex_log"                     # --cost
    norm = "l2"                              # --norm
    bands = [[1.0, 2000.0]]                  # --band (Hz)
    channels = ["x.x", "y.y"]                # --channels
    coherence = true                         # --no-coherence ignores the coherence column
    weighting = "auto"                       # --weighting: auto|coherence|estimated|none
    lines = "auto"                           # --lines: auto|all|N (lines per file fitted)
    [cost.channel_weights]
    "x.x" = 2.0

    points_file = "points.toml"              # --points: [points] and [gains] tables
    package_path = ["../ros_ws/src"]         # --package-path (package:// meshes)
    floating_base = false                    # --floating-base (a free-free structure)
    damping = "rayleigh"                     # --damping: model|joints|rayleigh|rayleigh-only
                                             # or {kind = "rayleigh", alpha = 0.5, beta = 1e-6}

    [operating_points]                       # --operating-point FILE=x=0.1,y=0.3
    "pose_b.uff" = {x = 0.1, y = 0.3}        # for data files that state none (m or rad)

    [uff_map]                                # --uff-map NAME=NODE:DIR (UFF58 files)
    acc = [101, 3]                           # channel name = [node, direction code ±1..±6]

    [points.load]                            # a measurement point (bondid.model.points)
    link = "load"
    kind = "rotation"
    direction = [0, 0, 1]

    [gains]                                  # transducer gains (fixed unless --free names them)
    "gain.in.motor" = 0.35

    [ties]                                   # --tie: joint parameters sharing one value
    damping = "*.damping"                    # a tie's name = names or globs of one kind
    inner = ["j2.stiffness", "j3.stiffness"]

    [search]
    multistart = 8                           # --multistart
    seed = 0                                 # --seed
    workers = 2                              # --workers
    staged = true                            # --staged
    continuation = 8                         # --continuation (bands; 0 = off)
    max_iter = 200                           # --max-iter
    presolve = 60                            # --presolve (0 = none)
    fallback = 8                             # --fallback (bands; 0 = off)
    fallback_starts = 4                      # --fallback-starts (0 = off)
    [search.stage_bands]                     # staged fitting bands (Hz); default: from the modes
    stiffness = [[1.0, 300.0]]
    damping = [[350.0, 500.0], [800.0, 950.0]]
    inertia = [[400.0, 4000.0]]

Errors are :class:`~bondid.exceptions.ConfigError` naming the file, the key and what is valid
(the value checks, shared with the command line, are in :mod:`.setting_checks`).
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..cost.residuals import NORMS, RESIDUAL_KINDS
from ..data.reduce import parse_lines
from ..data.weights import WEIGHTINGS
from ..exceptions import ConfigError
from ..model.points import Point
from ..optim.schedules import STAGES
from .defaults import DEFAULT_FREE, DEFAULT_WIDTH, check_prior
from .setting_checks import (
    check_bands,
    check_bool,
    check_bound,
    check_choice,
    check_int,
    check_keys,
    check_names,
    check_path,
    check_table,
    config_error,
)

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..modes.bands import Span as Band

#: Parameter kinds a bound key may name (besides names and globs).
KINDS = ("mass", "com", "inertia", "stiffness", "damping", "gain", "mix", "rayleigh")

_TOP_KEYS = (
    "model", "data", "parameters", "bounds", "cost", "search", "points", "gains", "points_file",
    "package_path", "floating_base", "uff_map", "operating_points", "ties", "damping",
)  # fmt: skip
_SECTION_KEYS = {
    "parameters": ("free", "fixed", "prior"),
    "cost": ("kind", "norm", "bands", "channels", "coherence", "weighting", "channel_weights",
             "lines"),
    "search": ("multistart", "seed", "workers", "staged", "continuation", "max_iter", "presolve",
               "fallback", "fallback_starts", "stage_bands"),
}  # fmt: skip


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
        lines: the lines per file the fit uses (:func:`bondid.data.reduce.parse_lines`):
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
            that state none (:mod:`bondid.fit.operating_points`).
        ties: tie name -> the names and globs of its joint parameters (one value each tie;
            :mod:`bondid.model.ties`).
        damping, damping_start: the damping model and the (α, β) to start from, or None
            (:mod:`bondid.fit.damping`).
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
    damping_start: tuple[float, float] | None = None

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


def _pair(v: tuple[float, float] | None) -> list[float] | None:
    return None if v is None else list(v)


def add_bound(settings: StudySettings, key: str, bound: float | tuple[float, float]) -> None:
    """Record a bound (relative or absolute) for ``key``, replacing any earlier one."""
    settings.rel_bounds.pop(key, None)
    settings.abs_bounds.pop(key, None)
    if isinstance(bound, tuple):
        settings.abs_bounds[key] = bound
    else:
        settings.rel_bounds[key] = bound


def load_study(path: str | os.PathLike[str]) -> StudySettings:
    """Read and validate a study TOML file.

    Raises:
        ConfigError: unreadable file, TOML syntax error, unknown key or invalid value (the
            message names the file, the key and the valid values).
    """
    p = Path(path)
    where = str(p)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{where}: cannot read the study file ({exc.strerror})") from None
    try:
        doc = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise ConfigError(f"{where}: not UTF-8 text; save the study file as UTF-8") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: not valid TOML ({exc})") from None
    return study_from_dict(doc, where=where, base=p.parent, source=p)


def study_from_dict(
    doc: Mapping[str, Any], *, where: str = "<study>", base: Path | None = None,
    source: Path | None = None,
) -> StudySettings:  # fmt: skip
    """Validate a parsed study (a TOML mapping) into :class:`StudySettings`."""
    base = Path(".") if base is None else base
    s = StudySettings(source=source)
    check_keys(doc, _TOP_KEYS, where, "")
    if "model" in doc:
        s.model = check_path(doc["model"], base, where, "model")
    if "data" in doc:
        items = [doc["data"]] if isinstance(doc["data"], str) else doc["data"]
        if not isinstance(items, list) or not items:
            raise config_error(
                where, "data", f"{doc['data']!r} is not a file path or a list of them"
            )
        s.data = [check_path(v, base, where, f"data[{i}]") for i, v in enumerate(items)]

    from .model_setup import read_model_keys

    read_model_keys(doc, s, where, base)

    _read_parameters(doc, s, where)
    for name, items in check_table(doc.get("ties", {}), where, "ties").items():
        s.ties[str(name)] = check_names(items, where, f"ties.{name}")
        if not s.ties[str(name)]:
            raise config_error(where, f"ties.{name}", "empty; give names or globs")
    _read_cost(doc, s, where)
    _read_search(doc, s, where)
    return s


def _read_parameters(doc: Mapping[str, Any], s: StudySettings, where: str) -> None:
    """The study's ``[parameters]`` and ``[bounds]`` tables into ``s``."""
    par = check_table(doc.get("parameters", {}), where, "parameters")
    check_keys(par, _SECTION_KEYS["parameters"], where, "parameters")
    if "free" in par:
        s.free = check_names(par["free"], where, "parameters.free")
        if not s.free:
            raise config_error(where, "parameters.free", "empty; give names, globs or groups")
    if "fixed" in par:
        s.fixed = check_names(par["fixed"], where, "parameters.fixed")
    if "prior" in par:
        s.prior = check_prior(par["prior"], f"{where}: parameters.prior")
    bounds = check_table(doc.get("bounds", {}), where, "bounds")
    for key, value in bounds.items():
        add_bound(s, key, check_bound(value, where, f"bounds.{key}"))


def _read_cost(doc: Mapping[str, Any], s: StudySettings, where: str) -> None:
    """The study's ``[cost]`` table into ``s``."""
    cost = check_table(doc.get("cost", {}), where, "cost")
    check_keys(cost, _SECTION_KEYS["cost"], where, "cost")
    if "kind" in cost:
        s.cost = check_choice(cost["kind"], RESIDUAL_KINDS, where, "cost.kind")
    if "norm" in cost:
        s.norm = check_choice(cost["norm"], NORMS, where, "cost.norm")
    if "bands" in cost:
        s.bands = check_bands(cost["bands"], where, "cost.bands")
    if "channels" in cost:
        s.channels = check_names(cost["channels"], where, "cost.channels")
        if not s.channels:
            raise config_error(where, "cost.channels", "empty; give OUT.IN names such as x.x")
    if "coherence" in cost:
        s.coherence = check_bool(cost["coherence"], where, "cost.coherence")
    if "weighting" in cost:
        s.weighting = check_choice(cost["weighting"], WEIGHTINGS, where, "cost.weighting")
    if "lines" in cost:
        s.lines = str(parse_lines(cost["lines"], f"{where}: cost.lines"))
    for ch, w in check_table(
        cost.get("channel_weights", {}), where, "cost.channel_weights"
    ).items():
        key = f"cost.channel_weights.{ch}"
        if isinstance(w, bool) or not isinstance(w, int | float) or not 0 <= w < float("inf"):
            raise config_error(where, key, f"{w!r} is not a finite weight >= 0")
        if ch.count(".") != 1:
            raise config_error(where, key, "not a channel name OUT.IN such as x.y")
        s.channel_weights[ch] = float(w)


#: ``[search]`` integer keys: minimum value
_SEARCH_INTS = {"multistart": 1, "seed": 0, "workers": 1, "continuation": 0, "max_iter": 0,
                "presolve": 0, "fallback": 0, "fallback_starts": 0}  # fmt: skip


def _read_search(doc: Mapping[str, Any], s: StudySettings, where: str) -> None:
    """The study's ``[search]`` table into ``s``."""
    search = check_table(doc.get("search", {}), where, "search")
    check_keys(search, _SECTION_KEYS["search"], where, "search")
    for key, minimum in _SEARCH_INTS.items():
        if key in search:
            setattr(s, key, check_int(search[key], where, f"search.{key}", minimum))
    if "staged" in search:
        s.staged = check_bool(search["staged"], where, "search.staged")
    if "stage_bands" in search:
        table = check_table(search["stage_bands"], where, "search.stage_bands")
        check_keys(table, STAGES, where, "search.stage_bands")
        for stage, bands in table.items():
            s.stage_bands[stage] = check_bands(bands, where, f"search.stage_bands.{stage}")
