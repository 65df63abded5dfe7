"""The line reduction for fitting dense data (:mod:`bondid.data.reduce`) and ``--lines``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from models import two_mass_chain

from bondid.data import FrfData, add_measurement_noise, write_csv
from bondid.data.reduce import (
    AUTO_ABOVE,
    AUTO_LINES,
    MIN_LINES,
    decimate_log,
    parse_lines,
    reduce_datasets,
    reduce_to,
    select_lines,
)
from bondid.data.weights import information_weights, noise_to_signal
from bondid.exceptions import ConfigError
from bondid.linear import build_affine_model

# the two-mass chain: drive point a.a has two resonances and the anti-resonance of body b
M_A, M_B, K_A, K_B, D_A, D_B = 1.0, 0.5, 1.0e5, 2.0e5, 7.7, 6.3
#: the reduced fit's parameters against the all-lines fit's: within this relative difference
REDUCED_VS_ALL_REL = 1e-2
#: ... and within this many standard deviations (the all-lines fit's std)
REDUCED_VS_ALL_STD = 3.0


def _dense(n: int, noise: float = 0.01, seed: int = 0) -> FrfData:
    doc = two_mass_chain(M_A, M_B, K_A, D_A, K_B, D_B)
    f = np.geomspace(1.0, 1000.0, n)
    H = build_affine_model(doc, {}).linear_model().frf(f)
    Hn, coh = add_measurement_noise(H, f, rel=noise, floor_db=-80.0, rng=seed)
    return FrfData(f, ("a", "b"), ("a", "b"), Hn, coherence=coh, source=f"dense{n}.csv")


def _true_features() -> list[tuple[float, float]]:
    """``(f [Hz], half-power half-width [Hz])`` of the two resonances (damped eigenvalues)
    and of a.a's anti-resonance (the zero of ``k_b + jω d_b − ω² m_b``)."""
    M = np.array([[M_A + M_B, M_B], [M_B, M_B]])
    K = np.diag([K_A, K_B])
    D = np.diag([D_A, D_B])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    out = [(abs(x) / (2 * math.pi), -x.real / (2 * math.pi)) for x in lam]
    z = np.roots([-M_B, 1j * D_B, K_B])
    z = z[z.real > 0][0]
    out.append((abs(z) / (2 * math.pi), D_B / (2 * M_B) / (2 * math.pi)))
    return sorted(out)


def test_every_resonance_and_antiresonance_line_is_kept() -> None:
    ds = _dense(20000)
    red = select_lines(ds, 1500)
    assert red.reduced and red.n_kept <= 1500 and red.n_lines == 20000
    kept = set(red.kept.tolist())
    assert {0, 19999} <= kept
    truth = _true_features()
    assert len(truth) == 3
    for f0, half in truth:
        near = np.flatnonzero(np.abs(ds.freq_hz - f0) <= half)
        assert near.size > 20  # a dense grid: many lines within the half-power band
        assert set(near.tolist()) <= kept, f"lines near {f0:.2f} Hz dropped"
    # the features found are the true ones
    found = [f for f in red.features if f.channel == "a.a"]
    for f0, half in truth:
        assert any(abs(f.f_hz - f0) <= half for f in found), f0
    kinds = {f.kind for f in found}
    assert kinds == {"resonance", "anti-resonance"}
    # the rest is spread log-uniformly: no gap wider than the log step of the budget left
    gaps = np.diff(np.log(ds.freq_hz[red.kept]))
    assert gaps.max() <= 2.5 * math.log(1000.0) / (1500 - red.feature_lines)


def test_reduced_weights_are_those_of_the_full_grid() -> None:
    ds = _dense(6000)
    (red,), info = reduce_datasets([ds], "500")
    idx = info.files[0].kept
    assert red.freq_hz.size == idx.size <= 500
    np.testing.assert_array_equal(red.H, ds.H[:, :, idx])
    for weighting in ("auto", "estimated"):
        np.testing.assert_allclose(
            information_weights(red, weighting), information_weights(ds, weighting)[:, :, idx]
        )
    np.testing.assert_allclose(
        noise_to_signal(red, "auto", prediction=True),
        noise_to_signal(ds, "auto", prediction=True)[:, :, idx],
    )


