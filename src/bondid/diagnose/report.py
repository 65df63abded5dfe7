"""What a diagnosis writes: ``diagnosis.json``, plots and URDF files (the human summary:
:mod:`.summary`).

``diagnosis.json`` keys (spec §4 plus extras):

* ``gap`` — the remaining gap after the parameter refit (``db_rms``, ``by_channel``,
  ``by_band``, ``modes``), plus ``db_rms_unweighted``, ``mag_db_rms``, ``weighting``,
  ``antiresonances``; ``gap_closed`` is always relative to this ``gap.db_rms``. Every gap
  figure is information-weighted (:data:`DB_RMS_DEFINITION`);
* ``candidates`` — best first: ``effect``, ``location``, ``parameters`` {name: value},
  ``db_rms_after``, ``gap_closed``, ``heldout_db_rms_after``, ``score`` (see
  :mod:`.scoring`), plus ``parameters_std``, ``heldout_weighted_rms``, ``train_weighted_rms``,
  ``n_parameters``, ``strength_z`` (the data's determination of the effect's strength,
  :func:`.scoring.strength_z`; the verdict's test is taken on the best-scoring refit with
  ``strength_z ≥ z``), ``detail`` (the variant the runner kept, e.g. a pivot), ``wall_s``,
  ``error``;
* ``verdict`` — ``effect`` (or ``"none"``), ``location``, ``gap_closed``, plus
  ``reason``, ``detail``, ``parameters`` with ``std``, ``where`` (gap by channel and band after it),
  ``indistinguishable_from`` (the refits the data cannot tell from it, :func:`.verdict.tied`;
  each entry of ``effects`` has the same list for its step); the first effect the backward
  elimination keeps (:mod:`.prune`, :mod:`.verdict`);
* ``effects`` — the kept effects in the order accepted, with the gap after each; ``dropped``
  — the accepted effects the elimination dropped, with the figures that dropped them;
* ``stages`` — the gap (total, per channel, per band) of the nominal model, after the
  parameter refit and after the winning effect; ``gap_closed_total`` (vs the nominal gap);
* ``refit`` (the parameter refit: names, values, std, IPOPT stage), ``split``, ``settings``;
* ``weighting`` — which weighting, its rule, and per data set and channel the estimated
  noise (``rho``, ``floor_median``, ``floor_db_below_median``) and the informative share
  (SNR ≥ 10 dB), see :func:`bondid.data.weights.weighting_summary`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..atomic import write_text_atomic
from ..jsonsafe import json_safe as _num
from ..model.packages import restore_mesh_names
from ..model.pivot import settled_text
from . import scoring
from .gap import GapReport, gap_report
from .job import JobResult
from .pipeline import Diagnosis
from .scoring import ABS_MARGIN_DB, REL_MARGIN, gap_closed
from .verdict import (
    dropped_entries,
    effect_entries,
    effect_params,
    kept_effects,
    verdict_entry,
)

#: the backward elimination as ``diagnosis.json`` states it (``scoring.elimination``)
ELIMINATION = (
    "with two or more accepted effects, each is tested again against the refit of the model "
    "with all the others by the same rule; of those that fail, the one whose removal leaves "
    "the best held-out score is dropped (listed in 'dropped'), and the test repeats until "
    "each passes or one is left"
)
#: how the gap figures are defined (written into diagnosis.json)
DB_RMS_DEFINITION = (
    "db_rms = sqrt(sum(w * e^2) / sum(w)) over the used channels and all their frequencies, "
    "e = (20/ln 10)|ln(H_meas/H_model)| (phase wrapped), w = the point's information weight "
    "S/(S+N) (see 'weighting'); the same for by_channel, by_band, held-out figures and "
    "gap_closed; db_rms_unweighted: the plain RMS of e over the points with w >= 0.5"
)


def gaps(diag: Diagnosis) -> dict[str, GapReport]:
    """Weighted gap reports of the nominal model, the refit and the winner (when there is
    one); the unweighted figures over the points of weight ≥ 0.5 under ``"<stage>_unweighted"``.
    The data's coherence holds the information weights (see :func:`.pipeline.diagnose`)."""
    from .split import mask_incoherent

    masked = [mask_incoherent(d) for d in diag.datasets]
    ch, fb = diag.channels, diag.channels_by_file
    models = {"nominal": diag.nominal_H, "refit": diag.baseline.full_H}
    if diag.winner is not None:
        models["effect"] = diag.winner.full_H
    out: dict[str, GapReport] = {}
    for stage, H in models.items():
        out[stage] = gap_report(
            diag.datasets, H, diag.bands, channels=ch, by_file=fb, weighting="coherence"
        )
        out[f"{stage}_unweighted"] = gap_report(masked, H, diag.bands, channels=ch, by_file=fb)
    return out


