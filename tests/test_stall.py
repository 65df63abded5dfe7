"""The stall test (bondid.optim.stall): a solve whose cost, steps and projected gradient have
gone flat stops converged with its reason; the command's status line, exit code and advice."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from models import two_mass_chain

from bondid.fit.summary import ITERATION_LIMIT, exit_code, merged_notes, status_line, summary
from bondid.optim.ipopt import SOFT_STATUSES, SUCCESS_STATUSES, TINY_STEP, solve
from bondid.optim.problem import FitProblem
from bondid.optim.stall import (
    STALLED,
    StallMonitor,
    StallRule,
    gauss_newton_decrement,
    still_falling,
)
from bondid.simulate import simulate

#: the decrement of a linear least-squares problem equals its exact decrease to round-off
DECREMENT_RTOL = 1e-10
#: a stalled solve ends where IPOPT's own test ends, to this relative cost
SAME_COST_RTOL = 1e-8


def test_gauss_newton_decrement_is_the_exact_decrease_of_a_linear_least_squares():
    """For r = A z − b the Gauss–Newton step is exact: ¼ dᵀ(AᵀA)⁻¹d = f(z) − min f."""
    rng = np.random.default_rng(3)
    A, b, z = rng.normal(size=(40, 6)), rng.normal(size=40), rng.normal(size=6)
    f = float(np.sum((A @ z - b) ** 2))
    z_star = np.linalg.lstsq(A, b, rcond=None)[0]
    f_star = float(np.sum((A @ z_star - b) ** 2))
    d = 2.0 * A.T @ (A @ z - b)
    assert math.isclose(gauss_newton_decrement(A, d), f - f_star, rel_tol=DECREMENT_RTOL)


def test_decrement_leaves_out_directions_the_data_do_not_determine():
    """A gradient along a null direction of J promises nothing (no division by ~0)."""
    J = np.array([[1.0, 0.0], [0.0, 0.0], [2.0, 0.0]])
    assert gauss_newton_decrement(J, np.array([0.0, 5.0])) == 0.0
    assert gauss_newton_decrement(J, np.array([2.0, 5.0])) == pytest.approx(0.25 * 4.0 / 5.0)


def _feed(monitor: StallMonitor, costs: list[float], steps: list[float]) -> list[bool]:
    z = np.zeros(3)
    out = [monitor(costs[0], z, np.zeros(3), np.zeros(0))]
    for f, s in zip(costs[1:], steps, strict=True):
        z = z + s
        out.append(monitor(f, z, np.zeros(3), np.zeros(0)))
    return out


@pytest.mark.parametrize(
    ("costs", "steps", "decrement", "stops"),
    [
        ([2.0] * 11, [1e-9] * 10, 1e-12, True),  # flat everywhere
        ([2.0 - 1e-3 * k for k in range(12)], [1e-9] * 11, 1e-12, False),  # still falling
        ([2.0] * 12, [1e-2] * 11, 1e-12, False),  # steps still moving
        ([2.0] * 12, [1e-9] * 11, 1e-3, False),  # the local model still promises a decrease
        ([2.0] * 10, [1e-9] * 9, 1e-12, False),  # too few iterations for the window
    ],
)
def test_stall_monitor_needs_all_three_conditions(costs, steps, decrement, stops):
    rule = StallRule(window=10)
    calls: list[np.ndarray] = []

    def dec(z: np.ndarray, lx: np.ndarray, lg: np.ndarray) -> float:
        calls.append(z)
        return decrement * costs[-1]

    mon = StallMonitor(rule, dec)
    said = _feed(mon, costs, steps)
    # the earliest iterate that closes a full window is where a stall is seen
    assert said == [stops and k == rule.window for k in range(len(costs))]
    assert (mon.reason is not None) is stops
    if stops:
        assert "stalled" in mon.reason and "10 iterations" in mon.reason
    # the decrement (a Jacobian) is asked for only once the cost and the steps are flat
    flat = len(costs) > rule.window and max(costs) - min(costs) == 0 and max(steps) < 1e-5
    assert bool(calls) is flat


def _wandering(costs: list[float], step: float = 1e-2) -> tuple[StallMonitor, list[bool]]:
    """A monitor fed ``costs`` with steps that never settle and a decrement that never
    vanishes: only the no-progress test can stop it."""
    mon = StallMonitor(StallRule(window=10), lambda z, lx, lg: 1.0)
    return mon, _feed(mon, costs, [step] * (len(costs) - 1))


#: the no-progress test's window (iterations) under the default rule
PROGRESS_WINDOW = StallRule().progress_window


def test_a_solve_that_makes_no_progress_stops_although_its_steps_still_move():
    """The best cost stuck within 1e-8 (relative) for a whole progress window, the steps
    still 1e-2: stopped where the window closes, converged with its reason."""
    rng = np.random.default_rng(0)
    n = PROGRESS_WINDOW + 20
    costs = list(229.5 * (1.0 + 1e-8 * rng.random(n)))
    costs[0] = 300.0  # the first iterate is far above: the window starts after it
    mon, said = _wandering(costs)
    assert said.index(True) == PROGRESS_WINDOW + 1
    assert mon.reason is not None and "no more progress" in mon.reason
    assert f"{PROGRESS_WINDOW} iterations" in mon.reason


@pytest.mark.parametrize(
    "costs",
    [
        # falling steadily by 1e-5 (relative) per iteration: progress
        [100.0 * (1.0 - 1e-5 * k) for k in range(PROGRESS_WINDOW + 20)],
        # flat at its best, but an iterate inside every window strays 1e-3 above it
        [100.0] * 30 + [100.1] + [100.0] * (PROGRESS_WINDOW - 10),
    ],
)
def test_progress_or_an_excursion_keeps_the_solve_going(costs):
    mon, said = _wandering(costs)
    assert not any(said) and mon.reason is None


def test_still_falling():
    assert still_falling([5.0, 4.0, 3.0])  # too short to tell: falling
    assert still_falling([10.0 - k for k in range(20)])
    assert not still_falling([1.0] * 20)
    assert not still_falling([1.0 + 1e-12 * k for k in range(20)])


@pytest.fixture(scope="module")
def chain_problem() -> FitProblem:
    truth = two_mass_chain(1.0, 0.5, 4e4, 8.0, 1e4, 3.0)
    data = simulate(truth, freq_hz=np.geomspace(5.0, 200.0, 80), noise=0.02, seed=4)
    names = ["a.stiffness", "b.stiffness", "a.damping", "b.damping", "body_b.mass"]
    model = two_mass_chain(1.0, 0.6, 3e4, 5.0, 1.3e4, 2.0)
    return FitProblem(model, [data], names)


#: IPOPT options that take away its own ways to stop short of ``tol`` (the tiny-step test
#: and the acceptable level), as on a problem where neither triggers
NO_OWN_STOP = {"tiny_step_tol": 0.0, "acceptable_iter": 0}


def test_a_solve_that_cannot_meet_its_tolerance_stops_converged_with_its_reason(chain_problem):
    """With tol = 1e-30 and IPOPT's own early stops off, the solve runs to its iteration limit
    without the stall test; with it, it stops converged at the point IPOPT's own test reaches
    with the default tolerance."""
    reference = solve(chain_problem, max_iter=200)
    assert reference.success and reference.status != STALLED
    kw = {"max_iter": 150, "tol": 1e-30, "ipopt_options": NO_OWN_STOP}
    endless = solve(chain_problem, stall=None, **kw)
    assert endless.status == ITERATION_LIMIT and not endless.success
    stalled = solve(chain_problem, **kw)
    assert stalled.status == STALLED and stalled.success and STALLED in SUCCESS_STATUSES
    assert stalled.stop_reason is not None and stalled.stop_reason.startswith("stalled:")
    assert stalled.iterations < 50 < endless.iterations
    assert math.isclose(stalled.cost, reference.cost, rel_tol=SAME_COST_RTOL)


def test_too_small_a_search_direction_at_a_flat_cost_is_converged(chain_problem):
    """IPOPT gives up on tol = 1e-30 with too small a search direction: without the stall
    test that reads as not converged, with it as converged (its reason says why)."""
    alone = solve(chain_problem, max_iter=150, tol=1e-30, stall=None)
    assert alone.status == TINY_STEP and alone.status in SOFT_STATUSES and not alone.success
    judged = solve(chain_problem, max_iter=150, tol=1e-30)
    assert judged.status == STALLED and judged.success
    assert judged.stop_reason is not None and "too small" in judged.stop_reason
    assert judged.cost == alone.cost


def _result(**kw):
    base = {"status": "Solve_Succeeded", "success": True, "iterations": 40, "failure": None,
            "solver_status": None, "cost_history": [], "stop_reason": None}  # fmt: skip
    return SimpleNamespace(**{**base, **kw})


def test_exit_code_and_advice(capsys):
    assert exit_code(_result(status=STALLED, stop_reason="stalled: ...")) == 0
    falling = [10.0 - 0.1 * k for k in range(50)]
    assert exit_code(_result(status=ITERATION_LIMIT, success=False, cost_history=falling)) == 1
    assert "raise --max-iter" in capsys.readouterr().err
    flat = [3.0] * 50
    assert exit_code(_result(status=ITERATION_LIMIT, success=False, cost_history=flat)) == 1
    err = capsys.readouterr().err
    assert "--max-iter" not in err and "will not lower it" in err


def test_status_line_says_how_it_converged_and_the_runs_time():
    extra = {"multistart": {"n_runs": 4, "iterations_all": 900}}
    line = status_line(_result(status=STALLED, iterations=120, wall_s=9.04), 11.46, extra)
    assert line.startswith("bondid.fit: converged: the cost stopped falling (Converged_Stalled)")
    assert "120 iterations in the kept search, 900 in all 4 runs" in line
    assert line.endswith("9.0 s fitting, 11.5 s in all")
    limit = _result(status=ITERATION_LIMIT, success=False, wall_s=1.0)
    assert "NOT converged" in status_line(limit, 1.0, {})


def test_one_fallback_note_when_the_kept_search_is_a_fallback_start():
    notes = [
        "a note",
        "fallback: the search ended at 1.40× ...; kept the staged schedule",
        "fallback: the search ended at 1.52× ...; kept the band continuation (8 bands)",
        "fallback starts: the fit ended at 1.40× ...; kept start 2 at 1.40×",
    ]
    out = merged_notes(notes, best_start=2)
    fb = [n for n in out if n.startswith("fallback:")]
    assert len(fb) == 1 and "start 2 (kept): the search ended at 1.40×" in fb[0]
    assert "start 0: the search ended at 1.52×" in fb[0]
    assert out[0] == "a note" and out[-1].startswith("fallback starts:")
    assert merged_notes(notes[:2], best_start=0) == notes[:2]


def test_summary_initial_column_is_the_models_value():
    """A kept fallback start is reported as the start, not as the model's "initial"."""
    res = _result(
        wall_s=2.0, names=["k"], initial=np.array([100.0]), fitted=np.array([110.0]),
        std=np.array([1.0]), start=np.array([900.0]), cost_start=7.0, cost_initial=5.0,
        cost_final=1.0, cost_name="complex_log_l2", active_constraints=[], notes=[],
    )  # fmt: skip
    text = summary(res, None, {"multistart": {"n_runs": 4, "n_failed": 0, "min": 1, "median": 2,
                                              "max": 3, "best_start": 2}}, 3.0)  # fmt: skip
    row = next(line for line in text.splitlines() if line.startswith("k "))
    assert row.split()[1:4] == ["100", "110", "+10.00"]
    assert "started from start 2 at 7" in text


def test_an_error_of_the_iteration_hook_stops_the_solve_quietly(chain_problem, capfd):
    """A progress hook that raises (a diagnosis cancelling a refit it no longer needs) ends
    the solve as failed with the hook's message, at the iterate it had reached, and CasADi
    prints nothing (no traceback, no dump of the iterate)."""
    calls = []

    def hook(iteration: int, cost: float) -> None:
        calls.append(cost)
        if iteration == 3:
            raise RuntimeError("no longer needed")

    out = solve(chain_problem, max_iter=200, progress=hook)
    assert not out.success and out.failure == "no longer needed"
    assert len(calls) == 4 and out.iterations <= 4
    assert out.cost <= calls[0]
    err = capfd.readouterr().err
    assert "Traceback" not in err and "fit_iteration" not in err