def test_lines_setting() -> None:
    assert parse_lines(None).mode == "auto"
    assert parse_lines("all").budget(10**6) is None
    assert parse_lines("auto").budget(AUTO_ABOVE) is None
    assert parse_lines("auto").budget(AUTO_ABOVE + 1) == AUTO_LINES
    assert parse_lines("500").budget(400) is None
    assert parse_lines(500).budget(501) == 500
    for bad in ("many", "0", str(MIN_LINES - 1), "1.5", "-200", True):
        with pytest.raises(ConfigError, match="--lines"):
            parse_lines(bad)  # type: ignore[arg-type]
    ds = _dense(300)
    (same,), info = reduce_datasets([ds], "auto")
    assert same is ds and not info.reduced and info.kept_per_file() == [300]


def test_decimate_log_matches_the_nearest_line_search() -> None:
    rng = np.random.default_rng(4)
    f = np.sort(rng.uniform(1.0, 2000.0, 5000))
    ds = FrfData(f, ("a",), ("a",), (1.0 + rng.standard_normal((1, 1, f.size))) + 0j)
    out = decimate_log(ds, 300)
    target = np.geomspace(f[0], f[-1], 300)
    ref = np.unique(np.abs(np.log(f)[None, :] - np.log(target)[:, None]).argmin(axis=1))
    np.testing.assert_array_equal(out.freq_hz, f[ref])
    assert reduce_to(ds, 10**6) is ds
    assert reduce_to(ds, 300).freq_hz.size <= 300


@pytest.mark.slow
def test_fit_on_reduced_lines_matches_the_fit_on_all_lines(tmp_path: Path) -> None:
    from bondid.fit.cli import main

    truth = two_mass_chain(M_A, M_B, K_A, D_A, K_B, D_B)
    model = two_mass_chain(1.2 * M_A, 0.8 * M_B, 0.8 * K_A, 1.3 * D_A, 1.25 * K_B, 0.7 * D_B)
    (tmp_path / "model.urdf").write_text(model.to_string())
    f = np.geomspace(1.0, 1000.0, 6000)
    files = []
    for k, op in enumerate(({}, {"a": 0.05})):
        H = build_affine_model(truth, op).linear_model().frf(f)
        Hn, coh = add_measurement_noise(H, f, rel=0.01, floor_db=-80.0, rng=10 + k)
        ds = FrfData(f, ("a", "b"), ("a", "b"), Hn, coherence=coh, operating_point=op)
        files.append(str(write_csv(ds, tmp_path / f"pose{k}.csv")))
    res = {}
    for lines in ("all", "600"):
        out = tmp_path / f"fit_{lines}"
        argv = ["--model", str(tmp_path / "model.urdf"), "--data", *files, "--out", str(out),
                "--quiet", "--lines", lines, "--prior", "0", "--presolve", "0",
                "--free", "*.mass", "*.stiffness", "*.damping",
                "--fallback", "0", "--fallback-starts", "0"]  # fmt: skip
        assert main(argv) == 0
        res[lines] = json.loads((out / "fit.json").read_text())
    red, full = res["600"], res["all"]
    assert red["lines"]["reduced"] and red["lines"]["kept"] <= 1200
    assert red["lines"]["lines"] == 12000 and not full["lines"]["reduced"]
    for pr, pa in zip(red["parameters"], full["parameters"], strict=True):
        diff = abs(pr["fitted"] - pa["fitted"])
        assert diff <= REDUCED_VS_ALL_REL * abs(pa["fitted"]), pa["name"]
        assert diff <= REDUCED_VS_ALL_STD * max(pa["std"], pr["std"]), pa["name"]
    # the figures are on all lines in both: the same points, the same noise level
    assert red["db_rms"]["noise_level"] == pytest.approx(full["db_rms"]["noise_level"], rel=1e-9)
    assert red["db_rms"]["final"] == pytest.approx(full["db_rms"]["final"], rel=0.02)


