"""What a fit writes under ``--out``: ``fit.json``, ``fitted.urdf`` and PNG plots.

Every file is written atomically (:mod:`bondid.atomic`); no output may be one of the inputs.

* ``fit.json`` — :meth:`FitResult.to_json_dict` (spec keys ``status``, ``cost_initial``,
  ``cost_final``, ``cost_name``, ``iterations``, ``wall_s``, ``parameters``, plus the correlation
  matrix and the active constraints), and ``multistart`` (spread of the final costs),
  ``stages`` (staged fit), ``settings`` (every setting used), ``model_file``, ``data_files``,
  ``db_rms`` (before/after, total, per channel and per data set) and ``outputs``.
* ``fitted.urdf`` — the fitted model (the input URDF is never touched).
* ``bode_<data-stem>.png`` — measured, initial model and fitted model per data set.
* ``convergence.png`` — cost per iteration of every run.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..atomic import refuse_overwrite, write_text_atomic
from ..cost.problem import CostOptions, used_points
from ..cost.residuals import DB
from ..data.measurement import FrfData
from ..exceptions import ConfigError
from ..frf.aligned import model_frf
from ..jsonsafe import json_safe
from ..model.document import UrdfDocument

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..optim.result import FitResult

FIT_JSON = "fit.json"
FITTED_URDF = "fitted.urdf"
CONVERGENCE_PNG = "convergence.png"


def bode_names(datasets: Sequence[FrfData]) -> list[str]:
    """``bode_<stem>.png`` per data set (a numeric suffix keeps repeated stems apart)."""
    stems = [Path(ds.source).stem if ds.source else f"data{i}" for i, ds in enumerate(datasets)]
    out = []
    for i, s in enumerate(stems):
        out.append(f"bode_{s}.png" if stems.count(s) == 1 else f"bode_{s}_{i}.png")
    return out


def output_paths(out_dir: Path, datasets: Sequence[FrfData]) -> list[Path]:
    """Every file a fit writes under ``out_dir``."""
    names = [FIT_JSON, FITTED_URDF, CONVERGENCE_PNG, *bode_names(datasets)]
    return [out_dir / n for n in names]


def check_out_dir(
    out_dir: str | os.PathLike[str],
    inputs: Sequence[str | os.PathLike[str]],
    datasets: Sequence[FrfData] = (),
) -> Path:
    """Refuse an ``--out`` that is an input file or would overwrite one.

    Raises:
        ConfigError: ``out_dir`` is an existing file, or one of its outputs is an input.
    """
    out = Path(out_dir)
    refuse_overwrite(out, inputs)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{out}: --out must be a folder, and this is a file")
    for p in output_paths(out, datasets):
        refuse_overwrite(p, inputs)
    return out


#: plain JSON values for fit.json (the one converter, :func:`bondid.jsonsafe.json_safe`)
jsonable = json_safe


def _units(doc: UrdfDocument, joints: Sequence[str]) -> dict[str, Any]:
    from ..model.points import plot_units

    return plot_units(doc, joints)


def _sq_db(Hs: np.ndarray, Hm: np.ndarray) -> np.ndarray:
    """Per point ``((20/ln10)|ln(Hm/Hs)|)²`` with the phase wrapped to (−π, π]; NaN where
    either FRF is zero or not finite (no finite figure there: :func:`no_figure_reason`)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        L = np.log(Hm / Hs)
        ph = np.pi - np.mod(np.pi - L.imag, 2.0 * np.pi)
        e = DB**2 * (L.real**2 + ph**2)
    return np.where(np.isfinite(e), e, np.nan)


def no_figure_reason(Hs: np.ndarray, Hm: np.ndarray) -> str:
    """Why the dB error of a channel (model ``Hs``, measured ``Hm``, ``(n,)``) is not finite
    at some of its points ("" when it is finite everywhere)."""
    bad = ~np.isfinite(_sq_db(Hs, Hm))
    if not bad.any():
        return ""
    where = "at every frequency" if bad.all() else f"at {int(bad.sum())} of {bad.size} frequencies"
    if np.any(~np.isfinite(Hs[bad])):
        why = "the model's FRF is not finite (a singular dynamic stiffness: a mode at 0 Hz?)"
    elif np.any(Hs[bad] == 0):
        why = "the model's FRF is zero (the model has no path from this input to this output)"
    else:
        why = "the measured FRF is zero"
    return f"{why} {where}; those points are left out of the figures"


