"""Known answers for the structural candidates' families and their refits (soft mounts about
an elastic centre off the CoM; the rescue's fallbacks)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from models import noisy_bonder_data

from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
#: unequal mount stiffnesses (factors on the start's, per x y z rx ry rz) and damping ratios
MOUNTS = (0.5, 0.8, 1.4, 2.0, 0.7, 1.2, *(0.6,) * 3, *(1.5,) * 3)  # 6 springs, 6 damping ratios
#: geometry computed two ways (the variants' centres on the hull face, the same start
#: stiffness): equal up to rounding [m] / relative
ROUNDING_ABS_M = 1e-12
ROUNDING_REL = 1e-12
#: the one-problem scan's costs vs each state's own cost (relative: the same sums, reordered)
SCAN_COST_RTOL = 1e-9
#: a refit of the right family from 30 % off reaches the truth's own cost within this share;
#: the wrong family (the CoM) must miss it by more than twice that
REFIT_COST_TOL = 0.05
#: the mounts' stiffnesses the drives excite, recovered within this (relative): 0.5 % noise
#: on 2 x 120 frequencies, with the stage masses refitted too (the yaw and lateral mounts
#: trade off with them)
REL_STIFF = 0.08
#: the chassis' stiffnesses recovered within this (relative; same noise)
REL_CHASSIS = 0.03
#: the chassis's node masses within this (the bottom node, farthest from the stages, is the
#: least determined: 3.4 % off where every stiffness is within 1.7 %)
REL_CHASSIS_MASS = 0.05
#: the refined pivot within this of the true pivot in each direction [m]
PIVOT_TOL_M = 0.006
#: the refit at the refined pivot leaves at most this share of the bearing centre's excess
#: cost over the exact pivot's (measured: 0.06 with the weights before stop 51 and after,
#: the same refined pivot; the exact pivot's cost itself fell from 6.37 to 3.63, so a ratio
#: to it moved from 1.24 to 1.44 with nothing else changed); the bearing centre's at least
#: CENTRE_COST_FACTOR times the refined pivot's
PIVOT_EXCESS_SHARE = 0.15
CENTRE_COST_FACTOR = 2.0
#: the other elastic centre's refit lowers the objective below this share of the CoM's
VARIANT_COST_SHARE = 0.8


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


_data = noisy_bonder_data


def _bottom(c):  # type: ignore[no-untyped-def]
    """The variant whose elastic centre lies on the hull's bottom face below the CoM."""
    com = np.array(c.spec["centre"])
    below = [v for v in c.variants if np.allclose(v.spec["centre"][:2], com[:2])]
    return next(v for v in below if v.spec["centre"][2] < com[2])


def test_soft_mounts_carry_elastic_centre_variants(doc):
    """The CoM first; variants on the collision hull's bottom face (below the CoM and at the
    face's centre), each with every mount stiffness its own parameter."""
    from bondid.consistency.hull import link_hull
    from bondid.diagnose.effects import get_effect

    (c,) = get_effect("soft_mounts").candidates(doc)
    lo = link_hull(doc.link(c.spec["root"])).vertices.min(axis=0)
    assert len(c.variants) >= 1
    for v in c.variants:
        assert v.spec["centre"][2] == pytest.approx(lo[2], abs=ROUNDING_ABS_M) and v.variants == ()
        assert [p.name for p in v.parameters] == [p.name for p in c.parameters]
    assert _bottom(c).spec["centre"][2] < c.spec["centre"][2]
    # rocking about a centre below the CoM is slower: a larger start stiffness for the same
    # 30 Hz start (the parallel-axis term), translations unchanged
    k = {p.name: p.initial for p in c.parameters}
    kb = {p.name: p.initial for p in _bottom(c).parameters}
    assert kb["stiffness_tx"] == pytest.approx(k["stiffness_tx"], rel=ROUNDING_REL)
    assert kb["stiffness_rx"] > k["stiffness_rx"] and kb["stiffness_ry"] > k["stiffness_ry"]


