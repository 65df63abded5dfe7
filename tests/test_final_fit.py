"""Tests of bondid.diagnose.final_fit: the final model refitted on all data."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bondid.data.noise import add_measurement_noise
from bondid.model import UrdfDocument, get_parameter, set_parameter
from bondid.simulate import log_grid, simulate

MODEL = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03})
FREE = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
#: the withheld compliance: each parameter at its initial value times this to its ``scan``
#: exponent (stiffness × 5, damping × √5)
TRUE_SCALE = 5.0
#: the final fit's stiffness within this relative error of the truth, and its weighted gap on
#: all data at most this relative amount above the training refit's
STIFFNESS_TOL = 0.15
GAP_RTOL = 1e-3


@pytest.fixture(scope="module")
def case():  # type: ignore[no-untyped-def]
    return _case()


def _case():  # type: ignore[no-untyped-def]
    """The job of the true candidate (from its initial values) on data of the bonder with a
    withheld joint compliance, and the withheld stiffness [N/m]."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.job import Job
    from bondid.diagnose.pipeline import Settings, prepare_data

    doc = UrdfDocument.load(MODEL)
    e = get_effect("joint_compliance")
    cand = next(c for c in e.candidates(doc) if c.location == "y_stage->z_stage:tz")
    truth = e.augment(doc, cand)
    for p in cand.parameters:
        for m, fac in p.members:
            set_parameter(truth, m, fac * p.initial * TRUE_SCALE**p.scan)
    k = next(i for i, p in enumerate(cand.parameters) if p.strength)
    k_true = cand.parameters[k].initial * TRUE_SCALE ** cand.parameters[k].scan
    f = log_grid(1.0, 4000.0, 150)
    data = []
    for k, op in enumerate(OPS):
        d = simulate(truth, op, f)
        d.H, d.coherence = add_measurement_noise(d.H, f, rel=0.005, floor_db=-70, rng=k,
                                                 floor_ref="response")  # fmt: skip
        data.append(d)
    s = Settings(n_points=150, workers=1, effects=["joint_compliance"], free=FREE, modes=False)
    prep = prepare_data(doc, data, s)
    job = Job(doc.to_string(), prep.space, prep.train, prep.held, prep.full, cand, prep.options,
              start_new=tuple(p.initial for p in cand.parameters), wider=False,
              modal=False)  # fmt: skip
    return job, k_true


def test_final_fit_recovers_a_displaced_model(case):  # type: ignore[no-untyped-def]
    """Known answer: the true candidate's refit, displaced (masses +20 %, its stiffness
    halved), refitted on all data: back at the known stiffness, its weighted gap on all data
    no worse than the training refit's; label, effect and chain stay the source's."""
    from bondid.diagnose.augmented import with_values
    from bondid.diagnose.final_fit import final_fit
    from bondid.diagnose.runner import run_job

    job, k_true = case
    ref = run_job(replace(job, all_iter=200, new_iter=10))  # the training refit
    assert not ref.error, ref.error
    (cand,) = ref.chain  # the refitted variant; its stiffness is values[at]
    at = _strength_index(cand)
    assert abs(ref.values[at] / k_true - 1.0) < STIFFNESS_TOL
    doc = UrdfDocument.from_string(ref.urdf, source="refit")
    for name in FREE[:3]:
        set_parameter(doc, name, 1.2 * get_parameter(doc, name))
    new = np.array([p.initial for p in cand.parameters])
    new[len(new) + at] *= 0.5
    source = replace(ref, urdf=doc.to_string(), chain=(with_values(cand, new),), db_rms=np.inf)
    out = final_fit(source, job, max_iter=200)
    assert out.kept and out.note.endswith("kept"), out.note
    m = out.model
    assert (m.label, m.effect, m.location) == (ref.label, ref.effect, ref.location)
    assert m.names == ref.names and len(m.chain) == 1 and m.extra["final fit"] == out.note
    assert m.db_rms <= ref.db_rms * (1.0 + GAP_RTOL), (m.db_rms, ref.db_rms)
    k = float(m.values[at])
    assert abs(k / k_true - 1.0) < STIFFNESS_TOL, (k, k_true)
    # the chain and the model text carry the fitted stiffness
    (par,) = [p for p in m.chain[0].parameters if p.strength]
    assert par.initial == pytest.approx(k, rel=1e-9)
    member, fac = par.members[0]
    fitted = UrdfDocument.from_string(m.urdf, source="final fit")
    assert get_parameter(fitted, member) == pytest.approx(fac * k, rel=1e-6)


def _strength_index(cand) -> int:  # type: ignore[no-untyped-def]
    """Index (negative, from the end of a refit's values) of ``cand``'s strength parameter."""
    (k,) = [i for i, p in enumerate(cand.parameters) if p.strength]
    return k - len(cand.parameters)


def _result(job, **kw):  # type: ignore[no-untyped-def]
    from bondid.diagnose.job import JobResult

    base = dict(
        label="c", effect="joint_compliance", location="a->b:tz", names=["m", "k"],
        values=np.array([1.0, 2.0]), std=np.array([0.1, 0.2]), n_new=1, train_rms=1.0,
        heldout_rms=1.0, n_train=100, heldout_db_rms=1.0, db_rms=1.0, full_H=[], urdf="<robot/>",
        wall_s=1.0, objective=1.0,
    )  # fmt: skip
    base.update(kw)
    return JobResult(**base)


