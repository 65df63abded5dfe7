"""The noise-level fallback (bondid.optim.fallback): a direct fit that ends above the predicted
noise level is followed by the band continuation, which reaches the truth model's own score."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_fit import FAR_SEEDS, REL, perturbed_start, synth

from bondid.fit import default_bounds, fit
from bondid.model import UrdfDocument, get_parameters, select_parameters
from bondid.optim import FitProblem, run_to_noise
from bondid.optim.fallback import ITERATION_LIMIT, NOISE_MARGIN, noise_ratio, resume
from bondid.optim.schedules import Strategy, direct
from bondid.optim.search import run_search

#: "at the noise level": within this factor of the truth model's own db_rms (issue 12)
WITHIN = 1.10


@pytest.fixture(scope="module")
def case() -> dict:
    """The bonder's 16 parasitic and 6 inertial parameters, every one 30 % off (random signs),
    2 % relative noise on 300 lines at two poses; the truth model's own data cost."""
    doc = UrdfDocument.load("urdf/bonder.urdf")
    names = select_parameters(
        doc, ["parasitic", "x_stage.mass", "y_stage.mass", "z_stage.mass", "x_stage.com.z",
              "y_stage.inertia.ixx", "z_stage.inertia.ixx"],
    )  # fmt: skip
    data = synth(doc, 300, noise_seed=11)
    lo, hi = default_bounds(doc, names, rel=REL)
    truth = get_parameters(doc, names)
    start = perturbed_start(doc, names, seed=FAR_SEEDS[0], inertial=0.3)
    p_truth = FitProblem(doc, data, names, lower=lo, upper=hi, start=truth)
    return {"doc": doc, "names": names, "data": data, "lo": lo, "hi": hi, "start": start,
            "truth_cost": p_truth.data_cost(p_truth.z0), "problem": p_truth}  # fmt: skip


def test_noise_ratio_of_the_truth_is_near_one(case: dict) -> None:
    """The criterion is computed from the data alone: the truth scores about the prediction."""
    ratio = noise_ratio(case["problem"], case["truth_cost"])
    assert ratio is not None and 0.8 < ratio < NOISE_MARGIN, ratio


def test_direct_fit_above_the_noise_falls_back_to_the_continuation(case: dict) -> None:
    kw = {"start": case["start"], "lower": case["lo"], "upper": case["hi"]}
    alone = fit(case["doc"], case["data"], case["names"], fallback_bands=0, **kw)
    truth_db = math.sqrt(case["truth_cost"])
    # the premise: the direct fit alone ends in another basin, above the noise level
    assert math.sqrt(alone.cost_final) > 1.5 * truth_db, (alone.cost_final, case["truth_cost"])
    assert not any("fallback" in n for n in alone.notes)
    res = fit(case["doc"], case["data"], case["names"], fallback_bands=8, **kw)
    assert math.sqrt(res.cost_final) <= WITHIN * truth_db, (res.cost_final, case["truth_cost"])
    note = [n for n in res.notes if n.startswith("fallback:")]
    assert note and "kept the band continuation" in note[0], res.notes
    assert res.iterations > alone.iterations


def test_no_fallback_at_the_noise_level(case: dict) -> None:
    """A search that ends at the noise level runs nothing more (same result, no note)."""
    p = FitProblem(case["doc"], case["data"], case["names"], lower=case["lo"],
                   upper=case["hi"], start=get_parameters(case["doc"], case["names"]))  # fmt: skip
    res = run_to_noise(p, direct(), fallback_bands=8).result
    assert not any("fallback" in n for n in res.notes), res.notes
    assert math.sqrt(res.cost_final) <= WITHIN * math.sqrt(case["truth_cost"])


def test_strategy_fallback_bands() -> None:
    assert Strategy().fallback_bands == 8
    assert Strategy(continuation=4).fallback_bands == 0  # already the continuation
    assert Strategy(staged=True, fallback=0).fallback_bands == 0
    assert np.isfinite(NOISE_MARGIN)


def test_fallback_setting_from_the_study_and_the_command_line(tmp_path) -> None:
    from bondid.exceptions import ConfigError
    from bondid.fit.cli import build_parser, resolve_settings
    from bondid.fit.study import StudySettings, study_from_dict

    assert StudySettings().fallback == 8
    s = study_from_dict({"model": "m.urdf", "data": ["d.csv"], "search": {"fallback": 0}})
    assert s.fallback == 0 and s.to_json_dict()["fallback"] == 0
    with pytest.raises(ConfigError):
        study_from_dict({"model": "m.urdf", "data": ["d.csv"], "search": {"fallback": -1}})
    args = build_parser().parse_args(["--model", "m.urdf", "--data", "d.csv", "--fallback", "4"])
    assert resolve_settings(args).fallback == 4


#: IPOPT iterations after which the direct fit (no presolve) from the near start is stopped:
#: it needs 42 to converge (measured), so it stops at its limit far above the noise level
SHORT = 12


@pytest.fixture(scope="module")
def near(case: dict) -> dict:
    """The near start (±30 % on joints, ±10 % inertial) and the converged fit from it."""
    start = perturbed_start(case["doc"], case["names"], seed=5, inertial=0.1)
    p = FitProblem(case["doc"], case["data"], case["names"], lower=case["lo"],
                   upper=case["hi"], start=start)  # fmt: skip
    return {"problem": p, "full": run_search(p, direct(0))}


def test_resume_continues_a_search_stopped_at_its_iteration_limit(case: dict, near: dict) -> None:
    p, full = near["problem"], near["full"]
    assert full.result.status == "Solve_Succeeded" and full.result.iterations > SHORT
    short = run_search(p, direct(0), max_iter=SHORT)
    assert short.result.status == ITERATION_LIMIT
    assert noise_ratio(p, short.result.cost_final) > 2 * NOISE_MARGIN  # the premise
    more = resume(p, short, max_iter=SHORT)
    # the same minimum as the uninterrupted fit, with the search's own start kept
    assert more.result.cost_final == pytest.approx(full.result.cost_final, rel=1e-6)
    assert more.result.cost_initial == short.result.cost_initial
    np.testing.assert_array_equal(more.result.initial, short.result.initial)
    assert [s.name for s in more.steps] == ["all", "all, resumed"]
    assert len(more.result.cost_history) > len(short.result.cost_history)


def test_run_to_noise_resumes_the_kept_search(
    case: dict, near: dict, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A search stopped at its limit above the noise level that no fallback improves (here:
    none runs) is resumed and reaches the uninterrupted fit's minimum; the note says so."""
    import bondid.optim.fallback as fallback

    monkeypatch.setattr(fallback, "_fallbacks", lambda *args: [])
    p = near["problem"]
    res = run_to_noise(p, direct(0), max_iter=SHORT, fallback_bands=8).result
    note = [n for n in res.notes if n.startswith("fallback:")]
    assert note and "the first search resumed from its end point ended at 1.0" in note[0]
    assert note[0].endswith("kept the first search, resumed")
    assert math.sqrt(res.cost_final) <= WITHIN * math.sqrt(case["truth_cost"])
    assert res.cost_final == pytest.approx(near["full"].result.cost_final, rel=1e-6)
    assert res.iterations > SHORT  # both solves counted