#: coherence from which a point counts in the ``coherent`` db_rms figure
COHERENT = 0.5


#: how the headline ``db_rms`` is defined (written into fit.json)
DB_RMS_DEFINITION = (
    "db_rms = sqrt(sum(w * e^2) / sum(w)) over the used points, e = (20/ln 10)|ln(H_meas/H_model)|"
    " (phase wrapped), w = the point's information weight (see 'weighting'); "
    "db_rms_unweighted: the same with w = 1"
)


def _wrms(e: list[np.ndarray], w: list[np.ndarray]) -> float | None:
    """``sqrt(Σ w e² / Σ w)`` over the concatenated points with a finite error (None when
    no such point has weight)."""
    if not e:
        return None
    ee, ww = np.concatenate(e), np.concatenate(w)
    ok = np.isfinite(ee)
    ee, ww = ee[ok], ww[ok]
    tot = float(ww.sum())
    return float(np.sqrt(np.sum(ww * ee) / tot)) if ee.size and tot > 0 else None


def _rms(e: list[np.ndarray]) -> float | None:
    return _wrms(e, [np.ones(x.size) for x in e])


class _Errors:
    """Squared dB errors and weights gathered over data sets, for :func:`db_rms_report`."""

    def __init__(self) -> None:
        self.E: dict[str, list[np.ndarray]] = {"initial": [], "final": []}
        self.W: list[np.ndarray] = []
        self.noise: list[np.ndarray] = []  # expected squared dB error of an exact model
        self.coh: dict[str, list[np.ndarray]] = {"initial": [], "final": []}
        self.per_ch: dict[str, dict[str, list[np.ndarray]]] = {}
        self.n_all = 0
        self.no_figure: list[str] = []  # "channel in file: why" for non-finite errors

    def add(
        self, ds: FrfData, frfs: tuple[np.ndarray, np.ndarray], mask: np.ndarray, w: np.ndarray
    ) -> dict[str, Any]:
        """One data set's points (``mask``, weights ``w`` ``(n_out, n_in, n_freq)``); returns
        its ``by_dataset`` entry."""
        entry: dict[str, Any] = {"file": ds.source, "by_channel": {}}
        good = mask.copy()
        if ds.coherence is not None:
            good &= np.nan_to_num(ds.coherence, nan=1.0) >= COHERENT
        self.n_all += int(mask.sum())
        self.W.append(w[mask])
        for label, H in zip(("initial", "final"), frfs, strict=True):
            e = _sq_db(H[mask], ds.H[mask])
            entry[label] = _wrms([e], [w[mask]])
            entry[f"{label}_unweighted"] = _rms([e])
            self.E[label].append(e)
            self.coh[label].append(_sq_db(H[good], ds.H[good]))
            self._channels(ds, H, mask, w, label, entry["by_channel"])
        return entry

    def _channels(
        self, ds: FrfData, H: np.ndarray, mask: np.ndarray, w: np.ndarray, label: str,
        out: dict[str, dict[str, Any]],
    ) -> None:  # fmt: skip
        for a, o in enumerate(ds.outputs):
            for b, i in enumerate(ds.inputs):
                m = mask[a, b]
                if not m.any():
                    continue
                ch = f"{o}.{i}"
                ec = _sq_db(H[a, b, m], ds.H[a, b, m])
                slot = out.setdefault(ch, {})
                why = no_figure_reason(H[a, b, m], ds.H[a, b, m])
                if why:
                    slot[f"{label}_no_figure"] = why
                    name = Path(ds.source).name if ds.source else "data"
                    self.no_figure.append(f"{ch} in {name} ({label} model): {why}")
                slot[label] = _wrms([ec], [w[a, b, m]])
                slot[f"{label}_unweighted"] = _rms([ec])
                acc = self.per_ch.setdefault(ch, {"initial": [], "final": [], "w": []})
                acc[label].append(ec)
                if label == "initial":
                    acc["w"].append(w[a, b, m])

    def by_channel(self) -> dict[str, dict[str, float | None]]:
        out = {}
        for ch, d in self.per_ch.items():
            row = {k: _wrms(d[k], d["w"]) for k in ("initial", "final")}
            row.update({f"{k}_unweighted": _rms(d[k]) for k in ("initial", "final")})
            out[ch] = row
        return out


