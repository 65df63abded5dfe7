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
    The screening gives the bottom-face centre a start; its refit from 30 % off
    recovers every stiffness; the CoM candidate (the family before the variants) cannot reach
    the same cost."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build, with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.job import Task
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.screen import screen
    from bondid.optim.schedules import direct

    e = get_effect("soft_mounts")
    (c,) = e.candidates(doc)
    target = _bottom(c)
    truth = np.array([p.initial for p in target.parameters]) * np.array(MOUNTS)
    data = _data(e.augment(doc, with_values(target, truth)))
    space = nominal_space(doc, FEW, 4000.0)
    text = doc.to_string()
    # the screening gives the bottom-face centre a start of its own (whether its one-step
    # figure leads is not decided by so little; the candidate's refit decides, see below)
    scr = screen(Task(text, space, data, data, data, CostOptions(), candidate=c))
    options = [c, *c.variants]
    assert any(options[st.variant].spec["centre"] == target.spec["centre"] for st in scr.starts)

    def refit(cand, values):  # type: ignore[no-untyped-def]
        r = build(text, space, data, CostOptions(), (), with_values(cand, values)).refit
        state, cost, _ = r.solve(r.state0, direct(30), max_iter=150)
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
    from bondid.optim.schedules import direct

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
    state, _, _ = r.solve(r.state0, direct(30), max_iter=150)
    got = dict(zip(names, r.new_values(state), strict=True))
    for name, want in zip(names, truth, strict=True):
        if name.endswith(("mass", "stiffness")):
            tol = REL_CHASSIS_MASS if name.endswith("mass") else REL_CHASSIS
            assert got[name] == pytest.approx(want, rel=tol), (name, got[name], want)


@pytest.mark.slow
def test_a_refit_of_the_other_elastic_centres_reaches_below_the_com_one(doc):
    """Known answer: unequal mounts about the bottom face's centre; the candidate's refit from
    its screened starts (the CoM family and every variant's start) keeps a bottom-face
    variant and ends below the best the CoM family alone reaches."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.job import Task
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.refit_job import run_refit

    e = get_effect("soft_mounts")
    (c,) = e.candidates(doc)
    centre = c.variants[-1]  # the bottom face's centre
    truth = np.array([p.initial for p in centre.parameters]) * np.array(MOUNTS)
    data = _data(e.augment(doc, with_values(centre, truth)))
    task = Task(doc.to_string(), nominal_space(doc, FEW, 4000.0), data, data, data,
                CostOptions(), candidate=c, max_iter=60)  # fmt: skip
    both = run_refit(task)
    com = run_refit(replace(task, candidate=replace(c, variants=())))
    assert not both.error and both.candidate is not None
    assert both.candidate.spec["centre"][2] < c.spec["centre"][2]  # below the CoM
    assert both.objective < VARIANT_COST_SHARE * com.objective
