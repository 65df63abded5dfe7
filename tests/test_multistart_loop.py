"""The one way out of a bad basin (bondid.optim.multistart.keep_best): its stopping rules on a
scripted runner, and on the bonder, a direct fit stuck above the noise level that the band
continuation start gets out of, a search stopped at its iteration limit that is resumed."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from test_fit import FAR_SEEDS, REL, perturbed_start, synth

from bondid.exceptions import SolverError
from bondid.fit import default_bounds, fit
from bondid.model import UrdfDocument, get_parameters, select_parameters
from bondid.optim import FitProblem
from bondid.optim.multistart import (
    ITERATION_LIMIT,
    MATERIAL,
    PATIENCE,
    Attempt,
    Budget,
    Start,
    keep_best,
    random_starts,
    search_runner,
)
from bondid.optim.noise import AT_LEVEL, NoisePolicy
from bondid.optim.schedules import Strategy, direct
from bondid.optim.search import run_search

#: "at the noise level": within this factor of the truth model's own db_rms
WITHIN = 1.10


class _Scripted:
    """A runner that ends each start at the objective the script gives it (by label)."""

    def __init__(self, objectives: dict[str, float], iterations: int = 10):
        self.objectives, self.iterations, self.ran = objectives, iterations, []

    def __call__(self, start: Start, max_iter: int) -> Attempt:
        self.ran.append(start.label)
        obj = self.objectives[start.label]
        if math.isnan(obj):
            return Attempt(start, None, math.inf, math.inf, 0, 0.0, "scripted failure")
        search = SimpleNamespace(result=SimpleNamespace(status="Solve_Succeeded"))
        return Attempt(start, search, obj, obj, min(self.iterations, max_iter), 0.0,  # type: ignore[arg-type]
                       x_end=np.zeros(1), theta_end=None)  # fmt: skip


def _starts(*labels: str) -> list[Start]:
    return [Start(label) for label in labels]


def test_the_loop_stops_at_the_noise_level():
    run = _Scripted({"a": 4.0, "b": 1.0, "c": 0.5})
    out = keep_best(_starts("a", "b", "c"), run, noise=NoisePolicy(1.0), budget=Budget(1000),
                    max_iter=50)  # fmt: skip
    assert run.ran == ["a", "b"] and out.best.start.label == "b"
    assert out.stopped == "at the noise level" and out.at_level


def test_the_loop_stops_when_restarts_cannot_improve():
    """PATIENCE starts in a row no lower than the kept one end the loop; a start that
    improves resets the count."""
    labels = ["a", "b", "c", "d", "e", "f"]
    objs = {"a": 9.0, "b": 9.5, "c": 5.0, "d": 5.0, "e": 6.0, "f": 1.5}
    run = _Scripted(objs)
    out = keep_best(_starts(*labels), run, noise=NoisePolicy(1.0), budget=Budget(1000),
                    max_iter=50)  # fmt: skip
    assert PATIENCE == 2
    assert run.ran == ["a", "b", "c", "d", "e"]
    assert out.best.start.label == "c" and out.stopped == "a restart could not improve"
    assert "kept c" in out.note() and "stopped: a restart could not improve" in out.note()


def test_a_lower_end_in_the_same_basin_is_kept_but_is_no_improvement():
    """Far above the noise level, restarts that lower the cost by less than MATERIAL of the
    excess are kept (the lowest wins) but count as misses; one that removes more resets the
    count."""
    noise = 1.0
    a = 100.0  # 100× the noise cost
    small = a - 0.5 * MATERIAL * (a - noise)  # lower, but not by a share the user would see
    objs = {"a": a, "b": 101.0, "c": small, "d": 50.0, "e": 50.0, "f": 49.9, "g": 1.0}
    run = _Scripted(objs)
    out = keep_best(_starts(*objs), run, noise=NoisePolicy(noise), budget=Budget(1000),
                    max_iter=50)  # fmt: skip
    assert run.ran == ["a", "b", "c"] and out.best.start.label == "c"
    run = _Scripted({k: v for k, v in objs.items() if k != "b"})
    out = keep_best(_starts("a", "c", "d", "e", "f", "g"), run, noise=NoisePolicy(noise),
                    budget=Budget(1000), max_iter=50)  # fmt: skip
    # c is a miss, d removes half the excess (the count starts again), e and f are misses
    assert run.ran == ["a", "c", "d", "e", "f"] and out.best.start.label == "f"
    assert out.stopped == "a restart could not improve"


def test_the_loop_spends_one_budget():
    run = _Scripted({k: 10.0 - i for i, k in enumerate("abcdef")}, iterations=40)
    out = keep_best(_starts(*"abcdef"), run, noise=NoisePolicy(None), budget=Budget(100),
                    max_iter=50)  # fmt: skip
    # 40 + 40 + 20 (the last start gets what is left)
    assert run.ran == ["a", "b", "c"] and out.iterations == 100
    assert out.stopped == "budget spent" and out.best.start.label == "c"


def test_a_failed_start_is_skipped_and_all_failed_raises():
    run = _Scripted({"a": math.nan, "b": 2.0, "c": 3.0, "d": 4.0})
    out = keep_best(_starts("a", "b", "c", "d"), run, noise=NoisePolicy(1.0),
                    budget=Budget(1000), max_iter=50)  # fmt: skip
    assert out.best.start.label == "b" and out.attempts[0].error
    with pytest.raises(SolverError, match="every start of the fit failed"):
        keep_best(_starts("a"), _Scripted({"a": math.nan}), noise=NoisePolicy(1.0),
                  budget=Budget(10), max_iter=5)  # fmt: skip


def test_random_starts_stay_in_the_bounds_and_repeat_with_the_seed():
    class P:  # the three fields random_starts reads
        initial = np.array([2.0, -0.01, 100.0])
        lower = np.array([1.0, -0.05, 50.0])
        upper = np.array([3.0, 0.05, 150.0])

    a = random_starts(P(), 20, width=0.25, seed=3)  # type: ignore[arg-type]
    b = random_starts(P(), 20, width=0.25, seed=3)  # type: ignore[arg-type]
    xs = np.array([s.x for s in a])
    assert np.all(xs >= P.lower) and np.all(xs <= P.upper)
    np.testing.assert_array_equal(xs, np.array([s.x for s in b]))
    # log-normal of width 0.25: the spread of ln(x/x0) of a positive parameter
    assert 0.15 < np.std(np.log(xs[:, 0] / 2.0)) < 0.35


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


def test_the_noise_level_of_the_truth_is_near_one(case: dict) -> None:
    """The criterion is computed from the data alone: the truth scores about the prediction."""
    from bondid.cost.noise_level import noise_level_cost

    ratio = NoisePolicy(noise_level_cost(case["problem"].frf)).ratio_of(case["truth_cost"])
    assert ratio is not None and 0.8 < ratio < AT_LEVEL, ratio


@pytest.mark.slow
def test_a_direct_fit_above_the_noise_is_saved_by_the_continuation_start(case: dict) -> None:
    kw = {"start": case["start"], "lower": case["lo"], "upper": case["hi"]}
    alone = fit(case["doc"], case["data"], case["names"], fallback_bands=0, **kw)
    truth_db = math.sqrt(case["truth_cost"])
    # the premise: the direct fit alone ends in another basin, above the noise level
    assert math.sqrt(alone.cost_final) > 1.5 * truth_db, (alone.cost_final, case["truth_cost"])
    assert not any("band continuation" in n for n in alone.notes)
    res = fit(case["doc"], case["data"], case["names"], fallback_bands=8, **kw)
    assert math.sqrt(res.cost_final) <= WITHIN * truth_db, (res.cost_final, case["truth_cost"])
    note = [n for n in res.notes if n.startswith("starts:")]
    assert note and "kept band continuation" in note[0], res.notes
    assert res.iterations > alone.iterations


def test_nothing_more_runs_at_the_noise_level(case: dict) -> None:
    p = FitProblem(case["doc"], case["data"], case["names"], lower=case["lo"],
                   upper=case["hi"], start=get_parameters(case["doc"], case["names"]))  # fmt: skip
    from bondid.cost.noise_level import noise_level_cost

    starts = Strategy().starts(p, n_random=3)
    out = keep_best(starts, search_runner(p, direct()), noise=NoisePolicy(noise_level_cost(p.frf)),
                    budget=Budget(2000), max_iter=200)  # fmt: skip
    assert len(out.attempts) == 1 and out.stopped == "at the noise level" and not out.note()


#: IPOPT iterations after which the direct fit (no presolve) from the near start is stopped:
#: it needs more to converge, so it stops at its limit far above the noise level
SHORT = 12


def test_a_search_stopped_at_its_limit_is_resumed(case: dict) -> None:
    """The resumed search reaches the uninterrupted fit's minimum, within one budget."""
    from bondid.cost.noise_level import noise_level_cost

    start = perturbed_start(case["doc"], case["names"], seed=5, inertial=0.1)
    p = FitProblem(case["doc"], case["data"], case["names"], lower=case["lo"],
                   upper=case["hi"], start=start)  # fmt: skip
    full = run_search(p, direct(0))
    assert full.result.status == "Solve_Succeeded" and full.result.iterations > SHORT
    noise = NoisePolicy(noise_level_cost(p.frf))
    out = keep_best([Start("near")], search_runner(p, direct(0)), noise=noise,
                    budget=Budget(10 * SHORT), max_iter=SHORT)  # fmt: skip
    first = out.attempts[0]
    assert first.status == ITERATION_LIMIT and not noise.at_level(first.data_cost)
    assert out.attempts[1].resumed and out.best is not first
    assert out.best.data_cost == pytest.approx(full.result.cost_final, rel=1e-5)
    assert "near, resumed" in out.note()


def test_the_fallback_settings_from_the_study_and_the_command_line() -> None:
    from bondid.exceptions import ConfigError
    from bondid.fit.cli import build_parser, resolve_settings
    from bondid.fit.study import StudySettings, study_from_dict

    assert StudySettings().fallback == 8 and StudySettings().fallback_starts == 4
    s = study_from_dict({"model": "m.urdf", "data": ["d.csv"],
                         "search": {"fallback": 0, "fallback_starts": 0}})  # fmt: skip
    assert s.fallback == 0 and s.to_json_dict()["fallback_starts"] == 0
    with pytest.raises(ConfigError):
        study_from_dict({"model": "m.urdf", "data": ["d.csv"], "search": {"fallback": -1}})
    argv = ["--model", "m.urdf", "--data", "d.csv", "--fallback", "4", "--fallback-starts", "6"]
    s2 = resolve_settings(build_parser().parse_args(argv))
    assert s2.fallback == 4 and s2.fallback_starts == 6
