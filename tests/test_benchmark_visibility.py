"""The blind benchmark's visibility check (``tools/benchmark/visibility.py``): the oracle
parameter refit and the strengthening of an effect the data do not show."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from benchmark import visibility  # noqa: E402
from benchmark.cases import Case, all_cases  # noqa: E402
from benchmark.truth import TruthEffect  # noqa: E402


def _case(name: str) -> Case:
    return next(c for c in all_cases() if c.name == name)


def test_a_step_strengthens_every_effect_class_by_its_rule() -> None:
    jc = TruthEffect("joint_compliance", "a->b:tz", {"f": 800.0, "offset": (0.02, 0.0)})
    sd = TruthEffect("sensor_delay", "x", {"tau": 40e-6})
    al = TruthEffect("actuator_lag", "y", {"T": 80e-6})
    assert visibility.stronger(jc).spec == {"f": 600.0, "offset": (0.02, 0.0)}
    assert visibility.stronger(sd).spec["tau"] == pytest.approx(60e-6, rel=1e-12)
    assert visibility.stronger(al).spec["T"] == pytest.approx(120e-6, rel=1e-12)
    assert jc.spec["f"] == 800.0  # the input is not changed


def test_the_loop_strengthens_until_visible_and_stops_at_the_limit(monkeypatch) -> None:
    seen: list[float] = []

    def fake_oracle(case: Case, paths, points: int) -> dict[str, float]:
        f = case.effects[0].spec["f"]
        seen.append(f)
        return {"oracle_db": 1.0, "truth_model_db": 1.0, "ratio": 1500.0 / f}

    monkeypatch.setattr(visibility, "oracle", fake_oracle)
    monkeypatch.setattr(visibility, "case_files", lambda case, folder, freq: ([], []))
    base = _case("bonder/fb/harsh")
    eff = replace(base.effects[0], spec={"f": 1600.0})
    got, rec = visibility.visible_case(replace(base, effects=(eff,)), 100)
    # 1600 (0.94) → 1200 (1.25 ≥ 1.2): one step
    assert seen == [1600.0, 1200.0] and rec["visible"] is True
    assert got.effects[0].spec["f"] == 1200.0 and got.name == base.name
    seen.clear()
    eff = replace(base.effects[0], spec={"f": 1e6})
    got, rec = visibility.visible_case(replace(base, effects=(eff,)), 100)
    assert len(seen) == visibility.MAX_TRIES + 1 and rec["visible"] is False
    assert len(rec["visibility"]) == visibility.MAX_TRIES + 1


def test_none_and_two_effect_cases_are_left_as_they_are(monkeypatch) -> None:
    def never(*_a, **_k):
        raise AssertionError("no oracle refit for these cases")

    monkeypatch.setattr(visibility, "oracle", never)
    for c in all_cases():
        if len(c.effects) != 1:
            assert visibility.visible_case(c, 100) == (c, {})


@pytest.mark.slow
def test_the_oracle_sees_a_clear_effect_and_not_parameter_errors(tmp_path: Path) -> None:
    """Known answer at a low resolution: a withheld 450 Hz rotational compliance of the
    reference bonder leaves the oracle parameter refit well above 1.2× the truth's gap; the
    same truth without it (parameter errors only, the oracle's own start) is at 1.0×."""
    case = _case("bonder/jcr/nocoh")
    paths, _ = visibility.case_files(case, tmp_path / "jc", 300)
    jc = visibility.oracle(case, paths, 120)
    assert jc["ratio"] > 2.0
    bare = replace(case, effects=())
    paths, _ = visibility.case_files(bare, tmp_path / "none", 300)
    none = visibility.oracle(bare, paths, 120)
    assert none["ratio"] == pytest.approx(1.0, abs=0.1)


def test_the_command_line_maps_onto_the_runner_settings(tmp_path: Path) -> None:
    import blind_benchmark

    s = blind_benchmark.settings(blind_benchmark.parse(["--keep", str(tmp_path), "--no-fit"]))
    assert s.keep == tmp_path and s.visibility is True and s.fit is False
    s = blind_benchmark.settings(blind_benchmark.parse(["--quick", "--no-visibility"]))
    assert (s.freq, s.points, s.keep, s.visibility) == (300, 120, None, False)
