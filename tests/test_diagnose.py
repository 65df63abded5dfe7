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

    five = ["joint_compliance", "flexible_base", "soft_mounts", "sensor_delay", "actuator_lag"]
    assert list(available())[:5] == five  # the later effects: tests/test_effect_*.py
    f = np.geomspace(1, 4000, 120)
    H0 = build_affine_model(doc).linear_model().frf(f)
    seen = set()
    for e in get_effects(five):
        cands = e.candidates(doc)
        assert cands, e.name
        for c in cands:
            if e.is_modifier:
                vals = np.array([p.initial for p in c.parameters])
                G, dG = e.modifier(c, vals, f, ("x", "y", "z"), ("x", "y", "z"))
                H = H0 * G
                # each exact derivative against a finite difference
                for k in range(vals.size):
                    h = np.where(np.arange(vals.size) == k, 1e-3 * vals, 0.0)
                    G2, _ = e.modifier(c, vals + h, f, ("x", "y", "z"), ("x", "y", "z"))
                    np.testing.assert_allclose((G2 - G) / h[k], dG[..., k], rtol=2e-2, atol=1e-6)
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


def _settings(**kw):
    from bondid.diagnose.pipeline import Settings

    base = dict(n_points=150, workers=1, modes=False)
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
    s = _settings(effects=["joint_compliance", "sensor_delay"], free=FEW)
    return diagnose(doc, data, s)


def test_withheld_joint_compliance_is_found_first(compliance_case):
    diag = compliance_case
    assert diag.results[0].effect == "joint_compliance"
    assert diag.results[0].location == "y_stage->z_stage:tz"
    assert diag.winner is diag.results[0]
    assert diag.results[0].heldout_rms < 0.7 * diag.baseline.heldout_rms
    assert diag.outcome is not None and diag.outcome.kind == "explained"
    assert diag.outcome.grades == ["confirmed"]


@pytest.mark.slow
def test_none_case_gives_verdict_none(doc):
    from bondid.diagnose import diagnose

    data = _data(doc, seed=5)
    s = _settings(effects=["joint_compliance", "actuator_lag"], free=FEW)
    diag = diagnose(doc, data, s)
    assert diag.winner is None and len(diag.steps) == 1
    # no effect kept: never "partly explained"; whether the parameter refit counts as at the
    # held-out noise level here rests on some 40 independent held-out points of 150 lines
    # (their sampling error is the rule's own), so either other answer is honest
    assert diag.outcome is not None and diag.outcome.kind in ("explained", "unexplained")
    assert diag.outcome.grades == []


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
    first = [c for c in d["candidates"] if c["step"] == 1]
    scores = [c["score"] for c in first if c["score"] is not None]
    assert scores == sorted(scores) and len(scores) == sum(c["refitted"] for c in first)
    # every candidate screened; the refitted ones come first, the others by screening figure
    assert len(first) == len(compliance_case.steps[0].screenings)
    rest = [c["screening_db"] for c in first if not c["refitted"]]
    assert rest == sorted(rest) and all(c["screening_db"] is not None for c in first)
    assert [(e["effect"], e["location"]) for e in d["effects"]] == [
        ("joint_compliance", "y_stage->z_stage:tz")
    ]
    assert d["dropped"] == [] and "elimination" in d["scoring"]  # one effect: nothing to drop
    assert {"effect", "location", "gap_closed"} <= set(d["verdict"])
    assert d["verdict"]["effect"] == "joint_compliance"
    g = d["verdict"]["gap_closed"]
    assert g == pytest.approx(1 - d["candidates"][0]["db_rms_after"] / d["gap"]["db_rms"])
    # the refits the data cannot tell from the verdict: the rule's figures, from the scores
    from bondid.diagnose import scoring

    ties = scoring.indistinguishable(scores, d["scoring"]["steps"][0])
    listed = d["verdict"]["indistinguishable_from"]
    assert [t["score"] for t in listed] == [scores[j] for j, _ in ties]
    assert listed == d["effects"][0]["indistinguishable_from"]
    # information weights (spec extension): which, how, and the unweighted figure kept
    assert d["gap"]["weighting"] == d["weighting"]["weighting"] == "auto"
    assert d["gap"]["db_rms_unweighted"] > 0 and "db_rms" in d["scoring"]
    assert {"rho", "floor_median", "informative_share"} <= set(
        d["weighting"]["datasets"][0]["channels"][0]
    )
    assert (tmp_path / "augmented.urdf") in written
    UrdfDocument.load(tmp_path / "augmented.urdf").build_pinocchio_model()
    # the final model refitted on all data (spec extension, .final_fit): of the accepted
    # effects, never worse on all data than the model it starts from
    ff = d["final_fit"]
    assert ff["effects"] == [
        {"effect": "joint_compliance", "location": "y_stage->z_stage:tz", "detail": None}
    ]
    assert ff["db_rms_before"] == pytest.approx(d["effects"][-1]["db_rms_after"])
    assert ff["db_rms"] <= ff["db_rms_before"] and ("kept" in ff["note"])
    assert ff["starts"] is None or isinstance(ff["starts"], str)  # the starts tried, if several
    assert (tmp_path / "final.urdf") in written
    UrdfDocument.load(tmp_path / "final.urdf").build_pinocchio_model()