def test_unequal_mounts_below_the_com_are_refitted_to_the_truth(doc):
    """Known answer: data from the nominal model on six unequal mounts about the bottom face.
    The screening of the variants keeps the bottom-face centre; its refit from 30 % off
    recovers every stiffness; the CoM candidate (the family before the variants) cannot reach
    the same cost."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build, with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.runner import Job, _screen_variants, direct

    e = get_effect("soft_mounts")
    (c,) = e.candidates(doc)
    target = _bottom(c)
    truth = np.array([p.initial for p in target.parameters]) * np.array(MOUNTS)
    data = _data(e.augment(doc, with_values(target, truth)))
    space = nominal_space(doc, FEW, 4000.0)
    text = doc.to_string()
    job = Job(text, space, data, data, data, c, CostOptions(), alt_urdf=text)
    picked, _ = _screen_variants(job)
    assert picked.candidate is not None
    assert picked.candidate.spec["centre"] == target.spec["centre"], picked.candidate.description

    def refit(cand, values):  # type: ignore[no-untyped-def]
        r = build(text, space, data, CostOptions(), (), with_values(cand, values)).refit
        state, cost, _ = r.solve(r.state0, direct(150, 30))
        return r.new_values(state), cost

    at_truth = build(text, space, data, CostOptions(), (), with_values(target, truth)).refit
    c_truth = at_truth.cost(at_truth.state0)
    got, cost = refit(target, truth * 1.3)
    assert cost < (1 + REFIT_COST_TOL) * c_truth, (cost, c_truth)
    # the drives push in x and y: the horizontal and rocking mounts show, the vertical one
    # (and the damping ratios) hardly: those within REL_STIFF
    for p, v, want in zip(target.parameters, got, truth, strict=True):
        if p.name in ("stiffness_tx", "stiffness_ty", "stiffness_rx", "stiffness_ry",
                      "stiffness_rz"):  # fmt: skip
            assert v == pytest.approx(want, rel=REL_STIFF), (p.name, v, want)
    # the CoM candidate (the family before the variants), started as close, stays above:
    # it misses the truth's cost by more than twice the tolerance the right family meets
    _, cost_com = refit(replace(c, variants=()), truth * 1.3)
    assert cost_com > (1 + 2 * REFIT_COST_TOL) * c_truth, (cost_com, c_truth, cost)


def test_a_chassis_heavier_at_the_bottom_is_refitted_to_the_truth(doc):
    """Known answer: data from the nominal model on a flexible base heavier at the bottom
    and heavier in all than the root body's mass (node masses 1.6, 1.4, 1.2, 1.0, 0.8 and 0.5
    times the uniform rod's shares, bottom to top, as under a heavy bed plate), modes near
    500 Hz; the refit started from the uniform rod of the root's mass, stiffnesses 30 % off,
    recovers every node's mass and every stiffness."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build, with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.runner import direct

    fb = get_effect("flexible_base")
    (c,) = fb.candidates(doc)
    names = [p.name for p in c.parameters]
    uniform = np.array([p.initial * 0.5**p.scan for p in c.parameters])
    shares = (1.6, 1.4, 1.2, 1.0, 0.8, 0.5)
    heavier = dict(zip([n for n in names if n.endswith("mass")], shares, strict=True))
    assert "top_mass" in heavier
    truth = uniform * np.array([heavier.get(n, 1.0) for n in names])
    data = _data(fb.augment(doc, with_values(c, truth)))
    start = uniform * np.where(np.char.endswith(names, "stiffness"), 1.3, 1.0)
    r = build(doc.to_string(), nominal_space(doc, FEW, 4000.0), data, CostOptions(), (),
              with_values(c, start)).refit  # fmt: skip
    assert not any(v.held for v in r.new)
    # the scans' one-problem costs agree with each state's own, also for a state that moves
    # the top mass (a link mass, not a joint entry of the problem)
    exps = np.array([p.scan for p in c.parameters])
    states = [
        *r.profile(r.state0, exps, c.scan_grid[::20]),
        r.with_new(r.state0, start * np.where(np.array(names) == "top_mass", 0.7, 1.0)),
    ]
    want_costs = [r.cost(s) for s in states]
    assert r.costs(r.state0, states) == pytest.approx(want_costs, rel=SCAN_COST_RTOL)
    state, _, _ = r.solve(r.state0, direct(150, 30))
    got = dict(zip(names, r.new_values(state), strict=True))
    for name, want in zip(names, truth, strict=True):
        if name.endswith(("mass", "stiffness")):
            tol = REL_CHASSIS_MASS if name.endswith("mass") else REL_CHASSIS
            assert got[name] == pytest.approx(want, rel=tol), (name, got[name], want)