def test_lines_in_the_study_file_and_on_the_command_line() -> None:
    from bondid.fit.cli import build_parser, resolve_settings
    from bondid.fit.study import study_from_dict

    assert study_from_dict({"cost": {"lines": 800}}).lines == "800"
    assert study_from_dict({"cost": {"lines": "all"}}).lines == "all"
    assert study_from_dict({}).lines == "auto"
    with pytest.raises(ConfigError, match=r"s\.toml: cost\.lines"):
        study_from_dict({"cost": {"lines": "some"}}, where="s.toml")
    args = build_parser().parse_args(["--model", "m.urdf", "--data", "d.csv", "--lines", "1200"])
    assert resolve_settings(args).lines == "1200"
    bad = build_parser().parse_args(["--model", "m.urdf", "--data", "d.csv", "--lines", "5"])
    with pytest.raises(ConfigError, match="--lines '5'"):
        resolve_settings(bad)


def test_the_budget_goes_to_the_lines_of_the_bands_used() -> None:
    ds = _dense(20000)
    bands = [(30.0, 50.0), (90.0, 140.0)]
    (red,), info = reduce_datasets([ds], "400", bands=bands)
    f = red.freq_hz
    inside = ((f >= 30.0) & (f <= 50.0)) | ((f >= 90.0) & (f <= 140.0))
    assert inside.all() and 300 < f.size <= 400
    assert ((f >= 30.0) & (f <= 50.0)).sum() > 100  # each band gets its share, not 1/40 of it
    assert {round(x.f_hz) for x in info.files[0].features} >= {40, 101, 127}
    (whole,), info = reduce_datasets([ds], "auto", bands=[(30.0, 50.0)])  # ~1500 lines: kept
    assert whole is ds and not info.reduced


def test_a_tight_budget_is_kept_with_every_extremum() -> None:
    ds = _dense(20000)
    for budget in (MIN_LINES, 300):
        red = select_lines(ds, budget)
        assert red.n_kept <= budget and red.feature_lines <= budget
        assert {f.index for f in red.features} <= set(red.kept.tolist())


#: the diagnosis's gap over the noise level, reduced lines against all lines (absolute: the
#: gap itself differs, the reduction keeping relatively more lines near the resonances)
OVER_NOISE_ABS = 0.15


def test_the_diagnosis_works_on_the_reduced_lines_and_says_so(tmp_path: Path) -> None:
    from bondid.diagnose.cli import main

    truth = two_mass_chain(M_A, M_B, K_A, D_A, K_B, D_B)
    model = two_mass_chain(1.2 * M_A, 0.8 * M_B, 0.8 * K_A, 1.3 * D_A, 1.25 * K_B, 0.7 * D_B)
    (tmp_path / "model.urdf").write_text(model.to_string())
    f = np.geomspace(1.0, 1000.0, 6000)
    H = build_affine_model(truth, {}).linear_model().frf(f)
    Hn, coh = add_measurement_noise(H, f, rel=0.01, floor_db=-80.0, rng=3)
    data = str(write_csv(FrfData(f, ("a", "b"), ("a", "b"), Hn, coherence=coh), tmp_path / "d.csv"))
    res = {}
    for lines in ("all", "600"):
        out = tmp_path / f"diag_{lines}"
        argv = ["--model", str(tmp_path / "model.urdf"), "--data", data, "--out", str(out),
                "--quiet", "--lines", lines, "--effects", "sensor_delay", "--workers", "1",
                "--points", "120", "--no-plots"]  # fmt: skip
        assert main(argv) == 0
        res[lines] = json.loads((out / "diagnosis.json").read_text())
    red, full = res["600"], res["all"]
    assert red["lines"]["reduced"] and red["lines"]["kept"] <= 600
    assert red["lines"]["lines"] == 6000 and not full["lines"]["reduced"]
    assert red["verdict"]["outcome"] == full["verdict"]["outcome"]
    over = (red["verdict"]["over_noise"], full["verdict"]["over_noise"])
    assert over[0] == pytest.approx(over[1], abs=OVER_NOISE_ABS)
