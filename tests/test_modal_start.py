"""Tests of the starts from the measured modes and the restart alternation of a candidate with
several springs (bondid.diagnose.modal_start), on the bonder with withheld soft mounts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from models import noisy_bonder_data

from bondid.diagnose import modal_start as ms
from bondid.diagnose import mode_match
from bondid.diagnose.effects import get_effect
from bondid.model import UrdfDocument, set_parameter

ROOT = Path(__file__).resolve().parents[1]
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
#: the truth's errors on FEW (factors)
ERRORS = (1.2, 0.85, 1.15, 0.8)
#: the truth's mount modes [Hz] per spring (tx, ty, tz, rx, ry, rz): unequal, as real mounts
MOUNT_HZ = (9.0, 11.0, 16.0, 21.0, 25.0, 13.0)
ZETA = (0.02, 0.03)  # translations, rotations
#: the alternation's start: the truth's springs times this (inside the basin the module
#: docstring measured: within ~40 %)
START_OFF = 1.3
#: the alternation's end: springs within this factor of the truth's ...
SPRING_FACTOR = 1.1
#: ... but for this many: the y mount (11 Hz, beside the 12.5 Hz arm mode) with its own
#: damping ratio is not determined by these data (measured: y 17-75x stiffer and overdamped
#: scores the truth model's data cost, 6.995-7.001 against 6.996)
UNDETERMINED = 1
#: ... and its data cost within this multiple of the truth model's own
COST_FACTOR = 1.5


def _mounts(doc: UrdfDocument):
    return get_effect("soft_mounts").candidates(doc)[0]


def test_only_structural_candidates_get_modal_starts():
    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    assert ms.applies(_mounts(doc)) and len(ms.springs(_mounts(doc))) == 6
    assert not ms.single(_mounts(doc))
    fb = get_effect("flexible_base").candidates(doc)
    assert fb and all(ms.applies(c) and not ms.single(c) for c in fb)
    jc = get_effect("joint_compliance").candidates(doc)
    assert jc and all(ms.applies(c) and ms.single(c) for c in jc)
    assert not any(ms.applies(c) for c in get_effect("sensor_delay").candidates(doc))
    assert not ms.applies(None) and not ms.single(None)


@pytest.fixture(scope="module")
def case():
    """Data of the bonder with errors on FEW and withheld soft mounts (MOUNT_HZ, ZETA); the
    nominal model, the candidate and the truth's new values."""
    from bondid.diagnose.augmented import with_values

    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    c = _mounts(doc)
    from bondid.model.parameters import get_parameters

    truth = doc.copy()
    for name, v, f in zip(FEW, get_parameters(doc, FEW), ERRORS, strict=True):
        set_parameter(truth, name, float(v) * f)
    new = np.array([q.initial for q in c.parameters])
    for i, f in zip(ms.springs(c), MOUNT_HZ, strict=True):
        new[i] *= (f / c.ref_hz) ** 2
    new[6:9], new[9:12] = ZETA  # one damping ratio per mount DOF
    data = noisy_bonder_data(get_effect("soft_mounts").augment(truth, with_values(c, new)))
    return doc, c, data, new, truth


def _refit(doc, c, data):
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build
    from bondid.diagnose.refit import nominal_space

    return build(doc.to_string(), nominal_space(doc, FEW, 4000.0), data, CostOptions(), (), c)


def test_the_alternation_reaches_the_truth_from_springs_near_it(case):
    """Known answer: from the nominal model (its errors not refitted), the springs 30 % off
    and the damping ratios at their start values, the restart alternation ends with every
    spring but UNDETERMINED within SPRING_FACTOR of the truth's and the data cost within
    COST_FACTOR of the truth model's own."""
    doc, c, data, new, truth = case
    refit = _refit(doc, c, data).refit
    start = np.array([q.initial for q in c.parameters])
    idx = ms.springs(c)
    start[idx] = new[idx] * START_OFF
    state, cost, _ = ms.alternation(refit, start)
    assert np.isfinite(cost)
    got = refit.new_values(state)
    ratio = got[idx] / new[idx]
    near = (ratio > 1 / SPRING_FACTOR) & (ratio < SPRING_FACTOR)
    assert np.count_nonzero(near) >= ratio.size - UNDETERMINED, ratio
    at_truth = refit.with_new(refit.state0, new)
    from bondid.model.parameters import get_parameters

    at_truth.x[: refit.n_nominal] = get_parameters(truth, FEW)
    assert refit.data_cost(state) <= COST_FACTOR * refit.data_cost(at_truth)


