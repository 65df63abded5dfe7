"""Where a diagnosis's refits run (bondid.diagnose.pool): the cancellation of work a decided
step no longer needs, and a diagnosis fanned out on a Dask cluster giving the answer of the
local run."""

from __future__ import annotations

from pathlib import Path

import pytest
from models import noisy_bonder_data

from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass"]


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def _task(doc):  # type: ignore[no-untyped-def]
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.job import Task
    from bondid.diagnose.pipeline import Settings, prepare_data

    data = noisy_bonder_data(doc, n=60)
    p = prepare_data(doc, data, Settings(n_points=60, free=FEW, modes=False))
    cand = get_effect("sensor_delay").candidates(doc)[0]
    return Task(doc.to_string(), p.space, p.train, p.held, p.full, p.options, candidate=cand)


def test_a_cancelled_refit_returns_at_once_in_a_worker(doc):
    """A task whose token is cancelled before it runs stops before its first start, and
    reports so; a task of a later token is not affected."""
    from dataclasses import replace

    from bondid.diagnose.pool import LocalPool
    from bondid.diagnose.refit_job import run_refit

    task = _task(doc)
    pool = LocalPool(2)
    try:
        first, second = pool.token(), pool.token()
        assert (first, second) == (1, 2)
        pool.cancel_level(first)
        out = pool.submit(run_refit, replace(task, token=first)).result()
        assert out.error == "cancelled"
        kept = pool.submit(run_refit, replace(task, token=second)).result()
        assert not kept.error and kept.label == task.candidate.label
    finally:
        pool.close()
    # in this process nothing runs beside: no token, nothing to cancel
    here = LocalPool(1)
    assert here.token() == 0 and not here.parallel


@pytest.mark.slow
def test_a_diagnosis_on_a_dask_cluster_gives_the_local_answer(doc):
    """The same diagnosis with its screenings and refits on the workers of a Dask cluster
    (``Settings.scheduler``) as on local processes: the same verdict and outcome."""
    distributed = pytest.importorskip("dask.distributed")
    from bondid.diagnose import diagnose
    from bondid.diagnose.pipeline import Settings

    data = noisy_bonder_data(doc, n=60)
    kw = dict(n_points=60, free=FEW, modes=False, effects=["sensor_delay"])
    local = diagnose(doc, data, Settings(workers=1, **kw))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:  # fmt: skip
        remote = diagnose(doc, data, Settings(scheduler=cluster.scheduler_address, **kw))
    assert (remote.winner is None) == (local.winner is None)
    assert remote.outcome is not None and local.outcome is not None
    assert remote.outcome.kind == local.outcome.kind
    assert remote.baseline.db_rms == pytest.approx(local.baseline.db_rms, rel=1e-6)
