"""Tests of bondid.diagnose: effects, refit engine, pipeline verdicts, outputs, CLI, benchmark."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bondid.data.noise import add_measurement_noise
from bondid.linear.affine import build_affine_model
from bondid.model import UrdfDocument, set_parameter
from bondid.simulate import log_grid, simulate

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03})


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def _with_values(effect, doc, cand, scale=1.0):
    aug = effect.augment(doc, cand)
    for p in cand.parameters:
        for m, fac in p.members:
            set_parameter(aug, m, fac * p.initial * scale**p.scan)
    return aug


def _data(truth: UrdfDocument, n: int = 150, noise: float = 0.005, seed: int = 0) -> list:
    f = log_grid(1.0, 4000.0, n)
    out = []
    for k, op in enumerate(OPS):
        d = simulate(truth, op, f)
        d.H, d.coherence = add_measurement_noise(
            d.H, f, rel=noise, floor_db=-70, rng=seed + k, floor_ref="response"
        )
        out.append(d)
    return out


def test_every_effect_augments_and_changes_the_frf(doc):
    from bondid.diagnose.effects import available, get_effects

    assert list(available())[:5] == [
        "joint_compliance", "flexible_base", "soft_mounts", "sensor_delay", "actuator_lag"
    ]  # fmt: skip
    f = np.geomspace(1, 4000, 120)
    H0 = build_affine_model(doc).linear_model().frf(f)
    seen = set()
    for e in get_effects():
        cands = e.candidates(doc)
        assert cands, e.name
        for c in cands:
            if e.is_modifier:
                vals = np.array([p.initial for p in c.parameters])
                G, dG = e.modifier(c, vals, f, ("x", "y", "z"), ("x", "y", "z"))
                H = H0 * G
                # exact derivative against a finite difference
                h = 1e-3 * vals
                G2, _ = e.modifier(c, vals + h, f, ("x", "y", "z"), ("x", "y", "z"))
                np.testing.assert_allclose((G2 - G) / h[0], dG[..., 0], rtol=2e-2, atol=1e-6)
            else:
                aug = e.augment(doc, c)
                reread = UrdfDocument.from_string(aug.to_string())
                model = reread.build_pinocchio_model()  # loads in Pinocchio
                assert model.nv > 11
                H = build_affine_model(reread).linear_model().frf(f)
            assert np.max(np.abs(np.log(H / H0))) > 0.05, c.label
            seen.add(c.effect)
    assert seen == {"joint_compliance", "flexible_base", "soft_mounts", "sensor_delay",
                    "actuator_lag"}  # fmt: skip


def test_joint_compliance_candidates_cover_missing_axes(doc):
    from bondid.diagnose.effects import get_effect

    locs = {c.location for c in get_effect("joint_compliance").candidates(doc)}
    assert locs == {
        "base->x_stage:tz", "base->x_stage:rx", "x_stage->y_stage:tz", "x_stage->y_stage:ry",
        "y_stage->z_stage:tx", "y_stage->z_stage:ty", "y_stage->z_stage:tz",
    }  # fmt: skip


def test_refit_jacobian_matches_finite_differences(doc):
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.engine import Refit
    from bondid.diagnose.pipeline import default_names
    from bondid.diagnose.runner import _modifier
    from bondid.diagnose.variables import Variable, nominal_variables

    data = _data(doc, n=40)
    names = [n for n in default_names(doc, None) if n.startswith(("z_stage", "z_bearing"))]
    e = get_effect("actuator_lag")
    c = e.candidates(doc)[1]
    p = c.parameters[0]
    variables = [*nominal_variables(doc, names), Variable("T", p.initial, p.lower, p.upper,
                                                          modifier=0)]  # fmt: skip
    R = Refit(doc, data, variables, modifier=_modifier(e, c))
    u = R.u0 + 0.01
    _, J = R.residual_and_jacobian(u)
    for k in range(len(u)):
        h = 1e-7 if not variables[k].log else 1e-6
        du = np.zeros(len(u))
        du[k] = h
        fd = (R.residual(u + du) - R.residual(u - du)) / (2 * h)
        assert np.max(np.abs(J[:, k] - fd)) <= 1e-3 * max(np.max(np.abs(fd)), 1e-9), k


def _settings(**kw):
    from bondid.diagnose.pipeline import Settings

    base = dict(n_points=150, workers=1, use_ipopt=False, modes=False, n_starts=2)
    base.update(kw)
    return Settings(**base)


@pytest.fixture(scope="module")
def compliance_case(doc):
    from bondid.diagnose import diagnose
    from bondid.diagnose.effects import get_effect

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "y_stage->z_stage:tz")
    truth = _with_values(e, doc, c, scale=5.0)
    data = _data(truth)
    diag = diagnose(doc, data, _settings(effects=["joint_compliance", "sensor_delay"]))
    return diag


def test_withheld_joint_compliance_is_found_first(compliance_case):
    diag = compliance_case
    assert diag.results[0].effect == "joint_compliance"
    assert diag.results[0].location == "y_stage->z_stage:tz"
    assert diag.winner is diag.results[0]
    assert diag.results[0].heldout_rms < 0.7 * diag.baseline.heldout_rms


def test_none_case_gives_verdict_none(doc):
    from bondid.diagnose import diagnose

    data = _data(doc, seed=5)
    diag = diagnose(doc, data, _settings(effects=["joint_compliance", "actuator_lag"]))
    assert diag.winner is None


def test_diagnosis_json_has_the_spec_keys(compliance_case, tmp_path):
    from bondid.diagnose import write_outputs

    written = write_outputs(compliance_case, tmp_path, plots=False)
    d = json.loads((tmp_path / "diagnosis.json").read_text())
    assert {"gap", "candidates", "verdict"} <= set(d)
    assert {"db_rms", "by_channel", "by_band", "modes"} <= set(d["gap"])
    assert {"f_lo_hz", "f_hi_hz", "db_rms"} <= set(d["gap"]["by_band"][0])
    for c in d["candidates"]:
        assert {"effect", "location", "parameters", "db_rms_after", "gap_closed",
                "heldout_db_rms_after", "score"} <= set(c)  # fmt: skip
    scores = [c["score"] for c in d["candidates"] if c["score"] is not None]
    assert scores == sorted(scores)
    assert {"effect", "location", "gap_closed"} <= set(d["verdict"])
    assert d["verdict"]["effect"] == "joint_compliance"
    g = d["verdict"]["gap_closed"]
    assert g == pytest.approx(1 - d["candidates"][0]["db_rms_after"] / d["gap"]["db_rms"])
    # information weights (spec extension): which, how, and the unweighted figure kept
    assert d["gap"]["weighting"] == d["weighting"]["weighting"] == "auto"
    assert d["gap"]["db_rms_unweighted"] > 0 and "db_rms" in d["scoring"]
    assert {"rho", "floor_median", "informative_share"} <= set(
        d["weighting"]["datasets"][0]["channels"][0]
    )
    assert (tmp_path / "augmented.urdf") in written
    UrdfDocument.load(tmp_path / "augmented.urdf").build_pinocchio_model()


def test_cli_exit_2_on_missing_file(tmp_path):
    cmd = [sys.executable, "-m", "bondid.diagnose", "--model", str(MODEL), "--data",
           str(tmp_path / "missing.csv"), "--quiet"]  # fmt: skip
    env = {"PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert proc.returncode == 2
    assert "missing.csv" in proc.stderr


def test_rotational_candidates_carry_pivot_variants(doc):
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.topology import axis_vector

    for c in get_effect("joint_compliance").candidates(doc):
        kind, vec = axis_vector(c.location.rsplit(":", 1)[1])
        if kind == "prismatic":
            assert c.variants == ()
            continue
        assert len(c.variants) >= 4, c.location
        main = np.array(c.spec["pivot"])
        along = np.abs(vec) > 0.5
        for v in c.variants:
            moved = np.abs(np.array(v.spec["pivot"]) - main) > 1e-12
            # one coordinate across the axis moves, nothing along it
            assert moved.sum() == 1 and not np.any(moved & along), (c.location, v.spec)
            assert v.location == c.location and v.variants == ()
        # the child frame's origin is among the levels tried in each direction across
        for d in np.flatnonzero(~along):
            levels = [v.spec["pivot"][d] for v in c.variants] + [main[d]]
            assert min(abs(x) for x in levels) < 0.003, (c.location, d, levels)


def test_screening_picks_the_pivot_that_made_the_data(doc):
    """Known answer: data from the nominal model plus a y-guide pitch DOF pivoting at one of
    the variants' pivots; the screening (from the nominal model) keeps that variant."""
    from dataclasses import replace

    from bondid.cost.problem import CostOptions
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.runner import Job, _screen_variants
    from bondid.diagnose.variables import nominal_variables

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "x_stage->y_stage:ry")
    target = max(c.variants, key=lambda v: v.spec["pivot"][2])  # the top face of the stage
    truth = _with_values(e, doc, replace(target, variants=()), scale=2.0)
    data = _data(truth, n=150)
    nom = nominal_variables(doc, ["x_stage.mass", "y_stage.mass", "z_stage.mass"])
    text = doc.to_string()
    job = Job(text, nom, data, data, data, c, CostOptions(), alt_urdf=text, alt_nominal=nom)
    picked, cost = _screen_variants(job)
    assert picked.candidate is not None and picked.candidate.variants == ()
    assert picked.candidate.spec["pivot"] == target.spec["pivot"], picked.candidate.description
    # a clear pick: every other pivot screens at least 20 % worse
    for v in (c, *c.variants):
        if v.spec["pivot"] != target.spec["pivot"]:
            other = _screen_variants(replace(job, candidate=replace(v, variants=())))[1]
            assert other > 1.2 * cost, (v.description, other, cost)