def db_rms_report(
    initial: UrdfDocument,
    fitted: UrdfDocument,
    datasets: Sequence[FrfData],
    options: CostOptions,
    model_frfs: list[tuple[np.ndarray, np.ndarray]] | None = None,
) -> dict[str, Any]:
    """The ``db_rms`` before and after over the points the fit used, weighted (headline) and
    unweighted (the spec's plain figure).

    Returns:
        ``{"initial", "final", "weighting", "definition", "unweighted": {"initial", "final"},
        "by_channel": {ch: {"initial", "final", "initial_unweighted", "final_unweighted"}},
        "by_dataset": [{"file", "initial", "final", "initial_unweighted",
        "final_unweighted", "by_channel"}], "coherent": {"initial", "final", "fraction",
        "min_coherence"}, "noise_level", "no_figure"}`` (dB). Points where the model's or the
        measured FRF is zero or not finite have no dB error: they are left out of every
        figure, and ``no_figure`` lists each such channel and why (a channel entry then has
        ``initial_no_figure`` / ``final_no_figure``). ``noise_level``: the weighted figure an exact
        model would score on these data (:mod:`bondid.cost.noise_level`; whatever the cost
        the fit minimised: ``db_rms`` is always the complex-log figure).
        ``initial``/``final`` are ``sqrt(Σ w e² / Σ w)`` with ``w``
        the information weight of :attr:`CostOptions.effective_weighting` (so noise-only
        points barely count); ``coherent`` is the unweighted figure over the points whose
        measured coherence is at least :data:`COHERENT` (all points without coherence).
    """
    from ..cost.noise_level import expected_sq_db, weighted_level
    from ..data.weights import information_weights

    weighting = options.effective_weighting
    frfs = model_frfs or [(model_frf(initial, ds), model_frf(fitted, ds)) for ds in datasets]
    acc = _Errors()
    by_ds = []
    for ds, H01 in zip(datasets, frfs, strict=True):
        mask = used_points(ds, options)
        acc.noise.append(expected_sq_db(ds, options.use_coherence)[mask])
        w = np.nan_to_num(information_weights(ds, weighting), nan=0.0)
        by_ds.append(acc.add(ds, H01, mask, w))
    n_good = sum(x.size for x in acc.coh["final"])
    return {
        "initial": _wrms(acc.E["initial"], acc.W),
        "final": _wrms(acc.E["final"], acc.W),
        "noise_level": weighted_level(acc.noise, acc.W),
        "weighting": weighting,
        "definition": DB_RMS_DEFINITION,
        "unweighted": {"initial": _rms(acc.E["initial"]), "final": _rms(acc.E["final"])},
        "by_channel": acc.by_channel(),
        "by_dataset": by_ds,
        "no_figure": acc.no_figure,
        "coherent": {
            "initial": _rms(acc.coh["initial"]),
            "final": _rms(acc.coh["final"]),
            "fraction": n_good / acc.n_all if acc.n_all else None,
            "min_coherence": COHERENT,
        },
    }