def test_cli_exit_2_on_missing_file(tmp_path):
    cmd = [sys.executable, "-m", "bondid.diagnose", "--model", str(MODEL), "--data",
           str(tmp_path / "missing.csv"), "--quiet"]  # fmt: skip
    env = {"PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert proc.returncode == 2
    assert "missing.csv" in proc.stderr


def test_rotational_candidates_free_the_pivot_and_start_it_in_several_places(doc):
    """A rotational candidate's pivot is two signed parameters (shifts across the axis, 0 at
    the bearing centre); its variants build the same model and start the pivot elsewhere
    across the axis (nothing along it), on a grid that spans the child's collision hull in
    both directions across the axis, moving both coordinates at once."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.joint_compliance import PIVOT_GRID, PIVOT_TOL
    from bondid.diagnose.effects.topology import axis_vector, link_box
    from bondid.model.pivot import pivot_of

    e = get_effect("joint_compliance")
    for c in e.candidates(doc):
        kind, vec = axis_vector(c.location.rsplit(":", 1)[1])
        names = [p.name for p in c.parameters]
        if kind == "prismatic":
            assert c.variants == () and names == ["stiffness", "damping"]
            continue
        assert names == ["stiffness", "damping", "pivot_u", "pivot_v"], c.location
        shifts = [p for p in c.parameters if p.name.startswith("pivot")]
        assert all(p.signed and p.initial == 0 and p.lower < 0 < p.upper for p in shifts)
        main = np.array(c.spec["pivot"])
        assert np.allclose(pivot_of(e.augment(doc, c), c.spec["joint"]), main)
        along = np.abs(vec) > 0.5
        starts = []
        for v in c.variants:
            assert v.spec == c.spec and v.location == c.location and v.variants == ()
            start = pivot_of(e.augment(doc, v), c.spec["joint"])
            assert not np.any((np.abs(start - main) > 1e-12) & along), v.description
            starts.append(start)
        child = c.location.split("->")[1].split(":")[0]
        box = link_box(doc, child)
        assert box is not None, child
        assert len(starts) >= PIVOT_GRID**2 - 1 - 1, c.location  # the grid, less the centre
        across = np.flatnonzero(~along)
        both = [p for p in starts if np.all(np.abs(p - main)[across] > PIVOT_TOL)]
        assert len(both) >= (PIVOT_GRID - 1) ** 2, c.location
        for d in across:  # the grid reaches both faces of the hull
            levels = np.array([p[d] for p in starts])
            assert np.min(np.abs(levels - box[0][d])) < 1e-9, (c.location, d)
            assert np.min(np.abs(levels - box[1][d])) < 1e-9, (c.location, d)


#: the refitted pivot within this of the one that made the data [m] (0.5 % noise)
PIVOT_FOUND_M = 0.003


def test_the_refit_finds_a_pivot_none_of_the_starts_has(doc):
    """Known answer: data from the nominal model plus a y-guide pitch DOF pivoting 2 cm and
    1.5 cm away from the bearing centre in both directions across the axis (no start's pivot
    within the accuracy asked of the refit); the candidate's refit places the pivot there and
    its cost is the truth's."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.job import Task
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.refit_job import run_refit
    from bondid.model.pivot import pivot_of

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "x_stage->y_stage:ry")
    truth_cand = with_values(c, [2 * c.parameters[0].initial, c.parameters[1].initial,
                                 0.02, -0.015])  # fmt: skip
    truth = e.augment(doc, truth_cand)
    pivot = pivot_of(truth, c.spec["joint"])
    assert min(np.linalg.norm(pivot - pivot_of(e.augment(doc, v), c.spec["joint"]))
               for v in [c, *c.variants]) > PIVOT_FOUND_M  # fmt: skip
    data = _data(truth, n=150)
    nom = nominal_space(doc, ["x_stage.mass", "y_stage.mass", "z_stage.mass"], 4000.0)
    r = run_refit(Task(doc.to_string(), nom, data, data, data, CostOptions(), candidate=c))
    assert not r.error
    fitted = UrdfDocument.from_string(r.urdf)
    assert np.linalg.norm(pivot_of(fitted, c.spec["joint"]) - pivot) < PIVOT_FOUND_M
    assert r.variant.startswith("pivot ")
    assert r.noise_ratio is not None and r.noise_ratio < 1.1, r.noise_ratio