def _gap_dict(g: GapReport, plain: GapReport | None = None) -> dict[str, Any]:
    return {
        "db_rms": g.db_rms,
        "db_rms_unweighted": None if plain is None else plain.db_rms,
        "mag_db_rms": g.mag_db_rms,
        "by_channel": dict(g.by_channel),
        "by_band": [
            {"f_lo_hz": b["f_lo_hz"], "f_hi_hz": b["f_hi_hz"], "db_rms": b["db_rms"]}
            for b in g.by_band
        ],
    }


def _refit_entry(r: Any, sc: float, before: float) -> dict[str, Any]:
    """The figures of one fully refitted candidate."""
    vals, std = effect_params(r, len(r.chain) - 1) if not r.error and r.chain else ({}, {})
    return {
        "parameters": vals,
        "db_rms_after": r.db_rms,
        "db_rms_unweighted_after": r.db_rms_unweighted,
        "gap_closed": gap_closed(before, r.db_rms),
        "heldout_db_rms_after": r.heldout_db_rms,
        "score": sc,
        "parameters_std": std,
        "heldout_weighted_rms": r.heldout_rms,
        "train_weighted_rms": r.train_rms,
        "n_parameters": r.n_own,
        "strength_z": scoring.strength_z(r) if not r.error else None,
        "detail": r.variant or None,
        "starts": [
            {
                "label": a.label,
                "noise_ratio": a.ratio,
                "iterations": a.iterations,
                "error": a.error or None,
            }
            for a in r.attempts
        ],
        "stopped": r.stopped or None,
        "wall_s": r.wall_s,
        "error": r.error or None,
    }


def candidate_entries(diag: Diagnosis, before: float) -> list[dict[str, Any]]:
    """``candidates`` of diagnosis.json: per search step (``step``, 1 = the verdict's), the
    refitted candidates by held-out score, then the others by screening figure; each with its
    screening figure (``screening_db``: the predicted training RMS [dB] of its best start),
    its screened starts (``screening_starts``: label, figure [dB] and ``edge``, a scan start
    at an end of the scan's grid, tried last) and ``refitted``."""
    out: list[dict[str, Any]] = []
    for step in diag.steps:
        by_label = {r.label: (r, sc) for r, sc in zip(step.results, step.scores, strict=True)}
        screened = sorted(step.screenings, key=lambda s: s.cost)
        refitted = [s for s in screened if s.label in by_label]
        refitted.sort(key=lambda s: step.results.index(by_label[s.label][0]))
        for s in refitted + [s for s in screened if s.label not in by_label]:
            entry: dict[str, Any] = {
                "effect": s.effect, "location": s.location, "step": step.index + 1,
                "screening_db": s.db,
                "screening_starts": [
                    {"label": st.label,
                     "figure_db": math.sqrt(st.figure) if math.isfinite(st.figure) else None,
                     "edge": st.edge}
                    for st in s.starts
                ],
                "screening_wall_s": s.wall_s, "refitted": s.label in by_label,
            }  # fmt: skip
            if s.label in by_label:
                entry.update(_refit_entry(*by_label[s.label], before))
            else:
                entry.update({"parameters": {}, "db_rms_after": None, "gap_closed": None,
                              "heldout_db_rms_after": None, "score": None,
                              "error": s.error or None})  # fmt: skip
            out.append(entry)
    return out


def _gap_section(diag: Diagnosis, reports: dict[str, GapReport]) -> dict[str, Any]:
    """``gap``: the gap after the parameter refit, its weighting, paired modes and
    anti-resonances."""
    gap = _gap_dict(reports["refit"], reports.get("refit_unweighted"))
    gap["weighting"] = diag.weighting.get("weighting")
    gap["modes"] = [
        {k: row.get(k) for k in ("f_measured_hz", "f_model_hz", "status", "mac", "df_rel",
                                 "zeta_measured", "zeta_model")}
        for row in diag.modes if "status" in row
    ]  # fmt: skip
    failed = [str(row["error"]) for row in diag.modes if "error" in row]
    if failed:  # why ``modes`` holds no measured mode (spec extension)
        gap["modes_error"] = failed[0]
    gap["antiresonances"] = diag.antiresonances
    return gap


