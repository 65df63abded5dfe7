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
from bondid.optim.fallback import NOISE_MARGIN, noise_ratio
from bondid.optim.schedules import Strategy, direct

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
