"""bondid.threads: the per-process pool, its cap, and the problem's choice of threads."""

from __future__ import annotations

import itertools
import threading
from pathlib import Path

import numpy as np
import pytest

from bondid import threads

ROOT = Path(__file__).resolve().parents[1]


def _name(_: object) -> str:
    return threading.current_thread().name


def test_results_keep_their_order_and_errors_reach_the_caller():
    assert threads.thread_map(lambda x: x * x, list(range(20))) == [x * x for x in range(20)]

    def boom(x: int) -> int:
        if x == 3:
            raise KeyError("item 3")
        return x

    with pytest.raises(KeyError, match="item 3"):
        threads.thread_map(boom, list(range(6)))


def test_the_pool_lives_across_calls(monkeypatch):
    monkeypatch.setattr(threads, "available_cores", lambda: 2)
    monkeypatch.delenv(threads.THREADS_VAR, raising=False)
    first = set(threads.thread_map(_name, list(range(8))))
    pool = threads._pool
    second = set(threads.thread_map(_name, list(range(8))))
    assert threads._pool is pool  # the same executor, not one per call
    assert all(n.startswith("bondid") for n in first | second)


def test_the_cap_and_small_jobs_run_in_the_calling_thread(monkeypatch):
    monkeypatch.setattr(threads, "available_cores", lambda: 2)
    me = threading.current_thread().name
    assert set(threads.thread_map(_name, [1, 2, 3], parallel=False)) == {me}
    monkeypatch.setenv(threads.THREADS_VAR, "1")
    assert threads.thread_limit() == 1
    assert set(threads.thread_map(_name, [1, 2, 3])) == {me}
    monkeypatch.setenv(threads.THREADS_VAR, "lots")  # not an integer: ignored
    assert threads.thread_limit() == 2


def test_a_job_that_maps_again_does_not_wait_on_its_own_pool(monkeypatch):
    monkeypatch.setattr(threads, "available_cores", lambda: 2)
    monkeypatch.delenv(threads.THREADS_VAR, raising=False)

    def inner(x: int) -> list[str]:
        return threads.thread_map(_name, [x, x + 1])

    out = threads.thread_map(inner, [0, 10, 20])
    for names in out:  # the nested map ran in the job's own thread
        assert len(set(names)) == 1 and names[0].startswith("bondid")


@pytest.mark.parametrize("n_freq", [40, 600])
def test_threaded_and_serial_evaluations_agree(monkeypatch, n_freq):
    """The problem threads only large data sets; either way the numbers are the same."""
    from bondid.cost import problem as cp
    from bondid.cost.problem import FrfProblem
    from bondid.linear.parameter_map import ParameterMap
    from bondid.model import UrdfDocument, select_parameters
    from bondid.simulate import log_grid, simulate

    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    f = log_grid(1.0, 4000.0, n_freq)
    data = [simulate(doc, op, f) for op in ({}, {"x": 0.05})]
    prob = FrfProblem(doc, data)
    assert prob.threaded == (prob.blocks[0].Hm.size >= cp.THREADED_MIN_POINTS)
    pm = ParameterMap(doc, prob.affines[0], select_parameters(doc, ["default"]))
    x = pm.p0 * 1.1
    r1, J1 = prob.residual_and_jacobian(pm, x)
    prob.threaded = not prob.threaded
    r2, J2 = prob.residual_and_jacobian(pm, x)
    np.testing.assert_allclose(r1, r2, rtol=0, atol=0)
    np.testing.assert_allclose(J1, J2, rtol=0, atol=0)
    np.testing.assert_allclose(prob.residual(pm, x), r1, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("channels", [None, "diagonal"])
def test_one_dense_data_set_is_cut_into_spans_with_the_same_numbers(monkeypatch, channels):
    """A single large data set is evaluated span by span on every core (each span of whole
    frequency blocks), and the residuals and Jacobian equal the one-job evaluation's bit for
    bit, on the whole grid and on a channel subset."""
    from bondid.cost import CostOptions
    from bondid.cost import problem as cp
    from bondid.cost.problem import FrfProblem
    from bondid.linear.parameter_map import ParameterMap
    from bondid.model import UrdfDocument, select_parameters
    from bondid.simulate import log_grid, simulate

    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    data = simulate(doc, {}, log_grid(1.0, 4000.0, 5000))
    chosen = None
    if channels == "diagonal":
        chosen = [f"{o}.{i}" for o, i in zip(data.outputs, data.inputs, strict=False)]
    prob = FrfProblem(doc, [data], CostOptions(channels=chosen))
    assert prob.threaded
    pm = ParameterMap(doc, prob.affines[0], select_parameters(doc, ["default"]))
    x = pm.p0 * 1.1
    monkeypatch.delenv(threads.THREADS_VAR, raising=False)
    monkeypatch.setattr(threads, "available_cores", lambda: 1)
    monkeypatch.setattr(cp, "thread_limit", lambda: 1)
    assert prob._tasks() == [(0, None)]
    r1, J1 = prob.residual_and_jacobian(pm, x)
    frf1 = prob.used_frf(pm, x)
    monkeypatch.setattr(threads, "available_cores", lambda: 4)
    monkeypatch.setattr(cp, "thread_limit", lambda: 4)
    tasks = prob._tasks()
    spans = [s for _, s in tasks]
    n_points = prob.blocks[0].Hm.size
    assert len(tasks) == min(4, n_points // cp.THREADED_MIN_POINTS) > 1
    assert spans[0].start == 0 and spans[-1].stop == prob.blocks[0].freq_hz.size
    assert all(a.stop == b.start for a, b in itertools.pairwise(spans))
    r2, J2 = prob.residual_and_jacobian(pm, x)
    np.testing.assert_array_equal(r1, r2)
    np.testing.assert_array_equal(J1, J2)
    np.testing.assert_allclose(prob.used_frf(pm, x)[0], frf1[0], rtol=1e-13, atol=0)
    np.testing.assert_allclose(prob.residual(pm, x), r1, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("n_freq", [1, 127, 128, 129, 1000, 5000])
@pytest.mark.parametrize("n_spans", [1, 2, 3, 7])
def test_frequency_spans_cover_the_lines_in_whole_blocks(n_freq, n_spans):
    from bondid.frf.jacobian import _BLOCK_FREQ, frequency_spans

    spans = frequency_spans(n_freq, n_spans)
    blocks = -(-n_freq // _BLOCK_FREQ)
    assert len(spans) == min(n_spans, blocks)
    covered = np.concatenate([np.arange(n_freq)[s] for s in spans])
    np.testing.assert_array_equal(covered, np.arange(n_freq))
    assert all(s.start % _BLOCK_FREQ == 0 and s.stop > s.start for s in spans)