def test_modal_starts_match_the_measured_modes_better_than_the_candidates_start(case):
    doc, c, data, _, _ = case
    from bondid.diagnose.modal_id import identify_modes

    refit = _refit(doc, c, data).refit
    starts = ms.modal_starts(refit, c, data, hints_hz=(9.0, 16.0))
    assert starts
    measured = [identify_modes(d) for d in data]
    s0 = refit.state0
    first = ms.matching_cost(refit, refit.with_new(s0, starts[0]), measured, data)
    assert first < ms.matching_cost(refit, s0, measured, data)
    # best matching first, and no two starts alike
    costs = [ms.matching_cost(refit, refit.with_new(s0, v), measured, data) for v in starts]
    assert costs == sorted(costs)
    idx = ms.springs(c)
    for a in range(len(starts)):
        for b in range(a):
            assert np.max(np.abs(np.log(starts[a][idx] / starts[b][idx]))) > 0
    # only the springs move: the damping ratios stay at their start values
    rest = [i for i in range(len(c.parameters)) if i not in idx]
    for v in starts:
        np.testing.assert_allclose(v[rest], [c.parameters[i].initial for i in rest])


def test_the_modal_step_tries_the_other_variants_while_stuck(monkeypatch):
    """The job's own variant first; the other variants (elastic centres) only while the refit
    is still stuck, found from the effect (the job's candidate, the screening's choice, has
    no variants of its own); the variant whose restart was kept becomes the job's candidate,
    and the step stops there."""
    from dataclasses import replace

    from bondid.cost.problem import CostOptions
    from bondid.diagnose import alternatives, runner

    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    c = _mounts(doc)
    assert len(c.variants) >= 2  # the test needs a variant after the one that is kept
    kept_spec = c.variants[0].spec
    tried: list[dict] = []

    class Aug:
        def __init__(self, spec):
            self.spec = spec

    def fake_setup(urdf, job):
        return Aug(job.candidate.spec)

    def fake_restarts(job, aug0, option, aug, state, res, measured):
        assert measured == [["m"]]  # identified once, passed to every variant
        tried.append(option.spec)
        if option.spec == kept_spec:
            return aug0, "s2", "r2", "kept"
        return aug, state, res, "not kept"

    monkeypatch.setattr(runner, "_setup", fake_setup)
    monkeypatch.setattr(ms, "modal_restarts", fake_restarts)
    monkeypatch.setattr(mode_match, "measured_modes", lambda data: [["m"]])
    monkeypatch.setattr(alternatives, "stuck", lambda job, aug, s, r: aug.spec != kept_spec)
    job = runner.Job(doc.to_string(), None, [], [], [], replace(c, variants=()), CostOptions())  # type: ignore[arg-type]
    job2, aug, state, res, note = ms.modal_step(job, Aug(c.spec), "s", "r")
    assert tried == [c.spec, kept_spec]  # the third centre is not tried: no longer stuck
    assert job2.candidate is not None and job2.candidate.spec == kept_spec
    assert not job2.candidate.variants
    assert aug.spec == kept_spec and (state, res) == ("s2", "r2")
    assert note == f"{c.description}: not kept; {c.variants[0].description}: kept"
    # not stuck after the job's own variant: no other is tried
    tried.clear()
    monkeypatch.setattr(alternatives, "stuck", lambda job, aug, s, r: False)
    job3, *_ = ms.modal_step(job, Aug(c.spec), "s", "r")
    assert tried == [c.spec] and job3 is job


