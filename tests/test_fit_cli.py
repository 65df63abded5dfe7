"""``python -m bondid.fit`` end to end, the study file, multistart starts, staged bands, bench."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from bondid.data import FrfData, write_csv
from bondid.exceptions import ConfigError
from bondid.fit.cli import build_parser, main, resolve_settings
from bondid.fit.multistart import lhs_starts
from bondid.fit.study import load_study, study_from_dict
from bondid.linear import build_affine_model
from bondid.model import UrdfDocument, get_parameter, set_parameter
from bondid.modes.bands import model_resonances, stage_bands
from bondid.optim import FitProblem, run_search
from bondid.optim.schedules import FIRST_BAND_SHARE, continuation, continuation_tops, staged

ROOT = Path(__file__).resolve().parents[1]

# ground --a (driven)--> A --p (parasitic spring/damper)--> B --b (driven)--> C
_BOX = 'ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"'


def _link(name: str, mass: float) -> str:
    return (
        f'<link name="{name}"><inertial><origin xyz="0 0 0"/><mass value="{mass}"/>'
        f'<inertia {_BOX}/></inertial><collision><geometry><box size="0.2 0.2 0.2"/>'
        "</geometry></collision></link>"
    )


def _joint(name: str, parent: str, child: str, damping: float) -> str:
    return (
        f'<joint name="{name}" type="prismatic"><parent link="{parent}"/>'
        f'<child link="{child}"/><axis xyz="1 0 0"/>'
        f'<limit lower="-1" upper="1" effort="100" velocity="1"/>'
        f'<dynamics damping="{damping}"/></joint>'
    )


def _extras(joint: str, k: float, driven: bool) -> str:
    s = (
        f'<gazebo reference="{joint}"><springStiffness>{k}</springStiffness>'
        "<springReference>0</springReference></gazebo>"
    )
    if driven:
        s += (
            f'<transmission name="{joint}_t"><type>transmission_interface/SimpleTransmission'
            f'</type><joint name="{joint}"><hardwareInterface>hardware_interface/'
            "EffortJointInterface</hardwareInterface></joint></transmission>"
        )
    return s


MODEL_XML = (
    '<robot name="chain"><link name="ground"/>'
    + _link("A", 1.0)
    + _link("B", 0.5)
    + _link("C", 0.2)
    + _joint("a", "ground", "A", 2.0)
    + _joint("p", "A", "B", 5.0)
    + _joint("b", "B", "C", 1.0)
    + _extras("a", 1000.0, True)
    + _extras("p", 2.0e4, False)
    + _extras("b", 500.0, True)
    + "</robot>"
)
TRUTH = {"p.stiffness": 2.6e4, "p.damping": 4.0}


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def case(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The model file and two noise-free data files (two operating points) of the truth."""
    d = tmp_path_factory.mktemp("fitcase")
    model, files = write_chain_case(d)
    return {"dir": d, "model": model, "data0": files[0], "data1": files[1]}


def write_chain_case(d: Path) -> tuple[Path, list[Path]]:
    """Write the chain model (``MODEL_XML``) and two noise-free data files of its truth
    (``TRUTH``, 40 frequencies 2–300 Hz, operating points a = 0 and 0.1) into ``d``."""
    model = d / "chain.urdf"
    model.write_text(MODEL_XML, encoding="utf-8")
    truth = UrdfDocument.from_string(MODEL_XML)
    for n, v in TRUTH.items():
        set_parameter(truth, n, v)
    f = np.geomspace(2.0, 300.0, 40)
    files = []
    for i, op in enumerate(({}, {"a": 0.1})):
        H = build_affine_model(truth, op).linear_model().frf(f)
        ds = FrfData(f, ("a", "b"), ("a", "b"), H, operating_point=op)
        files.append(write_csv(ds, d / f"pose{i}.csv"))
    return model, files