def _lagged(data: list, cand, T: float, T2: float = 0.0) -> list:  # type: ignore[no-untyped-def]
    """``data`` with the actuator lag ``cand`` of lag time ``T`` and second-order time ``T2``
    applied (known answer; ``T2 = 0``: a first-order lag)."""
    from bondid.diagnose.effects import get_effect

    e = get_effect(cand.effect)
    for d in data:
        v = np.array([T, T2])
        G, _ = e.modifier(cand, v, d.freq_hz, tuple(d.outputs), tuple(d.inputs))
        d.H = d.H * G
    return data


def test_a_two_pole_lag_is_refitted_to_its_poles(doc):
    """Known answer: data of the nominal model with an amplifier of two real poles on input y
    (time constants 120 µs and 15 µs); the lag's refit from the candidate's start (a 50 µs,
    nearly first-order lag) recovers the lag time ``T = T₁ + T₂'`` and the second-order
    time ``T₂ = √(T₁T₂')``, and the FRF factor is the product of the two poles."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.refit import nominal_space
    from bondid.optim.schedules import direct

    e = get_effect("actuator_lag")
    lag = next(k for k in e.candidates(doc) if k.location == "y")
    t1, t2 = 120e-6, 15e-6
    T, T2 = t1 + t2, float(np.sqrt(t1 * t2))
    f = np.geomspace(1.0, 4000.0, 9)
    G, _ = e.modifier(lag, np.array([T, T2]), f, ("x", "y"), ("x", "y"))
    jw = 2j * np.pi * f
    np.testing.assert_allclose(G[0, 1], 1.0 / ((1 + jw * t1) * (1 + jw * t2)), rtol=1e-12)
    np.testing.assert_allclose(G[:, 0], 1.0, rtol=0)  # the other input is left alone
    data = _lagged(_data(doc, n=150), lag, T, T2)
    refit = build(doc.to_string(), nominal_space(doc, FEW, 4000.0), data, CostOptions(), (),
                  lag).refit  # fmt: skip
    state, _, _ = refit.solve(refit.state0, direct(30), max_iter=150)
    got_T, got_T2 = refit.new_values(state)
    REL_LAG = 0.02  # 0.5 % noise on 2 × 150 frequencies: both times within 2 %
    assert got_T == pytest.approx(T, rel=REL_LAG)
    assert got_T2 == pytest.approx(T2, rel=REL_LAG)


def test_composed_modifier_derivatives_match_finite_differences(doc):
    from bondid.diagnose.augmented import ComposedModifier
    from bondid.diagnose.effects import get_effect

    sd = next(c for c in get_effect("sensor_delay").candidates(doc) if c.location == "x")
    al = next(c for c in get_effect("actuator_lag").candidates(doc) if c.location == "all")
    mod = ComposedModifier([sd, al])
    f = np.geomspace(10.0, 3000.0, 7)
    outs, ins = ("x", "y", "z"), ("x", "y", "z")
    v = np.array([4e-5, 7e-5, 2.5e-5])
    G, dG = mod(v, f, outs, ins)
    g1, _ = get_effect("sensor_delay").modifier(sd, v[:1], f, outs, ins)
    g2, _ = get_effect("actuator_lag").modifier(al, v[1:], f, outs, ins)
    np.testing.assert_allclose(G, g1 * g2, rtol=1e-14)
    for k in range(3):
        h = 1e-6 * v[k]
        vp, vm = v.copy(), v.copy()
        vp[k] += h
        vm[k] -= h
        fd = (mod(vp, f, outs, ins)[0] - mod(vm, f, outs, ins)[0]) / (2 * h)
        np.testing.assert_allclose(dG[..., k], fd, rtol=1e-6, atol=1e-9 * np.abs(fd).max())


FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]


def test_screening_ranks_the_withheld_effect_first(doc):
    """Known answer: every candidate screened on data of the nominal model plus one joint
    compliance; the true one has the best figure, and a figure (one joint Gauss–Newton step)
    is never above the objective of the start it is taken at."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.effects import get_effect, get_effects
    from bondid.diagnose.job import Task
    from bondid.diagnose.refit import State, nominal_space
    from bondid.diagnose.refit_job import Models
    from bondid.diagnose.screen import screen

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "x_stage->y_stage:tz")
    data = _data(_with_values(e, doc, c, scale=2.0), n=120)
    nom = nominal_space(doc, FEW, 4000.0)
    text = doc.to_string()
    cands = [
        c for e in get_effects(["joint_compliance", "actuator_lag"]) for c in e.candidates(doc)
    ]
    tasks = [Task(text, nom, data, data, data, CostOptions(), candidate=k) for k in cands]
    screens = [screen(t) for t in tasks]
    best = min(screens, key=lambda s: s.cost)
    assert best.label == c.label, sorted((s.cost, s.label) for s in screens)
    models = Models(tasks[cands.index(c)])
    for st in best.starts:
        if np.isfinite(st.figure):
            refit = models[st.variant].refit
            assert st.figure <= refit.cost(State(st.x, st.theta)) + 1e-12