def test_the_modal_step_runs_only_where_the_job_allows_it(monkeypatch):
    """A stuck soft-mount refit gets the modal step when ``Job.modal`` (the search sets it for
    the screening's best candidates, ``search.modal_ranked``), and a note saying it was not
    run otherwise; a stuck single-spring refit likewise, never on its other variants."""
    from dataclasses import replace

    from bondid.cost.problem import CostOptions
    from bondid.diagnose import alternatives, runner

    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    c = replace(_mounts(doc), variants=())
    calls: list[str] = []

    def fake_step(job, aug, state, res, others):
        calls.append((job.candidate.label, others))
        return job, aug, state, res, "ran"

    monkeypatch.setattr(runner, "_fit", lambda job: ("aug", "state", "res"))
    monkeypatch.setattr(alternatives, "stuck", lambda job, aug, s, r: True)
    monkeypatch.setattr(
        alternatives, "other_variants", lambda job, aug, s, r, extra: (job, aug, s, r)
    )
    monkeypatch.setattr(ms, "modal_step", fake_step)
    monkeypatch.setattr(runner, "finish", lambda job, aug, s, r, extra, t0, continuation: extra)
    job = runner.Job(doc.to_string(), None, [], [], [], c, CostOptions(), wider=False)  # type: ignore[arg-type]
    assert runner._run(job, 0.0)["modal starts"] == "ran" and calls == [(c.label, True)]
    calls.clear()
    extra = runner._run(replace(job, modal=False), 0.0)
    assert extra["modal starts"] == runner.MODAL_SKIPPED and calls == []
    jc = next(j for j in get_effect("joint_compliance").candidates(doc) if not j.variants)
    calls.clear()
    extra = runner._run(replace(job, candidate=jc), 0.0)
    assert extra["modal starts"] == "ran" and calls == [(jc.label, False)]
    calls.clear()
    extra = runner._run(replace(job, candidate=jc, modal=False), 0.0)
    assert extra["modal starts"] == runner.MODAL_SKIPPED and calls == []


def test_modal_ranked_keeps_the_best_figures_and_profile_picks():
    from types import SimpleNamespace

    from bondid.diagnose.search import MODAL_TOP, modal_ranked

    costs = [3.0, 1.0, float("inf"), 2.0, 5.0, 4.0, 6.0, 7.0]
    picks = [5, 4, 0, 6]
    screenings = [SimpleNamespace(cost=c) for c in costs]
    got = modal_ranked(screenings, picks=picks)  # type: ignore[arg-type]
    by_figure = [1, 3, 0, 5, 4, 6, 7]  # the finite figures, best first
    assert got == {*by_figure[:MODAL_TOP], *picks[:MODAL_TOP]}
    assert 2 not in got and 7 not in got  # no figure; the worst figure, not a pick


#: the withheld compliance of the single-spring case: the interface and its mode [Hz]
JC_LABEL = "joint_compliance@x_stage->y_stage:tz"
JC_HZ = 900.0


@pytest.fixture(scope="module")
def jc_case():
    """Data of the bonder with errors on FEW and a withheld x→y tz compliance (mode near
    JC_HZ); the nominal model, the candidate and the truth's new values."""
    from bondid.diagnose.augmented import with_values
    from bondid.model.parameters import get_parameters

    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    c = next(c for c in get_effect("joint_compliance").candidates(doc) if c.label == JC_LABEL)
    truth = doc.copy()
    for name, v, f in zip(FEW, get_parameters(doc, FEW), ERRORS, strict=True):
        set_parameter(truth, name, float(v) * f)
    g = (JC_HZ / c.ref_hz) ** 2
    new = np.array([q.initial for q in c.parameters]) * np.array([g, np.sqrt(g)])
    data = noisy_bonder_data(get_effect("joint_compliance").augment(truth, with_values(c, new)))
    return doc, c, data, new


def test_placed_starts_put_the_spring_at_the_hints_then_the_worst_matched_modes(jc_case):
    doc, c, data, _ = jc_case
    refit = _refit(doc, c, data).refit
    measured = [list(m) for m in ms.measured_modes(data)]
    v0 = refit.new_values(refit.state0)
    hint = 700.0
    beyond = c.ref_hz * np.sqrt(max(c.scan_grid)) * 2  # a scale outside the scan range
    starts = ms.placed_starts(refit, c, data, (beyond, hint, hint * 1.05), measured)
    assert 1 <= len(starts) <= ms.PLACED_STARTS
    # the hint first (the one beyond the scan range skipped), the damping at its start value
    np.testing.assert_allclose(starts[0], [v0[0] * (hint / c.ref_hz) ** 2, v0[1]])
    placed_hz = [c.ref_hz * np.sqrt(v[0] / v0[0]) for v in starts]
    for a in range(len(placed_hz)):  # no two within SAME_MODE (the second hint was one)
        for b in range(a):
            assert abs(np.log(placed_hz[a] / placed_hz[b])) >= np.log(ms.SAME_MODE) - 1e-12
    # the measured modes after the hint: inside the data's band, worst matched first
    terms = dict((f, t) for t, f in ms.mode_mismatch(refit, refit.state0, measured, data))
    after = [terms[min(terms, key=lambda f: abs(f - h))] for h in placed_hz[1:]]
    assert after == sorted(after, reverse=True)
    assert all(data[0].freq_hz[0] <= h <= data[0].freq_hz[-1] for h in placed_hz)
    # a candidate with several springs gets none
    assert ms.placed_starts(refit, _mounts(doc), data, (hint,), measured) == []


