"""The blind benchmark's machine designs, truth builders, data regimes and case list
(``tools/benchmark/``)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from benchmark.cases import DOUBLE, SINGLE, all_cases  # noqa: E402
from benchmark.designs import DESIGNS  # noqa: E402
from benchmark.regimes import REGIMES, measure, quantity_of  # noqa: E402
from benchmark.runner import score, screening, truth_db  # noqa: E402
from benchmark.truth import (  # noqa: E402
    EFFECTS,
    STRUCTURAL,
    TruthEffect,
    add_compliance,
    add_flexible_base,
    add_soft_mounts,
    signal_factor,
    truth_model,
)

from bondid.data.io import read_frf  # noqa: E402
from bondid.diagnose.gap import gap_report  # noqa: E402
from bondid.linear import build_affine_model  # noqa: E402
from bondid.model import UrdfDocument  # noqa: E402


def _modes_hz(doc: UrdfDocument) -> np.ndarray:
    """Damped natural frequencies (Hz) of the oscillating modes at q = 0, ascending."""
    lm = build_affine_model(doc).linear_model()
    n = lm.M.shape[0]
    Minv = np.linalg.inv(lm.M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ lm.K, -Minv @ lm.D]])
    lam = np.linalg.eigvals(A)
    assert lam.real.max() < 1e-6 * np.abs(lam).max(), "unstable linearisation"
    lam = lam[lam.imag > 1e-6]
    return np.sort(np.abs(lam)) / (2 * np.pi)


@pytest.fixture(scope="module", params=list(DESIGNS))
def design(request: pytest.FixtureRequest):
    return DESIGNS[request.param]


def test_design_loads_and_linearises(design) -> None:
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(design.path))
    doc = UrdfDocument.load(design.path)
    am = build_affine_model(doc, design.operating_points[1])
    assert model.nv == len(am.dofs) >= 10
    assert len(am.inputs) == 3 and am.inputs == am.outputs
    f = _modes_hz(doc)
    assert f[0] < 20.0 and f[-1] > 1500.0 and f[-1] < 4000.0, f
    assert len(f) >= 7


def test_design_bodies_are_physical(design) -> None:
    from scipy.spatial import ConvexHull

    from bondid.consistency.hull import link_hull

    doc = UrdfDocument.load(design.path)
    for lk in doc.robot.links:
        if lk.inertial is None:
            assert not lk.collisions, f"{lk.name}: massless links carry no geometry"
            continue
        I = np.asarray(lk.inertial.inertia)
        ev = np.sort(np.linalg.eigvalsh(I))
        assert ev[0] > 0 and ev[0] + ev[1] > ev[2], f"{lk.name}: inertia not physical"
        hull = link_hull(lk)
        assert hull is not None, f"{lk.name}: no collision geometry"
        com = np.asarray(lk.inertial.origin)[:3, 3]
        eq = ConvexHull(hull.vertices).equations
        assert np.all(eq[:, :3] @ com + eq[:, 3] < 0), f"{lk.name}: CoM outside its hull"


@pytest.mark.parametrize("name", list(DESIGNS))
def test_compliance_adds_a_mode_near_the_requested_frequency(name: str) -> None:
    from bondid.diagnose.effects.joint_compliance import PIVOT_TOL, pivot_options
    from bondid.diagnose.effects.topology import axis_vector, interfaces

    nominal = UrdfDocument.load(DESIGNS[name].path)
    n0 = len(_modes_hz(nominal))
    e = SINGLE[name]["jcr"]
    doc = add_compliance(nominal, e.location, e.spec["f"], e.spec["offset"])
    f = _modes_hz(doc)
    assert len(f) == n0 + 1
    assert np.min(np.abs(np.log(f / e.spec["f"]))) < np.log(1.25)
    # the truth's pivot is none of the diagnosis's candidate pivots
    pair, axis = e.location.split(":")
    itf = next(i for i in interfaces(nominal) if f"{i.parent}->{i.child}" == pair)
    j = next(j for j in doc.robot.joints if j.name == f"truth_{itf.child}_{axis}")
    pivot = np.asarray(j.origin)[:3, 3]
    for p in pivot_options(nominal, itf, axis_vector(axis)[1]):
        assert np.linalg.norm(pivot - p) > PIVOT_TOL


def test_base_effects_free_the_base() -> None:
    nominal = UrdfDocument.load(DESIGNS["gantry"].path)
    n0 = len(_modes_hz(nominal))
    fb = _modes_hz(add_flexible_base(nominal, 700.0))
    assert len(fb) == n0 + 12  # 4 elastic segments × 3 directions
    assert np.min(np.abs(np.log(fb / 700.0))) < np.log(1.25)
    sm = _modes_hz(add_soft_mounts(nominal, 12.0))
    assert len(sm) == n0 + 6
    assert np.count_nonzero((sm > 0.3 * 12.0) & (sm < 3 * 12.0)) == 6  # the six mount modes


def test_signal_effects_are_a_delay_and_a_two_pole_lag() -> None:
    f = np.array([10.0, 300.0, 3000.0])
    w = 2 * np.pi * f
    outs, ins = ("a", "b", "c"), ("a", "b", "c")
    G = signal_factor([TruthEffect("sensor_delay", "b", {"tau": 5e-5})], f, outs, ins)
    np.testing.assert_allclose(G[1], np.broadcast_to(np.exp(-1j * w * 5e-5), (3, 3)))
    np.testing.assert_array_equal(G[[0, 2]], 1.0)
    G = signal_factor([TruthEffect("actuator_lag", "all", {"T": 1e-4})], f, outs, ins)
    lag = 1 / ((1 + 1j * w * 1e-4) * (1 + 1j * w * 1e-4 / 8))
    np.testing.assert_allclose(G, np.broadcast_to(lag, (3, 3, 3)))


@pytest.mark.parametrize("regime", REGIMES)
def test_regime_files_read_back(regime: str, tmp_path: Path) -> None:
    d = DESIGNS["bonder_b"]
    eff = (TruthEffect("sensor_delay", "ya", {"tau": 3e-5}),)
    truth = truth_model(UrdfDocument.load(d.path), eff, seed=3)
    f = np.geomspace(1.0, 4000.0, 60)

    def factor(ff, o, i):
        return signal_factor(eff, ff, o, i)

    paths, exact = measure(truth, d.operating_points, f, regime, factor, tmp_path, seed=3)
    assert len(paths) == 2
    data = read_frf(paths[1])
    assert data.quantity == quantity_of(regime)
    assert (data.coherence is not None) == (regime == "coh")
    assert (".coh" in paths[1].read_text()) == (regime == "coh")
    assert data.operating_point == pytest.approx(d.operating_points[1])
    # 2 % relative noise dominates where the response is strong: the diagonal is close
    rel = np.abs(data.H[0, 0] / exact[1][0, 0] - 1)
    assert np.median(rel) < 0.1
    # the truth's own gap is read in whatever quantity the diagnosis converts the files to
    direct = gap_report([read_frf(p) for p in paths], exact, channels=["xa.xa", "ya.ya"])
    assert truth_db(paths, exact, {"channels": ["xa.xa", "ya.ya"]}) == pytest.approx(
        direct.db_rms, rel=1e-9
    )
    if regime in ("coh", "nocoh"):  # a floor that follows the response: diagonals clean
        assert direct.db_rms < 1.0
    if regime == "acc":  # accelerance = −ω² × receptance
        rec = measure(truth, d.operating_points[1:], f, "nocoh", factor, tmp_path, seed=3)[1]
        np.testing.assert_allclose(exact[1], -((2 * np.pi * f) ** 2) * rec[0], rtol=1e-9)


def test_case_list_covers_designs_regimes_and_effects() -> None:
    cases = all_cases()
    names = [c.name for c in cases]
    assert len(set(names)) == len(names)
    single = [c for c in cases if len(c.effects) == 1]
    assert len(single) >= 40
    for design in DESIGNS:
        classes = {c.effects[0].effect for c in single if c.design == design}
        assert classes == set(EFFECTS), design
        assert sum(1 for c in cases if c.design == design and not c.effects) >= 2
    for regime in REGIMES:
        assert {c.effects[0].effect for c in single if c.regime == regime} == set(EFFECTS)
    double = [c for c in cases if len(c.effects) == 2]
    assert len(double) == sum(len(v) for v in DOUBLE.values()) >= 8
    for c in double:
        a, b = c.effects
        assert a.location != b.location
        assert a.effect in STRUCTURAL


def _diag(effects: list[dict], candidates: list[dict] | None = None) -> dict:
    return {
        "gap": {"db_rms": 4.0},
        "verdict": effects[0] if effects else {"effect": "none", "location": None, "gap_closed": 0},
        "effects": effects,
        "candidates": candidates or [],
    }


def test_scores_two_effect_cases_and_screening() -> None:
    case = next(c for c in all_cases() if c.name == "gantry/sm+al/acc")
    sm = {"effect": "soft_mounts", "location": "frame", "gap_closed": 0.4}
    al = {"effect": "actuator_lag", "location": "gy", "gap_closed": 0.5}
    r = score(case, _diag([sm, al]), db_truth=2.0)
    assert r["class_ok"] and r["location_ok"] and r["extra_claims"] == 0
    assert r["ratio"] == pytest.approx(0.5 / 0.5)
    third = {"effect": "sensor_delay", "location": "gx", "gap_closed": 0.55}
    assert score(case, _diag([sm, al, third]), 2.0)["extra_claims"] == 1
    assert not score(case, _diag([sm]), 2.0)["location_ok"]
    assert screening(case, _diag([sm])) is None
    cands = [dict(sm, refitted=True), dict(al, refitted=False)]
    assert screening(case, _diag([sm], cands)) is False
    cands[1]["refitted"] = True
    assert screening(case, _diag([sm], cands)) is True


def test_a_true_effect_the_data_cannot_tell_from_the_claimed_one_counts_as_tied() -> None:
    case = next(c for c in all_cases() if c.name == "gantry/sm+al/acc")
    sm = {"effect": "soft_mounts", "location": "frame"}
    sd = {"effect": "sensor_delay", "location": "gy", "indistinguishable_from": [
        {"effect": "actuator_lag", "location": "gy", "score": 1.0, "lr": 2.0}]}  # fmt: skip
    r = score(case, _diag([sm, sd]), db_truth=2.0)
    assert not r["location_ok"] and r["named_or_tied"] is True
    assert score(case, _diag([sm]), 2.0)["named_or_tied"] is False
    none = next(c for c in all_cases() if not c.effects)
    assert score(none, _diag([]), 2.0)["named_or_tied"] is None


def test_final_model_at_the_noise_level() -> None:
    case = next(c for c in all_cases() if c.name == "gantry/sm+al/acc")
    sm = {"effect": "soft_mounts", "location": "frame", "db_rms_after": 2.5}
    al = {"effect": "actuator_lag", "location": "gy", "db_rms_after": 2.15}
    r = score(case, _diag([sm, al]), db_truth=2.0)
    assert r["final_db"] == 2.15 and r["at_noise"] is True  # 2.15 <= 1.1 * 2.0
    r = score(case, _diag([sm]), db_truth=2.0)
    assert r["final_db"] == 2.5 and r["at_noise"] is False
    none = score(case, _diag([]), db_truth=3.8)  # no effect: the parameter refit's gap, 4.0
    assert none["final_db"] == 4.0 and none["at_noise"] is True
    assert score(case, _diag([]), db_truth=None)["at_noise"] is None
    # the final fit on all data (stop 29) is counted apart; older outputs have none
    assert r["final_fit_db"] is None and r["final_fit_at_noise"] is None
    d = dict(_diag([sm]), final_fit={"db_rms": 2.1})
    r = score(case, d, db_truth=2.0)
    assert r["at_noise"] is False and r["final_fit_db"] == 2.1 and r["final_fit_at_noise"] is True


def test_an_effect_shows_only_where_the_parameter_refit_is_above_the_truths_level() -> None:
    from benchmark.runner import shows
    from benchmark.tables import summary_table

    assert shows(2.3, 2.0, 1) is True  # 2.3 > 1.1 * 2.0
    assert shows(2.1, 2.0, 1) is False
    assert shows(2.3, 2.0, 0) is None and shows(None, 2.0, 1) is None
    case = next(c for c in all_cases() if c.name == "gantry/sd/harsh")
    hidden = dict(score(case, _diag([]), db_truth=3.9), case=case.name, design="gantry",
                  regime="harsh", truth=[["sensor_delay", "gx"]])  # fmt: skip
    assert hidden["shows"] is False and not hidden["class_ok"]
    sd = {"effect": "sensor_delay", "location": "gx", "gap_closed": 0.5}
    seen = dict(score(case, _diag([sd]), db_truth=2.0), case=case.name, design="gantry",
                regime="harsh", truth=[["sensor_delay", "gx"]])  # fmt: skip
    assert seen["shows"] is True and seen["location_ok"]
    old = {k: v for k, v in hidden.items() if k != "shows"}  # a row that predates the field
    line = summary_table([hidden, seen]).splitlines()[2]
    assert (
        line.endswith("| 100% (1/1) | 100% (1/1) | 0/2 |") and "| 50% (1/2) | 50% (1/2) |" in line
    )
    assert summary_table([old, seen]).splitlines()[2] == line


def test_tables_keep_their_columns_with_failed_cases() -> None:
    from benchmark.tables import case_table, summary_table

    ok = {"case": "gantry/none_a/harsh", "design": "gantry", "regime": "harsh", "truth": [],
          "claimed": [["soft_mounts", "frame"]], "class_ok": False, "location_ok": None,
          "extra_claims": 1, "gap_refit": 3.0, "db_truth": 2.9, "gap_closed": 0.2,
          "truth_gap_closed": 0.03, "ratio": None, "screen_ok": None, "diagnosis_s": 90.0,
          "fit_s": 30.0, "fit_status": "Solve_Succeeded"}  # fmt: skip
    bad = {"case": "gantry/sd/harsh", "design": "gantry", "regime": "harsh",
           "truth": [["sensor_delay", "gx"]], "error": "diagnose: exit 1"}  # fmt: skip
    lines = case_table([ok, bad]).splitlines()
    assert len({line.count("|") for line in lines}) == 1
    assert "| 3.0 |" in lines[2]  # diagnose / fit time ratio
    summary = summary_table([ok, bad])
    assert "| gantry | harsh | 2 (1) | 0% (0/1) | – | 1/1 |" in summary


def test_open_table_counts_honest_answers_and_right_remainders() -> None:
    from benchmark.tables import open_table

    named = {"truth": [["sensor_dynamics", "y"]], "class_ok": True, "location_ok": True,
             "left_out": False, "outcome": "explained"}  # fmt: skip
    honest = {"truth": [["amplifier_highpass", "x"]], "class_ok": False, "location_ok": False,
              "left_out": True, "outcome": "partly_explained", "honest": True,
              "remainder_ok": True}  # fmt: skip
    claimed = {**honest, "outcome": "explained", "honest": False, "remainder_ok": False}
    broken = {"truth": [["amplifier_highpass", "x"]], "error": "diagnose: exit 1"}
    lines = open_table([named, honest, claimed, broken]).splitlines()
    assert len({line.count("|") for line in lines}) == 1
    assert lines[2].startswith("| sensor_dynamics | 1 (0) | 100% (1/1) | 100% (1/1) | – |")
    assert lines[3] == "| amplifier_highpass | 3 (1) | – | – | 1 / 1 / 0 | 50% (1/2) | 50% (1/2) |"
    assert lines[4].startswith("| **all** | 4 (1) | 100% (1/1) |")


@pytest.mark.slow
def test_blind_benchmark_runs_a_case_end_to_end(capsys: pytest.CaptureFixture[str]) -> None:
    import blind_benchmark

    assert blind_benchmark.main(["--list", "--quick"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 3
    blind_benchmark.main(["--cases", "bonder/none_a/coh", "--freq", "100", "--points", "50",
                          "--workers", "1", "--effects", "sensor_delay", "--no-fit"])  # fmt: skip
    out = capsys.readouterr().out
    assert "| bonder/none_a/coh | none | – |" in out
    assert "| bonder | coh | 1 (0) |" in out


def test_blind_benchmark_resumes_where_its_rows_end(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--resume`` keeps the finished rows of ``--out``, runs only the cases they lack (a row
    that ended in an error is run again) and writes every row back."""
    import blind_benchmark

    stored = json.loads((ROOT / "tools/benchmark/results/blind.json").read_text())
    kept, failed, missing = stored[0], dict(stored[1], error="RuntimeError()"), stored[2]
    out = tmp_path / "rows.json"
    out.write_text(json.dumps([kept, failed]))
    ran: list[str] = []

    def fake_run(case, settings):  # the stored row of a case stands for running it
        ran.append(case.name)
        return next(r for r in stored if r["case"] == case.name)

    monkeypatch.setattr(blind_benchmark, "run_case", fake_run)
    names = ",".join(r["case"] for r in (kept, failed, missing))
    assert blind_benchmark.main(["--cases", names, "--resume", "--out", str(out)]) == 0
    assert ran == [failed["case"], missing["case"]]
    assert [r["case"] for r in json.loads(out.read_text())] == names.split(",")
    assert "resuming: 1 of 3 cases" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        blind_benchmark.main(["--quick", "--resume"])  # no --out to resume