def _run(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_fit_end_to_end(case: dict[str, Path], tmp_path: Path, capsys) -> None:
    model, d0, d1 = case["model"], case["data0"], case["data1"]
    before = {p: _sha(p) for p in (model, d0, d1)}
    out = tmp_path / "res"
    # the exact known answer: no prior (bondid.optim.prior; tests/test_prior.py has the default)
    argv = ["--model", model, "--data", d0, d1, "--out", out, "--quiet", "--free", "parasitic",
            "--prior", "0"]  # fmt: skip
    code, stdout, _ = _run(capsys, *argv)
    assert code == 0, stdout
    res = json.loads((out / "fit.json").read_text())
    for key in ("status", "cost_initial", "cost_final", "cost_name", "iterations", "wall_s"):
        assert key in res
    assert res["cost_name"] == "complex_log_l2"
    assert [p["name"] for p in res["parameters"]] == ["p.stiffness", "p.damping"]
    for p in res["parameters"]:
        assert set(p) >= {"name", "initial", "fitted", "lower", "upper", "std"}
        assert p["lower"] <= p["fitted"] <= p["upper"]
        assert math.isclose(p["fitted"], TRUTH[p["name"]], rel_tol=1e-5)
    assert res["cost_final"] < 1e-8 < res["cost_initial"]
    assert res["db_rms"]["final"] < 1e-3 < res["db_rms"]["initial"]
    assert set(res["db_rms"]["by_channel"]) == {"a.a", "a.b", "b.a", "b.b"}
    assert res["data_files"] == [str(d0), str(d1)]
    fitted = UrdfDocument.load(out / "fitted.urdf")
    assert math.isclose(get_parameter(fitted, "p.stiffness"), TRUTH["p.stiffness"], rel_tol=1e-5)
    assert get_parameter(fitted, "p.stiffness") != get_parameter(
        UrdfDocument.load(model), "p.stiffness"
    )
    assert get_parameter(fitted, "A.mass") == 1.0  # not fitted, unchanged
    assert {p: _sha(p) for p in before} == before  # inputs untouched
    for png in ("bode_pose0.png", "bode_pose1.png", "convergence.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "p.stiffness" in stdout and "db_rms" in stdout


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--data", "{dir}/missing.csv"], "missing.csv"),
        (["--free", "nosuch.*"], "nosuch.*"),
        (["--band", "500:10"], "500:10"),
        (["--study", "{dir}/bad.toml"], "cost.colour"),
        (["--out", "{data0}"], "overwrite"),
    ],
)
def test_bad_input_exit_2(case: dict[str, Path], capsys, args: list[str], needle: str) -> None:
    (case["dir"] / "bad.toml").write_text('[cost]\ncolour = "red"\n')
    base = {"--model": str(case["model"]), "--data": str(case["data0"])}
    extra = [a.format(**{k: str(v) for k, v in case.items()}) for a in args]
    for i in range(0, len(extra), 2):
        base[extra[i]] = extra[i + 1]
    argv = [x for kv in base.items() for x in kv] + ["--quiet", "--max-iter", "5"]
    code, _, err = _run(capsys, *argv)
    assert code == 2
    reason = [ln for ln in err.splitlines() if "bad input" in ln]
    assert len(reason) == 1 and needle in reason[0]


def test_study_values_used_and_cli_overrides(case: dict[str, Path], tmp_path: Path, capsys) -> None:
    study = tmp_path / "study.toml"
    study.write_text(
        'model = "' + str(case["model"]) + '"\n'
        'data = ["' + str(case["data0"]) + '"]\n'
        '[parameters]\nfree = ["p.stiffness"]\n'
        '[bounds]\n"p.stiffness" = [1.0e4, 3.0e4]\n'
        '[cost]\nkind = "log_magnitude"\nbands = [[1.0, 200.0]]\n'
        "[search]\nmax_iter = 40\n"
    )
    parser = build_parser()
    s = resolve_settings(parser.parse_args(["--study", str(study)]))
    assert s.free == ["p.stiffness"] and s.cost == "log_magnitude" and s.max_iter == 40
    assert s.abs_bounds == {"p.stiffness": (1.0e4, 3.0e4)} and s.bands == [(1.0, 200.0)]
    s2 = resolve_settings(
        parser.parse_args(["--study", str(study), "--cost", "normalised_complex", "--band", "2:100",
                           "--bound", "p.stiffness=0.1", "--max-iter", "7"])
    )  # fmt: skip
    assert s2.cost == "normalised_complex" and s2.bands == [(2.0, 100.0)] and s2.max_iter == 7
    assert s2.rel_bounds == {"p.stiffness": 0.1} and s2.abs_bounds == {}
    assert s2.free == ["p.stiffness"]  # not overridden: kept from the study

    out = tmp_path / "res"
    code, _, _ = _run(capsys, "--study", study, "--out", out, "--quiet")
    assert code == 0
    res = json.loads((out / "fit.json").read_text())
    assert res["cost_name"] == "log_magnitude_l2"
    (p,) = res["parameters"]
    assert p["name"] == "p.stiffness" and (p["lower"], p["upper"]) == (1.0e4, 3.0e4)
    assert res["settings"]["bands"] == [[1.0, 200.0]]
    code, _, _ = _run(
        capsys, "--study", study, "--free", "p.damping", "--cost", "normalised_complex",
        "--out", out, "--quiet",
    )  # fmt: skip
    assert code == 0
    res = json.loads((out / "fit.json").read_text())
    assert res["cost_name"] == "normalised_complex_l2"
    assert [q["name"] for q in res["parameters"]] == ["p.damping"]