@pytest.mark.slow
def test_two_withheld_effects_are_found_in_order(doc, tmp_path):
    """Known answer: a joint compliance and an actuator lag withheld together; the search
    accepts both (class and location), one per step, and no third."""
    from bondid.diagnose import diagnose, write_outputs
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.report import gaps, to_json_dict
    from bondid.diagnose.summary import summary

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "y_stage->z_stage:tz")
    al = next(k for k in get_effect("actuator_lag").candidates(doc) if k.location == "y")
    data = _lagged(_data(_with_values(e, doc, c, scale=3.0), n=150), al, 2e-4)
    s = _settings(effects=["joint_compliance", "actuator_lag"], free=FEW)
    diag = diagnose(doc, data, s)
    content = to_json_dict(diag, gaps(diag))
    got = [(x["effect"], x["location"]) for x in content["effects"]]
    assert sorted(got) == sorted([(c.effect, c.location), (al.effect, al.location)]), got
    assert content["dropped"] == []  # both true: the backward elimination keeps them
    # each model without one effect, the one the search fitted refitted again as well
    assert diag.pruning is not None and diag.pruning.n_refits == 2
    assert content["verdict"]["effect"] == content["effects"][0]["effect"]
    after = [x["db_rms_after"] for x in content["effects"]]
    assert after[1] < after[0] < content["gap"]["db_rms"]
    # the third step: its base (both effects) at the noise level, so recorded, not run
    steps = {x["step"] for x in content["candidates"]}
    third = content["scoring"]["steps"][2]
    assert steps == {1, 2} and len(content["scoring"]["steps"]) == 3
    assert third["screened"] is False and not third["accepted"]
    assert third["base_above_noise"] is False and third["base_over_noise"] > 0
    assert all("refitted" in x and "screening_db" in x for x in content["candidates"])
    assert "→ +" in summary(diag, content)
    written = write_outputs(diag, tmp_path, plots=False)
    assert (tmp_path / "augmented_all.urdf") in written