def test_a_pivot_off_the_bearing_centre_in_both_directions_is_found(doc):
    """Known answer: data from the nominal model plus a roll DOF under the x stage at 450 Hz
    whose pivot lies 20 mm and 15 mm off the bearing centre across the axis (no variant has
    it: they move one direction at a time); the pivot refinement from the bearing centre ends
    near it, and the refit there reaches a cost near the exact pivot's."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.alternatives import refine_job_pivot
    from bondid.diagnose.augmented import build, with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.pivot import with_pivot
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.runner import Job, direct

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "base->x_stage:rx")
    centre = np.array(c.spec["pivot"])
    true_pivot = centre + np.array([0.0, 0.02, 0.015])
    stiff = np.array([p.initial * 1.5 ** (2 * p.scan) for p in c.parameters])  # 450 Hz
    exact = with_pivot(c, true_pivot)
    data = _data(e.augment(doc, with_values(exact, stiff)))
    space = nominal_space(doc, FEW, 4000.0)
    text = doc.to_string()
    job = Job(text, space, data, data, data, replace(c, variants=()), CostOptions(),
              alt_urdf=text, start_new=tuple(stiff * 1.3))  # fmt: skip
    refined, _, _ = refine_job_pivot(job)
    assert refined.candidate is not None
    got = np.array(refined.candidate.spec["pivot"])
    assert np.all(np.abs(got - true_pivot) < PIVOT_TOL_M), (got - centre, true_pivot - centre)

    def refit(cand):  # type: ignore[no-untyped-def]
        r = build(text, space, data, CostOptions(), (), with_values(cand, stiff * 1.3)).refit
        return r.solve(r.state0, direct(150, 30))[1]

    c_exact, c_got, c_centre = refit(exact), refit(refined.candidate), refit(c)
    figures = (c_exact, c_got, c_centre)
    assert c_got - c_exact < PIVOT_EXCESS_SHARE * (c_centre - c_exact), figures
    assert c_centre > CENTRE_COST_FACTOR * c_got, figures


def test_the_warm_pivot_search_finds_a_pivot_far_off_the_centre(doc):
    """Known answer: a roll DOF under the x stage whose pivot lies 40 mm and 30 mm off the
    bearing centre; from a refit at the bearing centre (its spring at the mode), the warm
    search (each pivot's spring scaled to keep its frequency, the new parameters solved
    alone) ends near the true pivot, with the state it found there."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.alternatives import refine_job_pivot
    from bondid.diagnose.augmented import build, with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.runner import Job, direct

    e = get_effect("joint_compliance")
    c = replace(next(c for c in e.candidates(doc) if c.location == "base->x_stage:rx"),
                variants=())  # fmt: skip
    centre = np.array(c.spec["pivot"])
    true_pivot = centre + np.array([0.0, 0.04, 0.03])
    exact = e.at_pivot(doc, c, true_pivot)  # type: ignore[attr-defined]
    stiff = np.array([p.initial * 1.5 ** (2 * p.scan) for p in exact.parameters])  # 450 Hz
    data = _data(e.augment(doc, with_values(exact, stiff)))
    space = nominal_space(doc, FEW, 4000.0)
    text = doc.to_string()
    aug = build(text, space, data, CostOptions(), (), c)
    start = aug.refit.with_new(aug.refit.state0, stiff)
    state = aug.refit.solve(start, direct(150, 30))[0]
    job = Job(text, space, data, data, data, c, CostOptions(), alt_urdf=text)
    refined, note, found = refine_job_pivot(job, (aug, state))
    assert refined.candidate is not None and found is not None, note
    got = np.array(refined.candidate.spec["pivot"])
    assert np.all(np.abs(got - true_pivot) < 2 * PIVOT_TOL_M), (got - centre, note)
    assert "warm figure" in note