@pytest.mark.parametrize(
    "doc, key",
    [
        ({"cost": {"kind": "cubic"}}, "cost.kind"),
        ({"cost": {"norm": "l3"}}, "cost.norm"),
        ({"cost": {"bands": [[10, 1]]}}, "cost.bands[0]"),
        ({"search": {"multistart": 0}}, "search.multistart"),
        ({"search": {"staged": "yes"}}, "search.staged"),
        ({"search": {"continuation": -1}}, "search.continuation"),
        ({"search": {"stage_bands": {"mass": [1, 2]}}}, "search.stage_bands.mass"),
        ({"bounds": {"mass": -0.1}}, "bounds.mass"),
        ({"bounds": {"mass": [2, 1]}}, "bounds.mass"),
        ({"solver": {}}, "solver"),
    ],
)
def test_study_validation(doc: dict, key: str) -> None:
    with pytest.raises(ConfigError) as exc:
        study_from_dict(doc, where="s.toml")
    msg = str(exc.value)
    assert msg.startswith(f"s.toml: {key}:") and "\n" not in msg


def test_study_file_errors(tmp_path: Path) -> None:
    bad = tmp_path / "broken.toml"
    bad.write_text("[cost\nkind = 1\n")
    with pytest.raises(ConfigError, match=r"broken\.toml: not valid TOML"):
        load_study(bad)
    with pytest.raises(ConfigError, match="cannot read"):
        load_study(tmp_path / "absent.toml")
    good = tmp_path / "sub" / "ok.toml"
    good.parent.mkdir()
    good.write_text('model = "m.urdf"\ndata = "d.csv"\n[search]\nstaged = true\n')
    s = load_study(good)
    assert s.model == good.parent / "m.urdf" and s.data == [good.parent / "d.csv"] and s.staged


def test_continuation_command(case: dict[str, Path], tmp_path: Path, capsys) -> None:
    """``--continuation 3``: two growing-band stages, then the full fit, in fit.json."""
    model, d0 = case["model"], case["data0"]
    out = tmp_path / "cont"
    code, stdout, _ = _run(
        capsys, "--model", model, "--data", d0, "--continuation", 3, "--out", out, "--quiet",
        "--free", "parasitic", "--prior", "0",  # the exact answer: no prior (test_prior.py)
    )  # fmt: skip
    assert code == 0, stdout
    res = json.loads((out / "fit.json").read_text())
    assert res["settings"]["continuation"] == 3
    stages = res["stages"]
    assert [s["name"] for s in stages][-1] == "all" and len(stages) == 3
    tops = [s["bands_hz"][-1][1] for s in stages]
    assert tops == sorted(tops) and tops[0] < 300.0 and math.isclose(tops[-1], 300.0)
    assert all(s["bands_hz"][0][0] == pytest.approx(2.0) for s in stages)
    for q in res["parameters"]:
        assert math.isclose(q["fitted"], TRUTH[q["name"]], rel_tol=1e-5)
    assert res["cost_initial"] == pytest.approx(res["cost_model"])
    for bad in (["--continuation", "1"], ["--continuation", "4", "--staged"]):
        code, _, err = _run(capsys, "--model", model, "--data", d0, *bad, "--quiet")
        assert code == 2 and "--continuation" in err and "at least 2" in err


def test_continuation_bands_and_errors(case: dict[str, Path]) -> None:
    tops = continuation_tops(1.0, 4000.0, 8)
    assert len(tops) == 7 and tops == sorted(tops) and tops[-1] < 4000.0
    assert tops[0] == pytest.approx(4000.0**FIRST_BAND_SHARE)
    assert continuation_tops(1.0, 4000.0, 1) == []
    from bondid.data import read_frf

    doc = UrdfDocument.load(case["model"])
    lo, hi = np.array([0.0]), np.array([np.inf])
    problem = FitProblem(doc, [read_frf(case["data0"])], ["p.damping"], lower=lo, upper=hi)
    with pytest.raises(ConfigError, match="at least 2 bands"):
        continuation(problem, 1)


def test_lhs_starts_within_bounds() -> None:
    x0 = np.array([1.0, 5.0, 0.0, 3.0])
    lo = np.array([0.5, 1.0, -1.0, 0.0])
    hi = np.array([2.0, 1000.0, 1.0, np.inf])
    S = lhs_starts(x0, lo, hi, 9, seed=3)
    assert S.shape == (9, 4)
    np.testing.assert_array_equal(S[0], x0)
    assert np.all((lo <= S) & (hi >= S))
    np.testing.assert_array_equal(S[1:, 3], 3.0)  # infinite bound: stays at x0
    np.testing.assert_array_equal(S, lhs_starts(x0, lo, hi, 9, seed=3))  # seeded
    assert not np.array_equal(S, lhs_starts(x0, lo, hi, 9, seed=4))
    # Latin hypercube: one sample per stratum in each dimension (log strata for the wide box)
    u0 = (S[1:, 0] - lo[0]) / (hi[0] - lo[0])
    assert sorted(np.floor(u0 * 8).astype(int)) == list(range(8))
    u1 = np.log(S[1:, 1] / lo[1]) / np.log(hi[1] / lo[1])
    assert sorted(np.floor(u1 * 8).astype(int)) == list(range(8))