def _stages_section(diag: Diagnosis, reports: dict[str, GapReport]) -> dict[str, Any]:
    """``stages``: the gap of the nominal model, after the parameter refit and after the
    effects, and the shares closed."""
    before, nominal = reports["refit"].db_rms, reports["nominal"].db_rms
    w = diag.winner
    return {
        "nominal": _gap_dict(reports["nominal"], reports.get("nominal_unweighted")),
        "refit": _gap_dict(reports["refit"], reports.get("refit_unweighted")),
        "effect": _gap_dict(reports["effect"], reports.get("effect_unweighted"))
        if "effect" in reports
        else None,
        "gap_closed_by_refit": gap_closed(nominal, before),
        "gap_closed_total": gap_closed(nominal, w.db_rms if w else before),
    }


def _refit_section(diag: Diagnosis) -> dict[str, Any]:
    """``refit``: the parameter refit's values and figures."""
    b = diag.baseline
    return {
        "parameters": _parameter_rows(b),
        "free": diag.names,
        "status": b.status,
        "starts": [
            {
                "label": a.label,
                "noise_ratio": a.ratio,
                "iterations": a.iterations,
                "error": a.error or None,
            }
            for a in b.attempts
        ],
        "stopped": b.stopped or None,
        "heldout_weighted_rms": b.heldout_rms,
        "train_weighted_rms": b.train_rms,
        "score": diag.baseline_score,
    }


def _scoring_section(diag: Diagnosis) -> dict[str, Any]:
    """``scoring``: the verdict rule, its constants and each step's figures."""
    return {
        "score": "held-out information-weighted RMS complex-log error [dB] x FPE factor",
        "rule": scoring.RULE,
        "level_tol": scoring.LEVEL_TOL,
        "z": scoring.Z,
        "min_excess_share": scoring.MIN_EXCESS_SHARE,
        "rel_margin": REL_MARGIN,
        "abs_margin_db": ABS_MARGIN_DB,
        "steps": [
            {"step": st.index + 1, **st.test, "refits_stopped": st.stopped or None}
            for st in diag.steps
        ],
        "elimination": ELIMINATION,
        "elimination_note": diag.pruning.note if diag.pruning is not None else "",
        "gap_closed": "1 - db_rms_after / gap.db_rms (gap after the parameter refit; "
        "both weighted)",
        "db_rms": DB_RMS_DEFINITION,
        "db_rms_points": "used channels, all points, weighted by the information weight",
    }


def to_json_dict(diag: Diagnosis, reports: dict[str, GapReport]) -> dict[str, Any]:
    """The content of ``diagnosis.json`` (module docstring)."""
    before = reports["refit"].db_rms
    out = {
        "gap": _gap_section(diag, reports),
        "candidates": candidate_entries(diag, before),
        "verdict": verdict_entry(
            diag,
            before,
            reports["nominal"].db_rms,
            _gap_dict(reports["effect"], reports.get("effect_unweighted"))
            if "effect" in reports
            else None,
        ),
        "effects": effect_entries(diag, before),
        "dropped": dropped_entries(diag),
        "stages": _stages_section(diag, reports),
        "refit": _refit_section(diag),
        "channels": diag.channels,
        "bands": [list(x) for x in diag.bands],
        "modes_by_dataset": diag.modes_by_dataset,
        "split": diag.split_info,
        "scoring": _scoring_section(diag),
        "weighting": diag.weighting,
        "lines": diag.lines,
        "final_fit": _final_section(diag),
        "remainder": diag.remainder.as_dict() if diag.remainder is not None else None,
        "wall_s": diag.wall_s,
    }
    return _num(out)


def _final_section(diag: Diagnosis) -> dict[str, Any] | None:
    """``final_fit`` (spec extension): the final model refitted on all data
    (:mod:`.final_fit`); its file is ``final.urdf``."""
    f = diag.final
    if f is None:
        return None
    m = f.model
    return {
        "effects": [{"effect": c.effect, "location": c.location, "detail": d or None}
                    for c, d in zip(f.source.chain, _details(m), strict=True)],
        "kept": f.kept, "note": f.note, "starts": f.starts or None,
        "db_rms_before": f.source.db_rms, "db_rms": m.db_rms,
        "db_rms_unweighted": m.db_rms_unweighted, "file": "final.urdf",
        "parameters": _parameter_rows(m),
    }  # fmt: skip