def test_final_fit_kept_only_when_it_lowers_the_gap(case):  # type: ignore[no-untyped-def]
    """Kept when the weighted gap on all data is lower; a failed or differently
    parameterised fit is not kept, with the reason in the note."""
    from bondid.diagnose.final_fit import judged

    job, _k = case
    source = _result(job)
    better = _result(job, label="refit", effect=None, location=None, values=np.array([1.5, 3.0]),
                     db_rms=0.8)  # fmt: skip
    out = judged(source, job, better)
    assert out.kept and out.model.label == "c" and out.model.effect == "joint_compliance"
    assert out.model.db_rms == 0.8 and np.allclose(out.model.values, [1.5, 3.0])
    assert out.source is source and "1.000 -> 0.800 dB, kept" in out.note
    worse = judged(source, job, replace(better, db_rms=1.2))
    assert not worse.kept and worse.model is source and worse.note.endswith("not kept")
    failed = judged(source, job, replace(better, error="SolverError: boom"))
    assert not failed.kept and "boom" in failed.note
    other = judged(source, job, replace(better, names=["m", "k", "d"]))
    assert not other.kept and other.model is source
    # the rescue's note is kept either way: in the model's notes only when the fit is kept
    told = replace(better, extra={"rescue": "staged schedule to 0.70x, kept"})
    assert judged(source, job, told).rescue == "staged schedule to 0.70x, kept"
    assert judged(source, job, told).model.extra["final fit rescue"] == told.extra["rescue"]
    refused = judged(source, job, replace(told, db_rms=1.2))
    assert refused.rescue == told.extra["rescue"] and "final fit rescue" not in refused.model.extra
    assert judged(source, job, better).rescue == ""


def test_the_final_fit_solves_as_a_warm_start(case):  # type: ignore[no-untyped-def]
    """The final job's refit hands IPOPT the warm-start options over the prior's; a job of
    the search keeps IPOPT's default barrier."""
    from bondid.diagnose.final_fit import final_job
    from bondid.diagnose.runner import _setup
    from bondid.fit.prior import PRIOR_IPOPT
    from bondid.optim.ipopt import WARM_START

    job, _k = case
    source = _result(job, urdf=job.urdf, chain=(job.candidate,))
    warm = _setup(job.urdf, final_job(source, job, 300)).refit._ipopt_options() or {}
    assert {**PRIOR_IPOPT, **WARM_START}.items() <= warm.items()
    search = _setup(job.urdf, job).refit._ipopt_options() or {}
    assert "mu_init" not in search


def test_the_final_fit_runs_every_fallback_when_the_heldout_score_is_above_its_noise(case):  # type: ignore[no-untyped-def]
    """The final job runs every fallback of the rescue when the source's held-out score is
    above RESCUE_RATIO times the held-out noise level, not when it is below or without a
    level."""
    from bondid.diagnose.final_fit import final_job
    from bondid.diagnose.rescue import RESCUE_RATIO

    job, _k = case
    source = _result(job, heldout_rms=1.0)
    above = replace(source, heldout_rms=1.01 * RESCUE_RATIO)
    below = replace(source, heldout_rms=0.99 * RESCUE_RATIO)
    at_level = replace(job, heldout_noise_db=1.0)
    assert final_job(above, at_level, 300).fallbacks_always
    assert not final_job(below, at_level, 300).fallbacks_always
    assert not final_job(above, replace(job, heldout_noise_db=float("nan")), 300).fallbacks_always
    assert not job.fallbacks_always  # a search job: the rescue's own ratio test


#: the nominal restart's nominal stiffness within this relative error of the truth's
RESTART_TOL = 0.05


def test_nominal_restart_brings_a_displaced_nominal_spring_back(case):  # type: ignore[no-untyped-def]
    """Known answer (bondid.diagnose.final_restart): the true candidate's refit with a nominal
    spring moved to a fifth (its mode far from the measured one) and the effect's parameters
    right, as a search step can leave it; restarted from the nominal model's values (the
    parameter refit's stand-in: the truth's nominal parameters) with the effect held, the
    spring is back at the truth's and the objective lower: kept. It does not run without the
    trigger, the parameter refit's text or an accepted effect."""
    from bondid.diagnose.final_fit import final_job
    from bondid.diagnose.final_restart import nominal_restart
    from bondid.diagnose.runner import _setup, run_job

    job, _k = case
    ref = run_job(replace(job, all_iter=200, new_iter=10))
    doc = UrdfDocument.from_string(ref.urdf, source="refit")
    spring = "x_guide_ry.stiffness"
    k_true = get_parameter(UrdfDocument.from_string(job.urdf), spring)
    at = list(ref.names).index(spring)
    low = float(job.nominal.lower[list(job.nominal.names).index(spring)])
    set_parameter(doc, spring, low)  # at its lower bound, its mode far from the data's
    final = final_job(replace(ref, urdf=doc.to_string()), replace(job, restart_urdf=job.urdf), 300)
    refit = _setup(final.urdf, final).refit
    stuck = replace(ref, urdf=final.urdf, objective=refit.cost(refit.state0))  # a fit ended here
    out, note = nominal_restart(replace(final, fallbacks_always=True), stuck)
    assert note.startswith("nominal restart from the parameter refit") and note.endswith("kept")
    assert out.objective < stuck.objective and not out.error
    assert abs(out.values[at] / k_true - 1.0) < RESTART_TOL, (out.values[at], k_true)
    assert len(out.chain) == 1 and out.chain[0].label == ref.chain[0].label
    for j in (replace(final, fallbacks_always=False), replace(final, restart_urdf=None)):
        assert nominal_restart(j, stuck) == (stuck, "")
    assert nominal_restart(replace(final, fallbacks_always=True), replace(stuck, chain=())) == (
        replace(stuck, chain=()), "")  # fmt: skip
