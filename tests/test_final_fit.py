"""Tests of bondid.diagnose.final_fit: the final model refitted on all data through the one
loop (warm start, then the nominal origin), kept only when its weighted gap is lower."""

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
    """The task of the true candidate on data of the bonder with a withheld joint
    compliance, the withheld stiffness [N/m] and the parameter refit."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.job import Task
    from bondid.diagnose.pipeline import Settings, prepare_data
    from bondid.diagnose.refit_job import run_refit

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
    base = Task(doc.to_string(), prep.space, prep.train, prep.held, prep.full, prep.options)
    refit = run_refit(base)
    return base, cand, k_true, refit


class _Now:
    """A pool that runs each task at once."""

    def submit(self, fn, *args):  # type: ignore[no-untyped-def]
        from concurrent.futures import Future

        fut: Future = Future()
        fut.set_result(fn(*args))
        return fut


def test_final_fit_recovers_a_displaced_model(case):  # type: ignore[no-untyped-def]
    """Known answer: the true candidate's refit, displaced (masses +20 %, its stiffness
    halved), refitted on all data: back at the known stiffness, its weighted gap on all data
    no worse than the training refit's; label, effect and chain stay the source's."""
    from bondid.diagnose.augmented import with_values
    from bondid.diagnose.final_fit import start_final
    from bondid.diagnose.refit_job import run_refit

    base, cand0, k_true, refit = case
    ref = run_refit(replace(base, urdf=refit.urdf, candidate=cand0))  # the training refit
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
    out = start_final(source, base, refit, _Now())()
    assert out.kept and out.note.endswith("kept"), out.note
    m = out.model
    assert (m.label, m.effect, m.location) == (ref.label, ref.effect, ref.location)
    assert m.names == ref.names and len(m.chain) == 1
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


def _result(**kw):  # type: ignore[no-untyped-def]
    from bondid.diagnose.job import JobResult

    base = dict(
        label="c", effect="joint_compliance", location="a->b:tz", names=["m", "k"],
        values=np.array([1.0, 2.0]), std=np.array([0.1, 0.2]), n_new=1, train_rms=1.0,
        heldout_rms=1.0, n_train=100, heldout_db_rms=1.0, db_rms=1.0, full_H=[], urdf="<robot/>",
        wall_s=1.0, objective=1.0,
    )  # fmt: skip
    base.update(kw)
    return JobResult(**base)


def test_final_fit_kept_only_when_it_lowers_the_gap():
    """Kept when the weighted gap on all data is lower; a failed or differently
    parameterised fit is not kept, with the reason in the note."""
    from bondid.diagnose.final_fit import judged

    source = _result()
    better = _result(label="refit", effect=None, location=None, values=np.array([1.5, 3.0]),
                     db_rms=0.8)  # fmt: skip
    out = judged(source, better)
    assert out.kept and out.model.label == "c" and out.model.effect == "joint_compliance"
    assert out.model.db_rms == 0.8 and np.allclose(out.model.values, [1.5, 3.0])
    assert out.source is source and "1.000 -> 0.800 dB, kept" in out.note
    worse = judged(source, replace(better, db_rms=1.2))
    assert not worse.kept and worse.model is source and worse.note.endswith("not kept")
    failed = judged(source, replace(better, error="SolverError: boom"))
    assert not failed.kept and "boom" in failed.note
    other = judged(source, replace(better, names=["m", "k", "d"]))
    assert not other.kept and other.model is source


def test_the_final_task_is_a_warm_refit_on_all_data(case):  # type: ignore[no-untyped-def]
    """The final task fits all data (no held-out points), warm (IPOPT's warm-start options
    over the prior's), with the parameter refit's nominal values as its second start; a
    search task keeps IPOPT's default barrier."""
    from bondid.diagnose.final_fit import final_task
    from bondid.diagnose.refit_job import Models
    from bondid.optim.ipopt import WARM_START
    from bondid.optim.prior import PRIOR_IPOPT

    base, cand, _k, refit = case
    source = replace(refit, label="with an effect")
    task = final_task(source, base, refit)
    assert task.train == base.full and task.heldout == [] and task.warm and task.fallbacks
    n = len(base.nominal.names)
    np.testing.assert_array_equal(task.places.nominal, refit.values[:n])
    assert final_task(refit, base, refit).places.nominal is None  # the refit itself: no restart
    warm = Models(task)[0].refit.ipopt_options() or {}
    assert {**PRIOR_IPOPT, **WARM_START}.items() <= warm.items()
    search = Models(replace(base, candidate=cand))[0].refit.ipopt_options() or {}
    assert "mu_init" not in search


#: the nominal restart's nominal stiffness within this relative error of the truth's
RESTART_TOL = 0.05


def test_the_nominal_origin_brings_a_displaced_nominal_spring_back(case):  # type: ignore[no-untyped-def]
    """Known answer: the true candidate's refit with a nominal spring moved to its lower
    bound (its mode far from the measured one) and the effect's parameters right, as a search
    step can leave it; the final fit's loop, whose second start puts the nominal parameters
    back at the parameter refit's values with the effect held, brings the spring back to the
    truth's."""
    from bondid.diagnose.final_fit import start_final
    from bondid.diagnose.refit_job import run_refit

    base, cand, _k, refit = case
    ref = run_refit(replace(base, urdf=refit.urdf, candidate=cand))
    doc = UrdfDocument.from_string(ref.urdf, source="refit")
    spring = "x_guide_ry.stiffness"
    k_true = get_parameter(UrdfDocument.from_string(base.urdf), spring)
    at = list(ref.names).index(spring)
    low = float(base.nominal.lower[list(base.nominal.names).index(spring)])
    set_parameter(doc, spring, low)  # at its lower bound, its mode far from the data's
    stuck = replace(ref, urdf=doc.to_string(), db_rms=np.inf)
    out = start_final(stuck, base, refit, _Now())()
    assert out.kept and not out.model.error
    assert abs(out.model.values[at] / k_true - 1.0) < RESTART_TOL, (out.model.values[at], k_true)
    assert len(out.model.chain) == 1 and out.model.chain[0].label == ref.chain[0].label