def _details(m: JobResult) -> list[str]:
    """What the model ``m`` says of each of its effects beyond their parameters (e.g. where
    a rotation pivots, :meth:`~.effects.base.Effect.detail`), in the order of its chain."""
    if not m.chain or not m.urdf:
        return [""] * len(m.chain)
    from ..model.document import UrdfDocument
    from .effects import get_effect

    doc = UrdfDocument.from_string(m.urdf, source="final model")
    return [get_effect(c.effect).detail(doc, c) for c in m.chain]


def _parameter_rows(r: JobResult) -> list[dict[str, Any]]:
    """``[{name, value, std}]`` of a refit's variables (SI)."""
    return [{"name": n, "value": float(v), "std": float(e)}
            for n, v, e in zip(r.names, r.values, r.std, strict=True)]  # fmt: skip


def write_outputs(
    diag: Diagnosis, out_dir: Path, *, plots: bool = True, warnings: Sequence[str] = ()
) -> list[Path]:
    """Write diagnosis.json (with the input ``warnings``), refit.urdf, augmented.urdf (the
    winner), final.urdf (the final model refitted on all data), residual map and Bode PNGs."""
    out_dir.mkdir(parents=True, exist_ok=True)
    reports = gaps(diag)
    content = to_json_dict(diag, reports)
    content["warnings"] = list(warnings)
    written = [write_text_atomic(out_dir / "diagnosis.json", json.dumps(content, indent=2) + "\n")]

    def urdf(name: str, text: str) -> None:
        # a free pivot written as the joint's own pivot; the meshes named as the user did
        text = restore_mesh_names(settled_text(text, name), diag.mesh_names)
        written.append(write_text_atomic(out_dir / name, text))

    urdf("refit.urdf", diag.baseline.urdf)
    if diag.winner is not None and diag.winner.urdf:
        urdf("augmented.urdf", diag.winner.urdf)
    kept = kept_effects(diag)
    if len(kept) > 1 and kept[-1].model.urdf:  # every kept effect built in
        urdf("augmented_all.urdf", kept[-1].model.urdf)
    if diag.final is not None and diag.final.model.urdf:
        urdf("final.urdf", diag.final.model.urdf)
    if plots:
        written += _plots(diag, reports, out_dir)
    return written


def write_plots(diag: Diagnosis, out_dir: Path) -> list[Path]:
    """Write the residual map and the Bode PNGs of ``diag`` into ``out_dir`` (they do not
    depend on the final fit: ``bondid.diagnose`` draws them while a worker runs it)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    return _plots(diag, gaps(diag), out_dir)


def _plots(diag: Diagnosis, reports: dict[str, GapReport], out_dir: Path) -> list[Path]:
    from ..data.weights import noise_estimate
    from ..plots import Curve, noise_curve, plot_bode, plot_residual_map

    out = []
    g = reports["refit"]
    out.append(
        plot_residual_map(
            g.freq_hz, g.residual_db, channels=g.channels, path=out_dir / "residual_map.png",
            title="Remaining gap after the parameter refit (model − measured)",
            bands=diag.bands, cbar_label="model − measured [dB]",
        )
    )  # fmt: skip
    best = diag.winner or (diag.results[0] if diag.results and not diag.results[0].error else None)
    for k, d in enumerate(diag.datasets):
        curves = [
            Curve("measured", d.H, kind="measured"),
            Curve("nominal", diag.nominal_H[k]),
            Curve("parameter refit", diag.baseline.full_H[k]),
        ]
        if best is not None:
            tag = "with effect" if best is diag.winner else "best candidate (not retained)"
            # a refit without a dropped effect carries no candidate label: its first effect's
            label = best.chain[0].label if best is diag.winner and best.chain else best.label
            curves.append(Curve(f"{tag}: {label}", best.full_H[k]))
        curves.append(noise_curve(noise_estimate(d).sigma))
        out.append(
            plot_bode(
                d.freq_hz, curves, outputs=d.outputs, inputs=d.inputs,
                path=out_dir / f"bode_{k + 1}.png",
                title=f"Data set {k + 1} at {d.operating_point or 'neutral'}",
            )
        )  # fmt: skip
    return out