def test_a_candidate_about_another_pivot_keeps_its_start_frequency(doc):
    """at_pivot rebuilds the start about the new pivot: the stiffness over the effective
    inertia about that pivot still puts the spring-alone mode at the reference frequency,
    and the damper keeps its ratio; with_pivot keeps the old numbers."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.topology import effective_inertia
    from bondid.diagnose.pivot import with_pivot

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "base->x_stage:rx")
    pivot = np.array(c.spec["pivot"]) + np.array([0.0, 0.06, -0.03])
    moved = e.at_pivot(doc, c, pivot)  # type: ignore[attr-defined]
    assert np.allclose(moved.spec["pivot"], pivot) and moved.variants == ()
    k, d = (p.initial for p in moved.parameters)
    m = effective_inertia(e.augment(doc, moved), moved.spec["joint"])
    assert np.sqrt(k / m) / (2 * np.pi) == pytest.approx(moved.ref_hz, rel=ROUNDING_REL * 1e3)
    k0, d0 = (p.initial for p in c.parameters)
    assert abs(k / k0 - 1) > 0.01  # the inertia about the new pivot differs
    assert d / d0 == pytest.approx(k / k0)  # both follow the inertia: the same ratio
    kept = with_pivot(c, pivot)
    assert [p.initial for p in kept.parameters] == [k0, d0]


def test_the_pivot_search_stays_inside_the_box():
    """A cost whose minimum lies outside the box: the search ends on the box's edge."""
    from bondid.diagnose.effects.base import Candidate
    from bondid.diagnose.pivot import refine_pivot

    spec = {"axis": [0.0, 1.0, 0.0], "pivot": [0.0, 0.0, 0.0], "kind": "revolute"}
    c = Candidate("joint_compliance", "a->b:ry", (), spec, (), "a DOF pivot [0] mm")
    target = np.array([0.5, 0.0, -0.2])
    box = (np.array([-0.1, -0.1, -0.1]), np.array([0.1, 0.1, 0.1]))

    seen = []

    def cost(k):  # type: ignore[no-untyped-def]
        p = np.array(k.spec["pivot"])
        seen.append(p)
        return float(np.sum((p - target) ** 2))

    best, _, _ = refine_pivot(c, cost, np.array([0.2, 0.2, 0.2]), box=box)
    inside = [bool(np.all(p >= box[0]) and np.all(p <= box[1])) for p in seen]
    assert all(inside), seen
    got = np.array(best.spec["pivot"])
    assert got[0] == pytest.approx(0.1) and got[2] == pytest.approx(-0.1), got
    best_free, _, _ = refine_pivot(c, cost, np.array([0.2, 0.2, 0.2]))
    assert np.array(best_free.spec["pivot"])[0] > 0.1  # without the box it leaves it


