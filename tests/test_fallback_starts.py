"""The fit's last tier (run_multistart's fallback_starts): a single-start fit that still
ends in another basin after its fallbacks gets the other starts of a multistart; known answer
on synthetic bonder data, and the setting's plumbing."""

from __future__ import annotations

import math

import pytest
from test_fit import FAR_SEEDS, REL, perturbed_start, synth

from bondid.fit import default_bounds
from bondid.fit.multistart import STARTS_RATIO, run_multistart
from bondid.model import UrdfDocument, get_parameters, select_parameters, set_parameters
from bondid.optim import FitProblem
from bondid.optim.fallback import noise_ratio
from bondid.optim.schedules import Strategy

#: the noise level's tolerance: within this factor of the truth model's own db_rms (issue 12)
WITHIN = 1.10
#: starts of the tier in these tests (the default of --fallback-starts)
N_STARTS = 4


@pytest.fixture(scope="module")
def stuck() -> dict:
    """The bonder's 22 identifiable parameters, the model's values 30 % off (FAR_SEEDS[0]);
    2 % noise. The band continuation and the staged schedule are switched off, so the
    single-start fit (direct, resumed) stays in another basin (measured: 3.87× the level)."""
    import bondid.optim.fallback as fallback

    truth_doc = UrdfDocument.load("urdf/bonder.urdf")
    names = select_parameters(
        truth_doc, ["parasitic", "x_stage.mass", "y_stage.mass", "z_stage.mass",
                    "x_stage.com.z", "y_stage.inertia.ixx", "z_stage.inertia.ixx"],
    )  # fmt: skip
    data = synth(truth_doc, 300, noise_seed=11)
    doc = UrdfDocument.load("urdf/bonder.urdf")
    far = perturbed_start(truth_doc, names, FAR_SEEDS[0], 0.3)
    set_parameters(doc, dict(zip(names, far, strict=True)))
    lo, hi = default_bounds(doc, names, rel=REL)
    truth = FitProblem(truth_doc, data, names, lower=lo, upper=hi,
                       start=get_parameters(truth_doc, names))  # fmt: skip
    kw = {"lower": lo, "upper": hi, "strategy": Strategy(prior_width=0)}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(fallback, "_fallbacks", lambda *args: [])
        # in 2 worker processes (forked: they inherit the patch), as the command runs it
        tier = run_multistart(
            doc, data, names, n_starts=1, workers=2, fallback_starts=N_STARTS, **kw
        )  # fmt: skip
    return {"doc": doc, "data": data, "names": names, "kw": kw, "tier": tier,
            "truth_cost": truth.data_cost(truth.z0), "problem": truth}  # fmt: skip


def test_a_fit_stuck_above_the_level_gets_the_other_starts(stuck: dict) -> None:
    """The tier runs every start and keeps the lowest. Whether one of 3 Latin-hypercube
    starts in a 22-dimensional box lands in the truth's basin is luck, and it differs between
    machines (IPOPT's path follows the BLAS's rounding): one reached the truth model's level
    where this test was written; on an AMD EPYC they ended at 2.50×, 6.59× and 3.02× the
    level against start 0's 3.87×. So the test asks for the lowest run, below start 0's."""
    tier = stuck["tier"]
    first = tier.runs[0].result  # the single search (start 0, the model's values)
    ratio = noise_ratio(stuck["problem"], first.cost_final)
    assert ratio is not None and ratio > STARTS_RATIO  # the premise
    assert [r.index for r in tier.runs] == list(range(N_STARTS))
    costs = [r.result.cost_final for r in tier.runs if r.result is not None]
    assert len(costs) == N_STARTS
    assert tier.best_index != 0
    assert tier.best.cost_final == min(costs) < first.cost_final
    # and no run went below what the exact model scores (the truth bounds every start)
    assert math.sqrt(min(costs)) >= math.sqrt(stuck["truth_cost"]) / WITHIN
    note = tier.best.notes[-1]
    assert note.startswith("fallback starts: the fit ended at") and "kept start" in note
    assert tier.best.notes[-2] == first.notes[-1]  # start 0's fallback note kept
    assert tier.spread()["n_runs"] == N_STARTS


def test_no_fallback_starts_at_the_level_or_when_off(stuck: dict) -> None:
    """A fit at the noise level (from the model's own values, the truth here) and a tier
    switched off (fewer than 2 starts) run one search."""
    kw = {**stuck["kw"], "n_starts": 1, "workers": 1}
    truth_doc = UrdfDocument.load("urdf/bonder.urdf")
    at_level = run_multistart(truth_doc, stuck["data"], stuck["names"], fallback_starts=4, **kw)
    assert len(at_level.runs) == 1
    assert not any("fallback" in n for n in at_level.best.notes)
    import bondid.optim.fallback as fallback

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(fallback, "_fallbacks", lambda *args: [])
        off = run_multistart(stuck["doc"], stuck["data"], stuck["names"], fallback_starts=1, **kw)
    assert len(off.runs) == 1 and off.best.cost_final == stuck["tier"].runs[0].cost


def test_fallback_starts_setting(tmp_path) -> None:
    from bondid.exceptions import ConfigError
    from bondid.fit.cli import build_parser, resolve_settings
    from bondid.fit.study import StudySettings, study_from_dict

    assert StudySettings().fallback_starts == N_STARTS
    s = study_from_dict({"model": "m.urdf", "data": ["d.csv"], "search": {"fallback_starts": 0}})
    assert s.fallback_starts == 0 and s.to_json_dict()["fallback_starts"] == 0
    with pytest.raises(ConfigError):
        study_from_dict({"model": "m.urdf", "data": ["d.csv"], "search": {"fallback_starts": -2}})
    argv = ["--model", "m.urdf", "--data", "d.csv", "--fallback-starts", "6"]
    assert resolve_settings(build_parser().parse_args(argv)).fallback_starts == 6