def test_the_alternation_from_a_placed_start_finds_a_single_spring(jc_case):
    """Known answer: no hint given, the first placed start (the measured mode the nominal
    model matches worst) and the restart alternation end with the compliance's stiffness
    within SPRING_FACTOR of the truth's."""
    doc, c, data, new = jc_case
    refit = _refit(doc, c, data).refit
    starts = ms.placed_starts(refit, c, data, (), ms.measured_modes(data))
    assert starts
    state, cost, _ = ms.alternation(refit, starts[0])
    assert np.isfinite(cost)
    ratio = refit.new_values(state)[0] / new[0]
    assert 1 / SPRING_FACTOR < ratio < SPRING_FACTOR, ratio


def test_the_screenings_placed_alternation_finds_a_single_spring(jc_case):
    """The screening's figure (one round from the first placed start): below the objective
    at the candidate's start, at new values whose stiffness is within SPRING_FACTOR of the
    truth's; the job's own identified modes are used when it carries them."""
    from types import SimpleNamespace

    doc, c, data, new = jc_case
    refit = _refit(doc, c, data).refit
    measured = tuple(tuple(m) for m in ms.measured_modes(data))
    job = SimpleNamespace(full=data, hints_hz=(), measured=measured)
    got = ms.placed_alternation(job, refit, c)  # type: ignore[arg-type]
    assert got is not None
    cost, values = got
    assert cost < refit.cost(refit.state0)
    assert 1 / SPRING_FACTOR < values[0] / new[0] < SPRING_FACTOR, values


def test_the_screenings_alternation_of_several_springs_starts_at_the_measured_modes(case):
    """A candidate with several springs (soft mounts) gets the screening's figure too: one
    round of the alternation from its first start matched to the measured modes, below the
    objective at the candidate's own start; without an identified mode, none."""
    from types import SimpleNamespace

    doc, c, data, new, _ = case
    refit = _refit(doc, c, data).refit
    measured = tuple(tuple(m) for m in ms.measured_modes(data))
    job = SimpleNamespace(full=data, hints_hz=(9.0, 16.0), measured=measured)
    got = ms.placed_alternation(job, refit, c)  # type: ignore[arg-type]
    assert got is not None
    cost, values = got
    assert cost < refit.cost(refit.state0)
    assert len(values) == len(new)
    # its springs sit nearer the measured modes than the candidate's start put them
    at = refit.with_new(refit.state0, np.array(values))
    modes = [list(m) for m in measured]
    assert ms.matching_cost(refit, at, modes, data) < ms.matching_cost(
        refit, refit.state0, modes, data
    )
    bare = SimpleNamespace(full=data, hints_hz=(), measured=tuple(() for _ in data))
    assert ms.placed_alternation(bare, refit, c) is None  # type: ignore[arg-type]


def test_placed_starts_fall_back_on_the_models_modes(jc_case):
    """No mode identified and none missing: the starts put the candidate's mode at the
    model's own in-band modes, lowest first (inside the scan range)."""
    doc, c, data, _ = jc_case
    refit = _refit(doc, c, data).refit
    starts = ms.placed_starts(refit, c, data, (), [[] for _ in data])
    assert 1 <= len(starts) <= ms.PLACED_STARTS
    v0 = refit.new_values(refit.state0)
    placed_hz = [c.ref_hz * np.sqrt(v[0] / v0[0]) for v in starts]
    assert placed_hz == sorted(placed_hz)
    lo, hi = c.ref_hz * np.sqrt(min(c.scan_grid)), c.ref_hz * np.sqrt(max(c.scan_grid))
    model_hz = [f for f in ms.model_modes_hz(refit, data) if lo <= f <= hi]
    np.testing.assert_allclose(placed_hz[0], model_hz[0])
