"""Tests of the screening's keep rule (bondid.diagnose.screen.select) and of the scan grid the
screening and the full refit share (bondid.diagnose.scan_grid)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bondid.diagnose.screen import TIE_FRACTION, UNEXPLAINED_RATIO, Screening, select
from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
#: the noise-level cost of the synthetic steps below
NOISE = 1.0


def _screens(costs: list[float], noise: float = NOISE) -> list[Screening]:
    return [
        Screening(f"c{i}", "e", f"l{i}", c, c, 0.0, noise_cost=noise) for i, c in enumerate(costs)
    ]


def test_select_keeps_the_lowest_figures_when_the_step_is_explained():
    """Best figure within UNEXPLAINED_RATIO of the noise level: the ranking is trusted, only
    n_refit are kept even though the others tie."""
    best = 0.9 * UNEXPLAINED_RATIO * NOISE
    costs = [best * (1 + 1e-4 * k) for k in range(10)]
    assert select(_screens(costs[::-1]), 3, 8) == [9, 8, 7]


def test_select_keeps_ties_of_an_unexplained_step_up_to_n_max():
    """Best figure well above the noise level and a flat cluster after the n_refit-th: the
    cluster is kept (ties within TIE_FRACTION of the last kept's excess), in figure order,
    up to n_max; a clear gap ends the ties; failed candidates never."""
    last = 4.0  # excess over the noise level: 3.0
    tie = TIE_FRACTION * (last - NOISE)
    costs = [2.0, 3.0, last, last + 0.2 * tie, last + 0.9 * tie, last + 1.5 * tie, math.inf]
    s = _screens(costs)
    assert select(s, 3, 10) == [0, 1, 2, 3, 4]
    assert select(s, 3, 4) == [0, 1, 2, 3]
    # without n_max (or n_max ≤ n_refit) the rule is the plain top n_refit
    assert select(s, 3) == [0, 1, 2]
    assert select(s, 3, 3) == [0, 1, 2]
    # without a noise level the ties cannot be judged: top n_refit
    assert select(_screens(costs, noise=math.nan), 3, 10) == [0, 1, 2]


def test_select_is_invariant_to_the_order_screened():
    rng = np.random.default_rng(3)
    costs = list(5.0 + 1e-3 * rng.random(12))
    s = _screens(costs)
    kept = select(s, 4, 9)
    perm = rng.permutation(len(costs))
    kept_p = select([s[i] for i in perm], 4, 9)
    assert [s[i].label for i in kept] == [s[perm[i]].label for i in kept_p]
    assert len(kept) == 9  # every figure ties (spread 1e-3 ≪ 2 % of an excess of 4)


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")


def test_scan_grid_puts_the_compliance_mode_at_each_hint(doc):
    """Known answer: a joint compliance's stiffness scaled by a hint's factor resonates on the
    DOF's effective inertia at that hint; the grid is the candidate's own plus the hints'."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.topology import effective_inertia
    from bondid.diagnose.scan_grid import scan_grid

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "x_stage->y_stage:tz")
    hints = (123.0, 2345.0)
    grid, factors = scan_grid(c, hints)
    assert set(factors) <= set(grid) and set(c.scan_grid) <= set(grid)
    assert list(grid) == sorted(set(grid)) and len(grid) == len(set(c.scan_grid)) + 2
    probe = e.augment(doc, c)
    m = effective_inertia(probe, c.spec["joint"])
    k0 = c.parameters[0].initial
    for f, s in zip(hints, factors, strict=True):
        f_mode = math.sqrt(k0 * s ** c.parameters[0].scan / m) / (2 * math.pi)
        assert f_mode == pytest.approx(f, rel=1e-9)


def test_scan_grid_of_a_signal_candidate_has_no_hints(doc):
    """An FRF modifier has no mode: its grid is its own, no hint factors."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.scan_grid import scan_grid

    c = get_effect("sensor_delay").candidates(doc)[0]
    grid, factors = scan_grid(c, (100.0, 200.0))
    assert factors == [] and grid == tuple(sorted(set(c.scan_grid)))


def test_select_puts_ties_at_a_kept_site_first():
    """Ties at the interface of a kept candidate (another axis) come before better-figured ties
    elsewhere; ties beyond n_max are dropped, the n_refit kept ones never."""
    last = 4.0
    tie = TIE_FRACTION * (last - NOISE)
    s = _screens([2.0, last, last + 0.1 * tie, last + 0.2 * tie, last + 0.3 * tie])
    s[0].location = "a->b:rz"
    s[1].location = "c"
    s[2].location = "d->e:tx"
    s[3].location = "f"
    s[4].location = "a->b:tz"  # the same interface as the best, another axis
    assert select(s, 2, 4) == [0, 1, 4, 2]
    assert select(s, 2, 3) == [0, 1, 4]


def test_select_takes_ties_in_turn_by_site_and_by_the_second_origin():
    """Ties of an unexplained step are taken in turn from two orders: at a kept site first,
    and by the second origin's figure (where an effect the parameter refit absorbed still
    shows); a tie without a second-origin figure comes only through the site order."""
    last = 4.0
    tie = TIE_FRACTION * (last - NOISE)
    s = _screens([2.0, last, last + 0.1 * tie, last + 0.2 * tie, last + 0.3 * tie,
                  last + 0.4 * tie])  # fmt: skip
    s[0].location = "a->b:rz"
    s[1].location = "c"
    for k, loc in zip(range(2, 6), ["d->e:tx", "f", "a->b:tz", "g"], strict=True):
        s[k].location = loc
    seconds = {2: 9.0, 3: 8.0, 4: math.nan, 5: 5.0}  # 5 best from the nominal model
    for k, v in seconds.items():
        s[k].by_origin = (s[k].cost, v)
    # turns: second origin's best (5), then the kept site's tie (4), then 3, then 2
    assert select(s, 2, 6) == [0, 1, 5, 4, 3, 2]
    assert select(s, 2, 4) == [0, 1, 5, 4]
    assert select(s, 2, 3) == [0, 1, 5]
    # without second-origin figures: the site order alone (as before)
    for k in seconds:
        s[k].by_origin = (s[k].cost, math.nan)
    assert select(s, 2, 4) == [0, 1, 4, 2]


def test_select_takes_the_best_kept_site_first():
    """Ties at several kept sites: those at the site of the better-ranked kept candidate come
    first, whatever their own figure (bonder_b/jct/nocoh: the truth, another axis of the best
    candidate's interface, came after a tie at the 4th kept candidate's site)."""
    last = 4.0
    tie = TIE_FRACTION * (last - NOISE)
    s = _screens([2.0, last, last + 0.1 * tie, last + 0.2 * tie, last + 0.3 * tie])
    s[0].location = "a->b:rz"  # the best kept candidate
    s[1].location = "c->d:tx"  # the last kept one
    s[2].location = "e"
    s[3].location = "c->d:tz"  # a tie at the last kept candidate's site
    s[4].location = "a->b:tz"  # a tie at the best kept candidate's site
    assert select(s, 2, 3) == [0, 1, 4]
    assert select(s, 2, 5) == [0, 1, 4, 3, 2]


def test_a_candidate_picked_twice_is_refitted_once():
    from bondid.diagnose.search import refit_indices

    assert refit_indices([3, 1], [5, 1], [5, 7]) == [3, 1, 5, 7]
    assert refit_indices([], [2], [2]) == [2]
    assert refit_indices([4], [], []) == [4]
