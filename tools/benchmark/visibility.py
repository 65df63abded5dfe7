"""Is a case's withheld effect in its data at all? The oracle parameter-only refit.

A case tests the diagnosis's naming of an effect only if the effect shows in the case's data:
if the best *parameter-only* model fits the files as well as the truth itself does, the
data say "none" and no diagnosis can name the effect (its verdict rule's first condition,
the base above the noise level, refuses every candidate, and rightly). This module measures
that with an **oracle**: the diagnosis's own parameter refit (:func:`bondid.diagnose.pipeline.
_baseline_task`, the same data preparation, weights, split, bounds and prior) started at the
truth's own parameter values (its random errors, without its effect), which the diagnosis
never sees. ``ratio`` is that refit's weighted gap on all data over the truth model's own,
the same figures as the benchmark rows' ``gap_refit`` and ``db_truth``.

A case is **visible** when ``ratio ≥`` :data:`VISIBLE`. Where it is not, :func:`visible_case`
strengthens its effects by a fixed rule (:func:`stronger`: structural effects' frequencies
× :data:`STRUCTURAL_STEP`, signal effects' times × :data:`SIGNAL_STEP`) and tries again, up to
:data:`MAX_TRIES` times; the case keeps its name, design, regime and seeds. The rule looks at
the truth and the files only, never at a diagnosis.

Why 1.2: over the benchmark's cases, the "none" cases' parameter refits end at 1.00–1.07× the
truth's gap, effects whose modes sit under a harsh noise floor at about 1.05×, every other
effect case at ≥ 1.50×. 1.2 lies in that empty interval, above what parameter errors alone
leave and below every effect that shows.
"""

from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from .cases import Case
from .designs import design
from .regimes import measure
from .truth import EFFECTS, STRUCTURAL, TruthEffect, signal_factor, strengthen, truth_model

#: an effect shows when the oracle parameter-only refit ends at least this factor above the
#: truth model's own weighted gap (module docstring)
VISIBLE = 1.2
#: one strengthening step: structural effects' frequencies times this
STRUCTURAL_STEP = 0.75
#: one strengthening step: a delay's or a lag's time constant times this
SIGNAL_STEP = 1.5
#: most strengthening steps before the case is reported as invisible
MAX_TRIES = 4
#: the diagnosis's decimation for the oracle refit (its default ``--points``)
POINTS = 500


def frequencies(n: int) -> np.ndarray:
    """The benchmark's frequency grid: ``n`` log-spaced lines from 1 Hz to 4 kHz."""
    return np.logspace(0.0, np.log10(4000.0), n)


def truth_model_db(case: Case, sets: list, channels: list[str]) -> float:
    """The truth model's weighted db_rms [dB] on ``sets`` (data sets whose ``coherence`` holds
    the diagnosis's information weights, in their quantity) over ``channels``."""
    from bondid.diagnose.gap import gap_report
    from bondid.model import UrdfDocument

    from .truth import observed_like

    truth = truth_model(UrdfDocument.load(design(case.design).path), case.effects, case.seed)
    H = [observed_like(truth, case.effects, d) for d in sets]
    return float(gap_report(sets, H, channels=channels, weighting="coherence").db_rms)


def oracle(case: Case, paths: list[Path], points: int = POINTS) -> dict[str, Any]:
    """The oracle refit of ``case`` on its files ``paths`` (module docstring): ``oracle_db``
    (its weighted gap on all data [dB]), ``truth_model_db`` (the truth's), ``ratio``."""
    from bondid.data.io import read_frf
    from bondid.diagnose.job import Task
    from bondid.diagnose.pipeline import Settings, prepare_data
    from bondid.diagnose.refit_job import run_refit
    from bondid.model import UrdfDocument

    nominal = UrdfDocument.load(design(case.design).path)
    s = Settings(n_points=points)
    p = prepare_data(nominal, [read_frf(x) for x in paths], s)
    start = truth_model(nominal, (), case.seed)  # the truth's parameters, no effect
    base = run_refit(Task(start.to_string(), p.space, p.train, p.held, p.full, p.options))
    t = truth_model_db(case, p.full, p.channels)
    return {"oracle_db": float(base.db_rms), "truth_model_db": t, "ratio": float(base.db_rms) / t}


def stronger(effect: TruthEffect) -> TruthEffect:
    """One strengthening step of ``effect`` (module docstring; the later causes:
    :func:`.truth.strengthen`)."""
    if effect.effect not in EFFECTS:
        return strengthen(effect)
    spec = dict(effect.spec)
    if effect.effect in STRUCTURAL:
        spec["f"] = spec["f"] * STRUCTURAL_STEP
    elif "tau" in spec:
        spec["tau"] = spec["tau"] * SIGNAL_STEP
    else:
        spec["T"] = spec["T"] * SIGNAL_STEP
    return replace(effect, spec=spec)


def case_files(case: Case, folder: Path, freq: int) -> tuple[list[Path], list[np.ndarray]]:
    """Measure ``case``'s truth into ``folder`` as the benchmark does (its seeds): the file
    paths and the exact FRFs (in the files' quantity)."""
    from bondid.model import UrdfDocument

    dz = design(case.design)
    truth = truth_model(UrdfDocument.load(dz.path), case.effects, case.seed)

    def factor(ff, outs, ins):
        return signal_factor(case.effects, ff, outs, ins)

    return measure(truth, dz.operating_points, frequencies(freq), case.regime, factor, folder,
                   case.seed, case.effects)  # fmt: skip


def visible_case(case: Case, freq: int, points: int = POINTS) -> tuple[Case, dict[str, Any]]:
    """``case``, strengthened until its effects show (module docstring), and the record of
    the tries: ``visibility`` = a list of ``{"spec": [...], "ratio": ...}``, ``visible``.
    A "none" case and a two-effect case are returned as they are, with no record: the oracle
    refits parameters only, so it cannot tell which of two effects is the one that does not
    show."""
    if len(case.effects) != 1:
        return case, {}
    tries: list[dict[str, Any]] = []
    for k in range(MAX_TRIES + 1):
        with tempfile.TemporaryDirectory(prefix="bondid_visibility_") as tmp:
            paths, _ = case_files(case, Path(tmp), freq)
            o = oracle(case, paths, points)
        tries.append({"spec": [dict(e.spec) for e in case.effects], **o})
        if o["ratio"] >= VISIBLE or k == MAX_TRIES:
            break
        case = replace(case, effects=tuple(stronger(e) for e in case.effects))
    return case, {"visibility": tries, "visible": tries[-1]["ratio"] >= VISIBLE}
