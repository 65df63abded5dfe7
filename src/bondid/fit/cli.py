"""``python -m bondid.fit``: fit a URDF's parameters to measured FRFs (conventions §4).

Reads the model and data, resolves the free parameters and bounds, runs the constrained fit
(optionally staged, optionally from several Latin-hypercube starts in parallel), prints a short
summary on stdout, shows progress on stderr and, with ``--out DIR``, writes ``fit.json``,
``fitted.urdf`` and the plots (:mod:`bondid.fit.outputs`). Exit codes: 0 converged, 2 bad
input, 1 the fit failed or did not converge (the results are still written).
"""

from __future__ import annotations

import argparse
import fnmatch
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..cli import Progress, parse_and_run, warn_lines
from ..cost.problem import CostOptions
from ..cost.selection import channels_by_file, informative_only
from ..data.measurement import FrfData
from ..data.reduce import reduce_datasets
from ..exceptions import ConfigError, DependencyError, SolverError
from ..model.document import UrdfDocument
from ..model.parameters import get_parameters, parameter_infos, select_parameters
from ..model.tie_declaration import declare_tie
from ..setup.damping import damping_json, data_band, declare_damping
from .options import build_parser, resolve_settings
from .settings import StudySettings
from .study import KINDS
from .summary import exit_code, summary

_KIND_GLOB = {
    "mass": "*.mass",
    "com": "*.com.*",
    "inertia": "*.inertia.*",
    "stiffness": "*.stiffness",
    "damping": "*.damping",
    "gain": "gain.*",
    "mix": "mix.*",
    "multiplier": "*.multiplier",
    "rayleigh": "rayleigh.*",
}


#: the names ``bondid.fit`` may write under ``--out``
OUT_PATTERNS = ("fit.json", "fitted.urdf", "convergence.png", "bode_*.png")


def cost_options(s: StudySettings) -> CostOptions:
    return CostOptions(
        kind=s.cost,
        norm=s.norm,
        bands=None if s.bands is None else list(s.bands),
        channels=None if s.channels is None else list(s.channels),
        channel_weights=dict(s.channel_weights),
        use_coherence=s.coherence,
        weighting=s.weighting,
    )


def resolve_names(
    doc: UrdfDocument, datasets: list[FrfData], s: StudySettings, options: CostOptions
) -> list[str]:
    """Free parameter names from ``free``/``fixed`` (``auto`` asks bondid.sensitivity) under
    the damping model (:func:`bondid.setup.damping.damping_free`)."""
    from ..setup.damping import damping_free

    free, fixed = damping_free(doc, s.damping, s.free, s.fixed)
    if "auto" in free:
        try:
            from ..sensitivity import recommend_subset
        except ImportError:
            raise DependencyError(
                "--free auto needs bondid.sensitivity.recommend_subset, which this installation"
                " lacks; name the parameters, globs or groups instead"
            ) from None
        free = [t for t in free if t != "auto"] + list(recommend_subset(doc, datasets, options))
    names = select_parameters(doc, free, fixed) if free else []
    if not names:
        raise ConfigError(
            f"{doc.source}: no free parameter left (free: {' '.join(s.free)};"
            f" fixed: {' '.join(s.fixed) or 'none'})"
        )
    return names