def write_outputs(
    out_dir: str | os.PathLike[str],
    *,
    result: FitResult,
    initial_doc: UrdfDocument,
    datasets: Sequence[FrfData],
    options: CostOptions,
    inputs: Sequence[str | os.PathLike[str]],
    histories: Sequence[Sequence[float]] = (),
    history_labels: Sequence[str] | None = None,
    extra: Mapping[str, Any] | None = None,
    file_quantities: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Write every output of a fit under ``out_dir`` and return the ``fit.json`` content.

    Args:
        out_dir: results folder (created if missing).
        result: the fit (its ``document`` is the fitted model).
        initial_doc: the model before the fit (for the "initial" Bode curves).
        datasets: the measured data, one Bode plot each.
        options: the cost options (their bands/channels define the db_rms points).
        inputs: every input file (none may be overwritten).
        histories: cost per iteration of each run, for ``convergence.png``.
        history_labels: a label per history.
        extra: more top-level keys for ``fit.json`` (settings, multistart, stages, ...).
        file_quantities: the quantity each data file holds (the Bode plots are drawn in
            it); default: that of ``datasets``.

    Returns:
        The dictionary written as ``fit.json``.

    Raises:
        ConfigError: an output would overwrite an input.
    """
    from ..data.weights import weighting_summary

    out = check_out_dir(out_dir, inputs, datasets)
    out.mkdir(parents=True, exist_ok=True)
    frfs = [(model_frf(initial_doc, ds), model_frf(result.document, ds)) for ds in datasets]
    quantities = list(file_quantities or [ds.quantity for ds in datasets])
    written = _bode_plots(out, datasets, frfs, initial_doc, quantities, options)
    written += _convergence_plot(out, result.cost_name, histories, history_labels)
    result.document.write(out / FITTED_URDF)
    written.append(FITTED_URDF)
    content = dict(result.to_json_dict())
    _add_units(content, initial_doc)
    content.update(extra or {})
    content["data_files"] = [ds.source for ds in datasets]
    content["db_rms"] = db_rms_report(initial_doc, result.document, datasets, options, frfs)
    content["db_rms_unweighted"] = content["db_rms"]["unweighted"]
    content["weighting"] = weighting_summary(list(datasets), options.effective_weighting)
    content["outputs"] = [*written, FIT_JSON]
    write_text_atomic(out / FIT_JSON, json.dumps(jsonable(content), indent=2) + "\n")
    return content


def _add_units(content: dict[str, Any], doc: UrdfDocument) -> None:
    """Each parameter entry's SI ``unit`` (spec extension of fit.json)."""
    from ..model.parameters import parameter_infos

    units = {p.name: p.unit for p in parameter_infos(doc)}
    for p in content.get("parameters", []):
        if p.get("name") in units:
            p["unit"] = units[p["name"]]


def _bode_plots(
    out: Path,
    datasets: Sequence[FrfData],
    frfs: Sequence[tuple[np.ndarray, np.ndarray]],
    doc: UrdfDocument,
    quantities: Sequence[str],
    options: CostOptions,
) -> list[str]:
    """``bode_<stem>.png`` per data set, in the quantity of its file: measured, initial and
    fitted model, noise level; the channels the fit left out greyed."""
    from ..data.quantity import quantity_factor
    from ..data.weights import noise_estimate
    from ..plots import Curve, noise_curve, plot_bode

    written = []
    items = zip(datasets, frfs, bode_names(datasets), quantities, strict=True)
    for ds, (H0, H1), name, q in items:
        op = " ".join(f"{k}={v:g}" for k, v in ds.operating_point.items()) or "neutral"
        g = quantity_factor(ds.freq_hz, q) / quantity_factor(ds.freq_hz, ds.quantity)
        curves = [
            Curve("measured", ds.H * g, kind="measured"),
            Curve("initial model", H0 * g, style={"linestyle": "--"}),
            Curve("fitted model", H1 * g),
            noise_curve(noise_estimate(ds).sigma * np.abs(g)),
        ]
        names = options.channels_for(ds)
        left = [c for c in ds.channels if names is not None and c not in names]
        plot_bode(
            ds.freq_hz, curves, outputs=ds.outputs, inputs=ds.inputs, path=out / name,
            title=f"{Path(ds.source).name if ds.source else name}: operating point {op}",
            quantity=q, units=_units(doc, [*ds.outputs, *ds.inputs]), left_out=left,
        )  # fmt: skip
        written.append(name)
    return written


def _convergence_plot(
    out: Path,
    cost_name: str,
    histories: Sequence[Sequence[float]],
    history_labels: Sequence[str] | None,
) -> list[str]:
    """``convergence.png`` of the runs with a history (``[]`` when none has one)."""
    from ..plots import plot_convergence

    runs = [list(h) for h in histories if len(h) > 0]
    if not runs:
        return []
    labels = None
    if history_labels is not None:
        labels = [lb for lb, h in zip(history_labels, histories, strict=True) if len(h) > 0]
    plot_convergence(
        runs, path=out / CONVERGENCE_PNG, labels=labels, title=f"Convergence ({cost_name})"
    )
    return [CONVERGENCE_PNG]
