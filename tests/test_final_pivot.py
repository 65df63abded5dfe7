"""Tests of bondid.model.move_pivot and bondid.diagnose.final_pivot: the pivot of an accepted
rotational compliance searched again on all data."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bondid.exceptions import ModelError
from bondid.model import UrdfDocument, insert_parasitic_joint, move_pivot
from bondid.simulate import log_grid, simulate

MODEL = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"
LOCATION = "base->x_stage:rx"
#: the withheld pivot: the candidate's bearing centre moved this far across the axis [m]
OFFSET = np.array([0.0, 0.02, 0.03])
FREE = ["x_stage.mass", "y_stage.mass", "z_stage.mass"]
#: the pivot found within this distance of the withheld one [m]
PIVOT_TOL = 0.006


def _mass_and_stiffness(doc: UrdfDocument) -> tuple[np.ndarray, np.ndarray]:
    from bondid.linear.affine import build_affine_model

    am = build_affine_model(doc)
    return am.mass_matrix(), am.stiffness_matrix()


@pytest.mark.parametrize("first", [(0.0, 0.0, 0.0), (0.0, -0.01, 0.02)])
def test_a_moved_pivot_is_the_pivot_inserted_there(first):  # type: ignore[no-untyped-def]
    """Known answer: a compliance inserted about ``first`` and moved to another pivot has the
    mass and stiffness matrices of the one inserted about that pivot directly."""
    doc = UrdfDocument.load(MODEL)
    after = doc.joint_names[0]
    target = (0.0, 0.03, -0.02)
    a, b = doc.copy(), doc.copy()
    kw = {"after": after, "kind": "revolute", "axis": (1.0, 0.0, 0.0), "stiffness": 4e4}
    insert_parasitic_joint(a, "c_rx", pivot=first, **kw)
    move_pivot(a, "c_rx", target)
    insert_parasitic_joint(b, "c_rx", pivot=target, **kw)
    (Ma, Ka), (Mb, Kb) = _mass_and_stiffness(a), _mass_and_stiffness(b)
    np.testing.assert_allclose(Ma, Mb, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Ka, Kb, rtol=1e-12, atol=1e-9)


def test_moving_the_pivot_of_an_unknown_joint_names_it():
    doc = UrdfDocument.load(MODEL)
    with pytest.raises(ModelError, match="no_such_joint"):
        move_pivot(doc, "no_such_joint", (0.0, 0.0, 0.0))
    with pytest.raises(ModelError, match="finite 3-vector"):
        move_pivot(doc, doc.joint_names[0], (0.0, np.nan, 0.0))


@pytest.fixture(scope="module")
def data():  # type: ignore[no-untyped-def]
    """The diagnosis's data of the bonder with a rotational compliance about a pivot off the
    candidate's bearing centre; the candidate (at the centre) and the withheld pivot."""
    from bondid.data.noise import add_measurement_noise
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.pipeline import Settings, prepare_data
    from bondid.diagnose.pivot import with_pivot

    doc = UrdfDocument.load(MODEL)
    e = get_effect("joint_compliance")
    cand = replace(next(c for c in e.candidates(doc) if c.location == LOCATION), variants=())
    true_pivot = np.asarray(cand.spec["pivot"], float) + OFFSET
    truth = e.augment(doc, with_pivot(cand, true_pivot))
    f = log_grid(1.0, 4000.0, 150)
    sets = []
    for k, op in enumerate(({}, {"x": 0.05, "y": -0.03})):
        d = simulate(truth, op, f)
        d.H, d.coherence = add_measurement_noise(d.H, f, rel=0.005, floor_db=-70, rng=k,
                                                 floor_ref="response")  # fmt: skip
        sets.append(d)
    s = Settings(n_points=150, workers=1, effects=["joint_compliance"], free=FREE, modes=False)
    return doc, prepare_data(doc, sets, s), cand, true_pivot