def test_the_grid_finds_a_narrow_basin_the_compass_search_misses():
    """Known answer: a cost with a broad local minimum at the start and a narrow, deeper
    basin across the box (the final fit's landscape on bonder/jcr+al/coh). The compass
    search alone stays in the first; started from the grid's best point it reaches the
    second within 5 mm."""
    from bondid.diagnose.effects.base import Candidate
    from bondid.diagnose.pivot import refine_pivot

    spec = {"axis": [0.0, 1.0, 0.0], "pivot": [0.0, 0.0, 0.03], "kind": "revolute"}
    c = Candidate("joint_compliance", "a->b:ry", (), spec, (), "a DOF pivot [0] mm")
    deep = np.array([0.02, 0.0, -0.015])
    box = (np.array([-0.08, -0.1, -0.025]), np.array([0.08, 0.1, 0.05]))

    def cost(k):  # type: ignore[no-untyped-def]
        p = np.array(k.spec["pivot"])
        local = 10.0 - 3.0 * np.exp(-np.sum((p - [0.0, 0.0, 0.03]) ** 2) / 0.02**2)
        basin = 9.7 * np.exp(-np.sum((p - deep) ** 2) / 0.025**2)
        return float(local - basin)

    extent = box[1] - box[0]
    alone, _, _ = refine_pivot(c, cost, extent, box=box, max_evals=24)
    assert np.linalg.norm(np.array(alone.spec["pivot"]) - deep) > 0.02
    best, _, n = refine_pivot(c, cost, extent, box=box, max_evals=24, grid=5)
    assert np.linalg.norm(np.array(best.spec["pivot"]) - deep) < 0.005
    assert n <= 1 + 25 + 23  # the start, the grid, then the compass search's budget


def test_the_pivot_box_takes_in_the_bearing_centre(doc):
    """The reference bonder's x_stage->y_stage:ry: the bearing centre lies below the y
    stage's hull; the box the pivot is searched in is the hull's box grown to take it in,
    for the candidate and for each of its variants."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.topology import link_box
    from bondid.diagnose.pivot import pivot_box

    cands = get_effect("joint_compliance").candidates(doc)
    c = next(k for k in cands if k.location == "x_stage->y_stage:ry")
    hull = link_box(doc, "y_stage")
    assert hull is not None
    bearing = np.array(c.spec["bearing"])
    assert np.allclose(bearing, c.spec["pivot"])
    assert not np.all((hull[0] <= bearing) & (bearing <= hull[1]))  # the case it is for
    for k in (c, *c.variants):
        box = pivot_box(k)
        assert box is not None
        assert np.all(box[0] <= bearing) and np.all(bearing <= box[1])
        assert np.all(box[0] <= hull[0]) and np.all(box[1] >= hull[1])
        assert np.allclose(k.spec["bearing"], bearing)


def test_a_refit_above_the_noise_tries_the_other_elastic_centres(doc):
    """Known answer: unequal mounts about the bottom face's centre; a refit of the CoM
    variant (as if the screening had kept it) ends above the noise level, and the other
    variants' full refits replace it by the face centre's, at a lower objective."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.alternatives import other_variants
    from bondid.diagnose.augmented import with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.rescue import above_noise
    from bondid.diagnose.runner import Job, _fit

    e = get_effect("soft_mounts")
    (c,) = e.candidates(doc)
    centre = c.variants[-1]  # the bottom face's centre
    truth = np.array([p.initial for p in centre.parameters]) * np.array(MOUNTS)
    data = _data(e.augment(doc, with_values(centre, truth)))
    text = doc.to_string()
    job = Job(text, nominal_space(doc, FEW, 4000.0), data, data, data, replace(c, variants=()),
              CostOptions(), alt_urdf=text, start_new=tuple(truth), all_iter=60)  # fmt: skip
    aug, state, res = _fit(job)
    assert above_noise(aug.refit, state)
    job2, aug2, state2, _ = other_variants(job, aug, state, res)
    assert job2.candidate is not None and job2.candidate.spec["centre"] == centre.spec["centre"]
    assert aug2.refit.cost(state2) < VARIANT_COST_SHARE * aug.refit.cost(state)