def test_a_modal_identification_error_reaches_the_report(doc, monkeypatch):
    """The error row of a failed modal identification is kept next to the model's modes."""
    from bondid.diagnose import diagnose
    from bondid.modal import identify as modal_id

    def fail(*_a, **_k):  # type: ignore[no-untyped-def]
        raise ValueError("no poles")

    monkeypatch.setattr(modal_id, "identify_modes", fail)
    data = _data(doc, n=60)
    s = _settings(effects=["sensor_delay"], free=FEW[:1], modes=True, n_points=60)
    diag = diagnose(doc, data, s)
    for rows in diag.modes_by_dataset:
        assert rows[0] == {"error": "modal identification failed: no poles"}
        assert any("status" in r for r in rows[1:])  # the model's modes are still listed


@pytest.mark.parametrize("n_nodes", [1, 0, 2.5, True, "4"])
def test_a_flexible_base_of_too_few_nodes_is_refused(n_nodes):
    from bondid.diagnose.effects.flexible_base import FlexibleBase
    from bondid.exceptions import ConfigError

    with pytest.raises(ConfigError, match="n_nodes"):
        FlexibleBase(n_nodes=n_nodes)


def test_a_flexible_base_of_n_nodes_has_n_masses_and_its_modes(doc):
    """Known answer: the candidate of N nodes augments the root into N lumps of the uniform
    rod's shares of the root's mass (the total kept), and its first elastic shear mode is at
    the candidate's reference frequency (F0_HZ) for every N."""
    from bondid.diagnose.effects.flexible_base import F0_HZ, FlexibleBase, rod_shares
    from bondid.model.parameters import link_inertial

    M = link_inertial(doc, doc.root_link())[0]
    for n in (2, 4, 6):
        fb = FlexibleBase(n_nodes=n)
        (c,) = fb.candidates(doc)
        masses = [p.initial for p in c.parameters if p.name.endswith("_mass")]
        assert masses == pytest.approx(M * rod_shares(n), rel=1e-12)
        assert sum(masses) == pytest.approx(M, rel=1e-12)
        kx = next(p.initial for p in c.parameters if p.name == "shear_x_stiffness")
        K = np.zeros((n, n))
        for i in range(n - 1):
            K[i : i + 2, i : i + 2] += kx * np.array([[1.0, -1.0], [-1.0, 1.0]])
        w2 = np.sort(np.linalg.eigvals(np.linalg.solve(np.diag(masses), K)).real)
        assert np.sqrt(w2[1]) / (2 * np.pi) == pytest.approx(F0_HZ, rel=1e-9)
        aug = fb.augment(doc, c)
        lumps = [f"flexible_base_{i}" for i in range(n - 1)]
        assert all(name in aug.link_names for name in lumps)
        assert f"flexible_base_{n - 1}" not in aug.link_names