def test_multistart_parallel(case: dict[str, Path], tmp_path: Path, capsys) -> None:
    out = tmp_path / "ms"
    code, stdout, _ = _run(
        capsys, "--model", case["model"], "--data", case["data0"], "--out", out,
        "--multistart", "3", "--workers", "2", "--quiet", "--max-iter", "60",
    )  # fmt: skip
    assert code == 0
    ms = json.loads((out / "fit.json").read_text())["multistart"]
    assert ms["n_runs"] == 3 and len(ms["costs"]) == 3
    assert ms["min"] <= ms["median"] <= ms["max"]
    assert ms["min"] == min(c for c in ms["costs"] if c is not None)
    assert "multistart: 3 runs" in stdout


def test_modes_and_staged(case: dict[str, Path]) -> None:
    doc = UrdfDocument.load(case["model"])
    modes = model_resonances(doc)
    lm = build_affine_model(doc).linear_model()
    w = np.sqrt(np.linalg.eigvals(np.linalg.solve(lm.M, lm.K)).real)
    # lightly damped: the damped |λ| equal the undamped frequencies √(eig(M⁻¹K))
    np.testing.assert_allclose(sorted(m.f_hz for m in modes), sorted(w / (2 * np.pi)), rtol=1e-2)
    assert [m.parasitic for m in modes].count(True) == 1
    fp = next(m.f_hz for m in modes if m.parasitic)
    bands = stage_bands(modes, 1.0, 1000.0)
    assert bands["stiffness"] == [(1.0, fp / 1.5)] and bands["inertia"] == [(fp, 1000.0)]
    assert any(lo < fp < hi for lo, hi in bands["damping"])

    from bondid.data import read_frf

    datasets = [read_frf(case["data0"])]
    names = ["B.mass", "p.stiffness", "p.damping"]
    lo = np.array([0.3, 1.0e4, 1.0])
    hi = np.array([0.8, 4.0e4, 10.0])
    problem = FitProblem(doc, datasets, names, lower=lo, upper=hi)
    res = run_search(problem, staged(problem, max_iter=80), max_iter=80)
    assert [s.name for s in res.stages] == ["stiffness", "damping", "inertia", "all"]
    assert res.stages[0].names == ["p.stiffness"] and res.stages[2].names == ["B.mass"]
    np.testing.assert_allclose(res.result.initial, [0.5, 2.0e4, 5.0])
    np.testing.assert_allclose(res.result.fitted, [0.5, 2.6e4, 4.0], rtol=1e-4)
    assert res.result.cost_final < 1e-8 < res.result.cost_initial


def test_bench_quick(capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    spec = importlib.util.spec_from_file_location("bench_fit", ROOT / "tools" / "bench_fit.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "bench_fit", bench)  # dataclasses look their module up
    spec.loader.exec_module(bench)
    code = bench.main(["--quick", "--n-freq", "40", "--budget-s", "0.5", "--max-iter", "8"])
    out = capsys.readouterr().out
    assert code == 0
    rows = [ln for ln in out.splitlines() if ln.startswith("(")]
    assert [r[:3] for r in rows if "done" not in r] == ["(a)", "(b)", "(c)", "(d)"]


def test_free_auto(case: dict[str, Path], tmp_path: Path, capsys, monkeypatch) -> None:
    import types

    argv = ["--model", case["model"], "--data", case["data0"], "--free", "auto", "--quiet"]
    monkeypatch.setitem(sys.modules, "bondid.sensitivity", None)  # not installed
    code, _, err = _run(capsys, *argv)
    assert code == 2 and "recommend_subset" in err
    calls = []

    def recommend_subset(doc, datasets, options):
        calls.append((len(datasets), options.kind))
        return ["p.damping"]

    fake = types.ModuleType("bondid.sensitivity")
    fake.recommend_subset = recommend_subset  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "bondid.sensitivity", fake)
    code, _, _ = _run(capsys, *argv, "--out", tmp_path / "auto")
    assert code == 0 and calls == [(1, "complex_log")]
    res = json.loads((tmp_path / "auto" / "fit.json").read_text())
    assert [p["name"] for p in res["parameters"]] == ["p.damping"]
