"""The backward elimination of accepted effects (:mod:`bondid.diagnose.prune`): an effect
accepted before the true one and redundant once it is in is dropped, the true one kept with
the figures of a refit without the other; the report lists it under ``dropped`` only."""

from __future__ import annotations

from concurrent.futures import Future
from types import SimpleNamespace

import pytest
from test_diagnose import FEW, _data, _settings, _with_values, doc  # noqa: F401

TRUE_AT = "y_stage->z_stage:tz"
WRONG_AT = "y_stage->z_stage:ty"


class SyncPool:
    """Runs each submitted call at once (the elimination's refits are under test, not the
    worker processes)."""

    def __init__(self) -> None:
        self.calls = 0

    def submit(self, fn, *args):  # type: ignore[no-untyped-def]
        self.calls += 1
        fut: Future = Future()
        fut.set_result(fn(*args))
        return fut


@pytest.fixture(scope="module")
def wrong_then_true(doc):  # type: ignore[no-untyped-def]  # noqa: F811
    """Data with a joint compliance at TRUE_AT; a search's steps as if it had accepted a
    compliance at WRONG_AT (same joint, other DOF) first and the true one second."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.job import Task
    from bondid.diagnose.pipeline import prepare_data
    from bondid.diagnose.refit_job import run_refit
    from bondid.diagnose.scoring import score, tests
    from bondid.diagnose.search import Context, Step

    e = get_effect("joint_compliance")
    cands = {c.location: c for c in e.candidates(doc)}
    data = _data(_with_values(e, doc, cands[TRUE_AT], scale=3.0))
    p = prepare_data(doc, data, _settings(effects=["joint_compliance"], free=FEW))
    ctx = Context(doc, p.names, p.train, p.held, p.full, p.options, p.candidates,
                  space=p.space, noise=p.noise)  # fmt: skip
    base = run_refit(Task(doc.to_string(), p.space, p.train, p.held, p.full, p.options))
    s0 = score(base.heldout_rms, base.n_train, 0)
    wrong = run_refit(ctx.task(base, cands[WRONG_AT]))
    both = run_refit(ctx.task(wrong, cands[TRUE_AT]))
    sw = score(wrong.heldout_rms, wrong.n_train, wrong.n_new)
    sb = score(both.heldout_rms, both.n_train, both.n_new)
    steps = [
        Step(0, base, s0, [], [], results=[wrong], scores=[sw], winner=wrong,
             test=tests(sw, s0, 2, ctx.noise)),
        Step(1, wrong, sw, [], [], results=[both], scores=[sb], winner=both,
             test=tests(sb, sw, 2, ctx.noise)),
    ]  # fmt: skip
    return ctx, base, steps


@pytest.mark.slow
def test_an_effect_redundant_once_the_true_one_is_in_is_dropped(wrong_then_true):  # type: ignore[no-untyped-def]
    from bondid.diagnose.prune import prune

    ctx, base, steps = wrong_then_true
    assert [c.location for c in steps[-1].winner.chain] == [WRONG_AT, TRUE_AT]
    pool = SyncPool()
    out = prune(ctx, pool, steps, base)
    assert [d.candidate.location for d in out.dropped] == [WRONG_AT]
    d = out.dropped[0]
    assert d.step == 0 and d.round == 1 and not d.test["accepted"]
    # the true compliance alone, refitted without the other: its own model, not a step's
    assert [k.model.chain[0].location for k in out.kept] == [TRUE_AT]
    k = out.kept[0]
    assert not k.forward and k.step == 1 and k.model is not steps[1].winner
    assert [c.location for c in k.model.chain] == [TRUE_AT]
    assert k.score_before == steps[0].base_score and k.test["accepted"]
    # the refit without the wrong effect is as good as the model with both (within the
    # rule's own tolerance: the wrong one does not earn its parameters)
    assert k.score <= 1.05 * steps[1].scores[0]
    assert out.final is k.model
    # both models without one effect are refitted; the one without the true effect is step
    # 1's model again, refitted from the values beside the true one (the better one kept)
    assert out.n_refits == pool.calls == 2


def test_the_report_lists_the_dropped_effect_apart(wrong_then_true):  # type: ignore[no-untyped-def]
    from bondid.diagnose.prune import prune
    from bondid.diagnose.verdict import dropped_entries, effect_entries, verdict_entry

    ctx, base, steps = wrong_then_true
    pr = prune(ctx, SyncPool(), steps, base)
    every = [f"{o}.{i}" for d in ctx.full for o in d.outputs for i in d.inputs]
    diag = SimpleNamespace(pruning=pr, steps=steps, scores=steps[0].scores,
                           baseline_score=steps[0].base_score, datasets=ctx.full,
                           channels=every, channels_by_file=None)  # fmt: skip
    effects = effect_entries(diag, 1.0)  # type: ignore[arg-type]
    assert [(x["effect"], x["location"]) for x in effects] == [("joint_compliance", TRUE_AT)]
    assert effects[0]["refitted_without_dropped"] and effects[0]["step"] == 2
    assert effects[0]["caveats"] == []  # a structure inside its range, on given channels
    assert effects[0]["db_rms_after"] == pr.kept[0].model.db_rms
    stiff = [n for n in effects[0]["parameters"] if "stiffness" in n]
    assert stiff and all(effects[0]["parameters"][n]["value"] > 0 for n in stiff)
    dropped = dropped_entries(diag)  # type: ignore[arg-type]
    assert [(x["location"], x["round"]) for x in dropped] == [(WRONG_AT, 1)]
    assert "refit without it" in dropped[0]["reason"]
    from bondid.diagnose.summary import dropped_lines

    (line,) = dropped_lines(dropped)
    assert f"joint_compliance@{WRONG_AT}" in line and "step 1" in line
    v = verdict_entry(diag, 1.0, 2.0, None)  # type: ignore[arg-type]
    assert (v["effect"], v["location"]) == ("joint_compliance", TRUE_AT)
    assert "backward elimination" in v["reason"]


class FailingPool(SyncPool):
    """Every refit fails as a worker's numerical failure does (``error`` set)."""

    def submit(self, fn, *args):  # type: ignore[no-untyped-def]
        from dataclasses import replace

        fut = super().submit(fn, *args)
        return _done(replace(fut.result(), error="ComputationError: injected", heldout_rms=1e9))