@pytest.fixture(scope="module")
def case(data):  # type: ignore[no-untyped-def]
    """A final job on :func:`data`, its model holding the compliance at the bearing centre
    (its start values); and the withheld pivot."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.job import Job

    doc, prep, cand, true_pivot = data
    model = get_effect(cand.effect).augment(doc, cand).to_string()
    job = Job(model, prep.space, list(prep.full), prep.held, prep.full, None, prep.options,
              accepted=(cand,), all_iter=100, wider=False, modal=False,
              fallbacks_always=True)  # fmt: skip
    return job, true_pivot


def test_the_search_judges_pivots_with_every_parameter(data):  # type: ignore[no-untyped-def]
    """Known answer: a candidate refitted at the bearing centre, its pivot refined warm with
    every parameter free (``full``): within :data:`PIVOT_TOL` of the withheld pivot, at a
    lower training objective; the note says how the pivots were judged."""
    from bondid.diagnose.alternatives import at_refined_pivot
    from bondid.diagnose.job import Job
    from bondid.diagnose.runner import _fit

    doc, prep, cand, true_pivot = data
    job = Job(doc.to_string(), prep.space, prep.train, prep.held, prep.full, cand, prep.options,
              start_new=tuple(p.initial for p in cand.parameters), all_iter=60, wider=False,
              modal=False)  # fmt: skip
    aug, state, res = _fit(job)
    moved, aug2, state2, _, note = at_refined_pivot(job, aug, state, res, warm=True, full=True)
    assert moved.candidate is not None
    found = np.asarray(moved.candidate.spec["pivot"], float)
    assert np.linalg.norm(found - true_pivot) < PIVOT_TOL, (found, true_pivot, note)
    assert aug2.refit.cost(state2) < aug.refit.cost(state)
    assert "all parameters figure" in note and "kept" in note


def test_the_final_fit_finds_the_withheld_pivot(case):  # type: ignore[no-untyped-def]
    """Known answer: from the bearing centre, the pivot search on all data ends within
    :data:`PIVOT_TOL` of the withheld pivot, at a lower objective, and says so."""
    from bondid.diagnose.final_pivot import refined_pivots, rotational
    from bondid.diagnose.runner import run_job

    job, true_pivot = case
    result = run_job(job)
    assert not result.error, result.error
    (k,) = rotational(result.chain)
    start = np.asarray(result.chain[k].spec["pivot"], float)
    assert np.linalg.norm(start - true_pivot) > 2 * PIVOT_TOL  # the search has work to do
    out, note = refined_pivots(job, result)
    found = np.asarray(out.chain[k].spec["pivot"], float)
    assert np.linalg.norm(found - true_pivot) < PIVOT_TOL, (found, true_pivot, note)
    assert out.objective < result.objective
    assert "pivots tried" in note and "kept" in note, note
    print(note)


def test_the_moved_spring_keeps_its_frequency(case):  # type: ignore[no-untyped-def]
    """``moved`` scales the spring and damper by the effective inertias' ratio: the spring
    alone resonates at the same frequency about either pivot."""
    from bondid.diagnose.effects.topology import effective_inertia
    from bondid.diagnose.final_pivot import moved, rotational
    from bondid.diagnose.runner import run_job

    job, _ = case
    result = run_job(replace(job, fallbacks_always=False))
    (k,) = rotational(result.chain)
    joint = str(result.chain[k].spec["joint"])
    new_pivot = np.asarray(result.chain[k].spec["pivot"], float) + np.array([0.0, -0.03, 0.01])
    urdf, chain = moved(result.urdf, result.chain, k, new_pivot)
    assert chain[k].spec["pivot"] == pytest.approx(new_pivot.tolist())

    def w2(text: str, c) -> float:  # type: ignore[no-untyped-def]
        d = UrdfDocument.from_string(text)
        return c.parameters[0].initial / effective_inertia(d, joint)

    assert w2(urdf, chain[k]) == pytest.approx(w2(result.urdf, result.chain[k]), rel=1e-9)


def test_without_a_rotational_compliance_the_search_does_nothing(case):  # type: ignore[no-untyped-def]
    from bondid.diagnose.final_pivot import refined_pivots
    from bondid.diagnose.runner import run_job

    job, _ = case
    result = run_job(replace(job, fallbacks_always=False))
    bare = replace(result, chain=())
    assert refined_pivots(job, bare) == (bare, "")


def test_a_pivot_that_cannot_be_judged_is_skipped_and_said(case):  # type: ignore[no-untyped-def]
    """A compliance whose joint is not in the model: every pivot fails to build, the result
    stays the final fit's own, and the note names the failure."""
    from bondid.diagnose.final_pivot import refined_pivots, rotational
    from bondid.diagnose.runner import run_job

    job, _ = case
    result = run_job(replace(job, fallbacks_always=False))
    (k,) = rotational(result.chain)
    spec = {**result.chain[k].spec, "joint": "no_such_joint"}
    broken = replace(result, chain=(replace(result.chain[k], spec=spec),))
    out, note = refined_pivots(job, broken)
    assert out is broken
    assert "failed, first: ModelError" in note and "no_such_joint" in note
    assert note.endswith("the pivots kept")