def test_tied_and_modifier_parameters_refitted_through_the_core(doc):
    """Known answer: a flexible base (each shear/compression parameter ties the joints of
    every segment) and an accepted actuator lag (the FRF modifier) withheld together; the
    core's refit (FitProblem with ties, modifier and prior) started 30 % off recovers every
    new parameter; the tied members follow their leader in the fitted model."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build, with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.flexible_base import FlexibleBase
    from bondid.diagnose.refit import nominal_space
    from bondid.model import get_parameter
    from bondid.optim.schedules import direct

    # four nodes: this answer is about ties and the modifier; the default chain's six masses
    # are less determined by these 150 lines (its own known answer: test_diagnose_structural)
    fb = FlexibleBase(n_nodes=4)
    c = fb.candidates(doc)[0]
    truth = np.array([p.initial * 0.5**p.scan for p in c.parameters])  # modes at 500 Hz
    lag = next(k for k in get_effect("actuator_lag").candidates(doc) if k.location == "y")
    T = 2e-4
    data = _lagged(_data(fb.augment(doc, with_values(c, truth)), n=150), lag, T)
    start = with_values(c, 1.3 * truth)
    space = nominal_space(doc, FEW, 4000.0)
    lag0 = with_values(lag, [T / 1.3, T / 13])
    refit = build(doc.to_string(), space, data, CostOptions(), (lag0,), start).refit
    assert not any(v.held for v in refit.new)
    # every node's mass (one link each) is free, untied; the springs and dampers tied: one
    # member per segment (a stiffness, the compression damper), two (the shear damper)
    assert all(len(v.ties) in (0, 2, 5) for v in refit.new if v.leader)
    assert [len(v.ties) for v in refit.new if v.name.endswith("mass")] == [0] * 4
    state, _, res = refit.solve(refit.state0, direct(30), max_iter=150)
    got = dict(zip(["T", "T2", *(p.name for p in c.parameters)],
                   refit.new_values(state, own=False), strict=True))  # fmt: skip
    # the lag was first order: its second-order term stays below 1 % of the first's square
    assert (got.pop("T2") / got["T"]) ** 2 < 0.01, got
    want = {"T": T, **{p.name: v for p, v in zip(c.parameters, truth, strict=True)}}
    REL_STIFF = 0.02  # 0.5 % noise on 2 × 150 frequencies: stiffness and lag within 2 %
    REL_DAMP = 0.15  # the dampers of modes at 500 Hz and above: within 15 %
    REL_MASS = 0.05  # the chassis's node masses (the bottom one the least determined)
    for name, v in got.items():
        tol = {"damping": REL_DAMP, "mass": REL_MASS}.get(name.rsplit("_", 1)[-1], REL_STIFF)
        assert v == pytest.approx(want[name], rel=tol), (name, v, want[name])
    fitted = res.result.document
    for p in c.parameters:
        (_, f0), *rest = p.members
        for m, f in rest:
            assert get_parameter(fitted, m) == pytest.approx(f / f0 * get_parameter(
                fitted, p.members[0][0]), rel=1e-9)  # fmt: skip
    # the std of every parameter from one Jacobian (named columns and ∂r/∂θ): the θ column
    # against central finite differences of the residual, and the named std can only widen
    from bondid.optim.result import parameter_statistics

    fit, std_theta = refit.result(res)
    theta = refit.state_theta(fit)
    p = refit.problem.restrict(start=fit.fitted, theta=theta)
    r, J_named = p.named_residual_and_jacobian(p.z0)
    EPS = 1e-6  # relative step of the finite differences
    cols = []
    for k in range(theta.size):
        step = np.where(np.arange(theta.size) == k, EPS * theta, 0.0)
        r_hi = p.restrict(theta=theta + step).residual(p.z0)[: p.n_residuals]
        r_lo = p.restrict(theta=theta - step).residual(p.z0)[: p.n_residuals]
        cols.append((r_hi - r_lo) / (2 * step[k]))
    J_fd = np.column_stack(cols)
    std_fd, _ = parameter_statistics(np.hstack([J_named, J_fd]), r)
    assert std_theta == pytest.approx(std_fd[-theta.size :], rel=1e-4)
    assert np.isfinite(std_theta).all() and 0 < std_theta[0] < REL_STIFF * T
    live = np.isfinite(res.result.std) & np.isfinite(fit.std)
    assert np.all(fit.std[live] >= 0.999 * res.result.std[live])


def _spy_start_final(monkeypatch) -> tuple[list, list]:
    """Record the source of every final fit the pipeline starts, and what it returned."""
    from bondid.diagnose import pipeline

    sources: list = []
    pending: list = []
    real = pipeline.start_final

    def spy(source, *a, **k):
        sources.append(source)
        pending.append(real(source, *a, **k))
        return pending[-1]

    monkeypatch.setattr(pipeline, "start_final", spy)
    return sources, pending


@pytest.mark.slow
def test_the_plots_are_drawn_while_the_final_fit_runs(doc, tmp_path, monkeypatch):
    """``during_final`` sees the diagnosis before its final fit (``final`` None, the plots'
    inputs all there) while a worker runs it; the returned diagnosis has the final fit and a
    finite wall time; the plots drawn then are the residual map and a Bode PNG per data set.
    The final fit run in a worker equals the same task run here."""
    import math

    from bondid.diagnose import diagnose, pipeline
    from bondid.diagnose.final_fit import final_task, judged
    from bondid.diagnose.refit_job import run_refit
    from bondid.diagnose.report import write_plots

    sources, tasks = [], []
    real = pipeline.start_final

    def spy(source, base, restart, pool):
        sources.append(source)
        tasks.append(final_task(source, base, restart))
        return real(source, base, restart, pool)

    monkeypatch.setattr(pipeline, "start_final", spy)
    seen = []

    def draw(d):
        seen.append(d.final)
        seen.extend(write_plots(d, tmp_path))

    data = _data(doc, n=60)
    s = _settings(effects=["sensor_delay"], free=FEW[:1], n_points=60, workers=2)
    diag = diagnose(doc, data, s, during_final=draw)
    assert seen[0] is None and diag.final is not None and math.isfinite(diag.wall_s)
    names = {"residual_map.png", *(f"bode_{k + 1}.png" for k in range(len(data)))}
    assert {p.name for p in seen[1:]} == names
    assert all(p.stat().st_size > 0 for p in seen[1:])
    assert len(sources) == 1 and diag.final.source is sources[0]
    here = judged(sources[0], run_refit(tasks[0]))
    assert here.kept == diag.final.kept
    assert here.model.db_rms == pytest.approx(diag.final.model.db_rms, rel=SAME_FIT)


#: relative agreement of one final fit run in a worker and here
SAME_FIT = 1e-6


def test_the_summary_says_why_a_candidate_or_the_modes_are_missing():
    """A refit whose strength the data leave open is marked in the candidate list (it cannot
    be the verdict whatever its score), and a failed modal identification is printed instead
    of an empty pairing."""
    from types import SimpleNamespace

    from bondid.diagnose.summary import summary

    gap = {
        "db_rms": 2.0,
        "by_channel": {"x.x": 2.0},
        "by_band": [],
        "modes": [],
        "modes_error": "modal identification failed: a.csv: no channel without a gap",
    }
    stage = {"db_rms": 2.0}
    content = {
        "stages": {"nominal": {"db_rms": 3.0}, "effect": stage}, "gap": gap,
        "candidates": [
            {"step": 1, "refitted": True, "effect": "joint_compliance", "location": "a->b:ry",
             "score": 1.1, "strength_z": 1e-4},
            {"step": 1, "refitted": True, "effect": "sensor_delay", "location": "x",
             "score": 1.9, "strength_z": 12.0},
        ],
        "verdict": {"effect": "none", "reason": "no candidate passes"},
    }  # fmt: skip
    diag = SimpleNamespace(channels=["x.x"], baseline_score=2.0, wall_s=1.0)
    text = summary(diag, content)  # type: ignore[arg-type]
    assert "modes: modal identification failed: a.csv" in text
    lines = text.splitlines()
    jc = next(x for x in lines if "joint_compliance@a->b:ry" in x)
    sd = next(x for x in lines if "sensor_delay@x" in x)
    assert "strength undetermined: z = 0.0001 < 3" in jc and "undetermined" not in sd