def _done(value):  # type: ignore[no-untyped-def]
    fut: Future = Future()
    fut.set_result(value)
    return fut


def test_a_failed_refit_without_an_effect_drops_nothing(wrong_then_true):  # type: ignore[no-untyped-def]
    """The refit without the wrong effect fails: no score, so no evidence against it; the
    search's accepted effects stand, in its order, with its own figures."""
    from bondid.diagnose.prune import prune

    ctx, base, steps = wrong_then_true
    pool = FailingPool()
    out = prune(ctx, pool, steps, base)
    assert pool.calls == 2 and out.dropped == []
    assert [k.model for k in out.kept] == [steps[0].winner, steps[1].winner]
    assert all(k.forward for k in out.kept) and out.note == ""


def test_a_single_effect_is_kept_without_a_refit(wrong_then_true):  # type: ignore[no-untyped-def]
    from bondid.diagnose.prune import prune

    ctx, base, steps = wrong_then_true
    pool = SyncPool()
    out = prune(ctx, pool, steps[:1], base)
    assert pool.calls == 0 and out.dropped == [] and out.n_refits == 0
    assert len(out.kept) == 1 and out.kept[0].forward and out.kept[0].model is steps[0].winner
    assert out.kept[0].test == steps[0].test
    assert prune(ctx, pool, [], base).kept == [] and pool.calls == 0


@pytest.mark.slow
def test_a_diagnosis_with_a_dropped_effect_writes_the_kept_one(doc, tmp_path, monkeypatch):  # type: ignore[no-untyped-def]  # noqa: F811
    """End to end through :func:`bondid.diagnose.diagnose` and its outputs, with the search
    replaced by one that accepts the wrong compliance first and the true one second (as the
    fixture's steps): the verdict, ``effects``, ``dropped``, the summary, ``augmented.urdf``
    (the true effect alone) and the final fit all follow the elimination."""
    from bondid.diagnose import diagnose, pipeline, write_outputs
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.refit_job import run_refit
    from bondid.diagnose.report import gaps, to_json_dict
    from bondid.diagnose.scoring import score, tests
    from bondid.diagnose.search import Step
    from bondid.diagnose.summary import summary
    from bondid.model import UrdfDocument

    e = get_effect("joint_compliance")
    cands = {c.location: c for c in e.candidates(doc)}
    data = _data(_with_values(e, doc, cands[TRUE_AT], scale=3.0))

    def two_steps(ctx, pool, baseline, say):  # type: ignore[no-untyped-def]
        s0 = score(baseline.heldout_rms, baseline.n_train, 0)
        wrong = run_refit(ctx.task(baseline, cands[WRONG_AT]))
        both = run_refit(ctx.task(wrong, cands[TRUE_AT]))
        sw = score(wrong.heldout_rms, wrong.n_train, wrong.n_new)
        sb = score(both.heldout_rms, both.n_train, both.n_new)
        return [
            Step(0, baseline, s0, [], [], results=[wrong], scores=[sw], winner=wrong,
                 test=tests(sw, s0, 2, ctx.noise)),
            Step(1, wrong, sw, [], [], results=[both], scores=[sb], winner=both,
                 test=tests(sb, sw, 2, ctx.noise)),
        ]  # fmt: skip

    monkeypatch.setattr(pipeline, "search", two_steps)
    s = _settings(effects=["joint_compliance"], free=FEW)
    diag = diagnose(doc, data, s)
    content = to_json_dict(diag, gaps(diag))
    assert (content["verdict"]["effect"], content["verdict"]["location"]) == (
        "joint_compliance", TRUE_AT)  # fmt: skip
    assert [x["location"] for x in content["effects"]] == [TRUE_AT]
    assert [x["location"] for x in content["dropped"]] == [WRONG_AT]
    # a translational compliance: nothing to say beyond its parameters (no pivot)
    assert content["final_fit"]["effects"] == [
        {"effect": "joint_compliance", "location": TRUE_AT, "detail": None}
    ]
    assert content["scoring"]["elimination_note"] == ""
    assert f"dropped: joint_compliance@{WRONG_AT}" in summary(diag, content)
    written = write_outputs(diag, tmp_path, plots=True)
    aug = UrdfDocument.load(tmp_path / "augmented.urdf")
    aug.build_pinocchio_model()
    joints = {j.name for j in aug.robot.joints}
    assert (tmp_path / "augmented_all.urdf") not in written  # one effect kept
    assert (tmp_path / "final.urdf") in written and (tmp_path / "bode_1.png") in written
    # the kept model has the true DOF only: one joint more than the nominal model
    assert len(joints) == len({j.name for j in doc.robot.joints}) + 1