def resolve_bounds(
    doc: UrdfDocument, names: list[str], s: StudySettings, f_max_hz: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds from the defaults, the study and ``--bound`` (a kind key applies to its kind)."""
    from ..optim.bounds import default_bounds

    known = [p.name for p in parameter_infos(doc)]
    for key in [*s.rel_bounds, *s.abs_bounds]:
        pattern = _KIND_GLOB.get(key, key)
        if not any(fnmatch.fnmatchcase(n, pattern) for n in known):
            raise ConfigError(
                f"{s.source or '--bound'}: bounds key {key!r} matches no parameter of"
                f" {doc.source}; valid: a kind ({', '.join(KINDS)}), a parameter name or a glob"
            )
    # absolute bounds of parameters that are not free this time are not an error
    absolute = {
        _KIND_GLOB.get(k, k): v
        for k, v in s.abs_bounds.items()
        if any(fnmatch.fnmatchcase(n, _KIND_GLOB.get(k, k)) for n in names)
    }
    try:
        return default_bounds(doc, names, rel=s.rel_bounds, absolute=absolute, f_max_hz=f_max_hz)
    except ConfigError as exc:
        raise ConfigError(f"{s.source or '--bound'}: {exc}") from None


def check_weights(s: StudySettings, datasets: list[FrfData]) -> None:
    """Every ``--weight`` / study weight must name a channel of the data."""
    have = sorted({ch for ds in datasets for ch in ds.channels})
    for ch in s.channel_weights:
        if ch not in have:
            raise ConfigError(
                f"{s.source or '--weight'}: channel {ch!r} is not in the data; valid:"
                f" {', '.join(have)}"
            )


def start_outside_bounds(
    doc: UrdfDocument, names: list[str], lower: np.ndarray, upper: np.ndarray
) -> list[str]:
    """Warnings for model values outside their bounds (the fit starts from the bound,
    and reports that clipped value as ``initial``)."""
    out = []
    for n, v, lo, hi in zip(names, get_parameters(doc, names), lower, upper, strict=True):
        if not lo <= v <= hi:
            out.append(
                f"{n}: the model's value {float(v):.6g} is outside the bounds"
                f" [{float(lo):.6g}, {float(hi):.6g}]; the fit starts from"
                f" {float(np.clip(v, lo, hi)):.6g} (reported as initial)"
            )
    return out


def write_failure(
    res: Any,
    exc: SolverError,
    doc: UrdfDocument,
    names: list[str],
    lower: np.ndarray,
    upper: np.ndarray,
    s: StudySettings,
    warnings: list[str],
) -> None:
    """``fit.json`` of a fit that failed without a usable iterate: status ``"failed"``, the
    reason, and the start (the best point known) as ``initial`` with ``fitted`` null."""
    import json

    from .outputs import FIT_JSON, jsonable

    start = np.clip(get_parameters(doc, names), lower, upper)
    content = {
        "status": "failed", "success": False, "solver_status": exc.status,
        "failure": str(exc), "cost_initial": None, "cost_final": None, "cost_name": None,
        "iterations": 0, "wall_s": None, "command": "bondid.fit",
        "model_file": str(s.model), "settings": s.to_json_dict(), "warnings": warnings,
        "parameters": [
            {"name": n, "initial": float(x), "fitted": None, "lower": float(lo),
             "upper": float(hi), "std": None}
            for n, x, lo, hi in zip(names, start, lower, upper, strict=True)
        ],
        "outputs": [FIT_JSON],
    }  # fmt: skip
    res.path(FIT_JSON).write_text(json.dumps(jsonable(content), indent=2) + "\n")
    res.commit(warnings=warnings, main=FIT_JSON)


def _load(args: argparse.Namespace, s: StudySettings) -> dict[str, Any]:
    """Model, data, names, bounds and the results folder of a fit command (checked)."""
    from ..results import open_results
    from ..setup.operating_points import given_operating_points
    from ..validation import check_inputs, check_selection, load_model
    from ..validation.datasets import load_datasets
    from .model_setup import prepare_model, uff_map
    from .outputs import check_out_dir

    assert s.model is not None
    inputs: list[Path] = [s.model, *s.data] + ([s.source] if s.source else [])
    inputs += [f for f in (s.points_file, args.points_file) if f is not None]
    res = None if args.out is None else open_results(args.out, "fit", inputs, patterns=OUT_PATTERNS)
    doc, warnings = load_model(s.model, lambda d: prepare_model(d, s, args))
    for name, items in s.ties.items():
        declare_tie(doc, name, items, "--tie" if name in (args.tie or ()) else str(s.source))
    raw = load_datasets(doc, s.data, drop_nan=args.drop_nan, channel_map=uff_map(s, args.uff_map))
    warnings += given_operating_points(doc, raw, s.operating_points)
    warnings += check_inputs(doc, raw, s.data)
    check_selection(raw, bands=s.bands, channels=s.channels, band_option=_where(s, "--band"),
                    channel_option=_where(s, "--channels"))  # fmt: skip
    datasets = [ds if ds.quantity == "receptance" else ds.to_quantity("receptance") for ds in raw]
    damping_start = declare_damping(
        doc, s.damping, start=s.damping_start, band_hz=data_band(datasets, s.bands),
        operating_point=datasets[0].operating_point,
    )  # fmt: skip
    if args.out is not None:
        check_out_dir(args.out, inputs, datasets)
    check_weights(s, datasets)
    options, left_out, note = informative_only(datasets, cost_options(s))
    if note:
        warnings.append(note)
    # the fit's cost runs on the reduced lines; the reported figures on all of them
    fit_datasets, lines = reduce_datasets(datasets, s.lines, options.channels, options.bands)
    names = resolve_names(doc, fit_datasets, s, options)
    lower, upper = resolve_bounds(doc, names, s, max(float(d.freq_hz[-1]) for d in datasets))
    warnings += start_outside_bounds(doc, names, lower, upper)
    return {
        "inputs": inputs, "res": res, "doc": doc, "warnings": warnings, "datasets": datasets,
        "options": options, "names": names, "lower": lower, "upper": upper,
        "left_out": left_out, "quantities": [ds.quantity for ds in raw],
        "fit_datasets": fit_datasets, "lines": lines, "damping_start": damping_start,
    }  # fmt: skip


def _where(s: StudySettings, option: str) -> str:
    """The option's name, or with a study file "STUDY / --option" (either may set it)."""
    return option if s.source is None else f"{s.source} / {option}"


def _search(s: StudySettings, w: dict[str, Any], quiet: bool) -> Any:
    """Run the multistart search with progress on stderr; its :class:`MultistartResult`."""
    from ..optim.schedules import Strategy
    from .multistart import run_multistart

    single = s.multistart == 1 or s.workers == 1
    # one start: a bar over the IPOPT iterations (out of the limit); several in parallel:
    # a bar over the starts
    prog = Progress(
        "fit (iterations)" if single else f"fit ({s.multistart} starts)",
        s.max_iter if single else s.multistart,
        quiet=quiet,
    )

    def on_iteration(it: int, cost: float) -> None:
        prog.set(it, f"cost {cost:.4g}")

    def on_run(done: int, total: int, out: Any) -> None:
        tier = s.multistart == 1 and out.index > 0  # after a single search: fallback starts
        info = f"{out.result.status} cost {out.cost:.4g}" if out.result else f"failed: {out.error}"
        if not single:
            prog.update(1, f"start {out.index}: {info}")
        elif tier or s.multistart > 1:
            prog.write(f"fit: {'fallback start' if tier else 'start'} {out.index}: {info}")

    strategy = Strategy(
        staged=s.staged, continuation=s.continuation, stage_bands=s.stage_bands or None,
        presolve_iter=s.presolve, max_iter=s.max_iter, prior_width=s.prior,
        fallback=s.fallback,
    )  # fmt: skip
    ms = run_multistart(
        w["doc"], w["fit_datasets"], w["names"], lower=w["lower"], upper=w["upper"],
        options=w["options"], n_starts=s.multistart, seed=s.seed, workers=s.workers,
        strategy=strategy, on_run=on_run, on_iteration=on_iteration,
        fallback_starts=s.fallback_starts if strategy.fallback_bands else 0,
    )  # fmt: skip
    prog.close(f"{ms.best.status}, cost {ms.best.cost_final:.4g}")
    return ms


def _model_cost(ms: Any, w: dict[str, Any]) -> float:
    """The cost at the model's own values (start 0), from its run when it has one."""
    start0 = ms.runs[0].result
    if start0 is not None:
        return float(start0.cost_initial)
    from ..optim.problem import FitProblem

    problem = FitProblem(
        w["doc"], w["fit_datasets"], w["names"], options=w["options"], lower=w["lower"],
        upper=w["upper"],
    )  # fmt: skip
    return problem.cost(problem.z0)


def _reported(result: Any, ms: Any, w: dict[str, Any], cost_model: float) -> Any:
    """The kept fit as the command reports it: ``initial`` the model's values (clipped to
    the bounds) and ``cost_initial`` the cost there, the kept search's own start in
    ``start``/``cost_start`` when it began elsewhere (a fallback start), and ``wall_s`` the
    whole search's time (every run)."""
    model_x = np.clip(get_parameters(w["doc"], w["names"]), w["lower"], w["upper"])
    if not np.array_equal(result.initial, model_x):
        result = replace(
            result, initial=model_x, start=result.initial, cost_initial=cost_model,
            cost_start=result.cost_initial,
        )  # fmt: skip
    return replace(result, wall_s=float(ms.wall_s))


def _body(args: argparse.Namespace) -> int:
    from .outputs import FIT_JSON, write_outputs

    t0 = time.perf_counter()
    s = resolve_settings(args)
    w = _load(args, s)
    res, warnings = w["res"], w["warnings"]
    try:
        ms = _search(s, w, args.quiet)
    except SolverError as exc:  # no run kept an iterate: still say so in fit.json
        if res is not None:
            write_failure(res, exc, w["doc"], w["names"], w["lower"], w["upper"], s, warnings)
        raise
    cost_model = _model_cost(ms, w)
    result = _reported(ms.best, ms, w, cost_model)
    spread = ms.spread()
    spread["iterations_all"] = sum(r.result.iterations for r in ms.runs if r.result is not None)
    extra: dict[str, Any] = {
        "cost_model": cost_model, "command": "bondid.fit", "model_file": str(s.model),
        "study_file": None if s.source is None else str(s.source),
        "settings": s.to_json_dict(), "multistart": spread,
        "stages": [st.to_json_dict() for st in ms.best_run.stages] or None,
        "warnings": warnings, "lines": w["lines"].to_json_dict(),
    }  # fmt: skip
    extra["damping"] = damping_json(s.damping, w["damping_start"], w["doc"], result)
    extra["channels_left_out"], extra["channels_by_file"] = channels_by_file(
        w["datasets"], w["options"], w["left_out"]
    )
    content = None
    if res is not None:
        histories = [r.result.cost_history if r.result else [] for r in ms.runs]
        content = write_outputs(
            res.tmp, result=result, initial_doc=w["doc"], datasets=w["datasets"],
            options=w["options"], inputs=w["inputs"], histories=histories,
            history_labels=[f"start {r.index}" for r in ms.runs], extra=extra,
            file_quantities=w["quantities"],
        )  # fmt: skip
        res.commit(warnings=warnings, main=FIT_JSON)
    print(summary(result, content, extra, time.perf_counter() - t0, w["lines"]))
    for line in warn_lines(warnings):
        print(line)
    if args.out is not None:
        print(f"results: {args.out} ({', '.join(content['outputs']) if content else ''})")
    else:
        print("(no --out given: nothing written)")
    return exit_code(result)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; returns the exit code (0 ok, 2 bad input, 1 failed)."""
    return parse_and_run(build_parser(), argv, _body)
