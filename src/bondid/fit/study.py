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
    damping = "rayleigh"                     # --damping: model|joints|rayleigh|rayleigh-only|
                                             # structural, or {kind = "rayleigh", alpha = 0.5,
                                             # beta = 1e-6} or {kind = "structural", eta = 0.008}

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

    [ties]                                   # --tie: parameters sharing one value
    damping = "*.damping"                    # a tie's name = names or globs of one kind
    inner = ["j2.stiffness", "j3.stiffness"]
    segment_mass = "seg*.mass"               # masses, CoM or inertia components too

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

The file is read into :class:`~.settings.StudySettings`, the record the command line fills
too. Errors are :class:`~bondid.exceptions.ConfigError` naming the file, the key and what is
valid (the value checks, shared with the command line, are in :mod:`.setting_checks`).
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..cost.residuals import NORMS, RESIDUAL_KINDS
from ..data.lines import parse_lines
from ..data.weights import WEIGHTINGS
from ..exceptions import ConfigError
from ..optim.schedules import STAGES
from .defaults import check_prior
from .model_setup import read_model_keys
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
from .settings import StudySettings as StudySettings
from .settings import add_bound

#: Parameter kinds a bound key may name (besides names and globs).
KINDS = (
    "mass", "com", "inertia", "stiffness", "damping", "gain", "mix", "multiplier", "rayleigh",
)  # fmt: skip

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
