"""A run's results as one unit (:mod:`bondid.results`), finite default bounds, and a failed
fit that still writes what it learnt (issue 16, points 7 and 8)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bondid.exceptions import ConfigError, DataError
from bondid.results import open_results, read_manifest

from .conftest import fast_args


def test_second_run_into_the_same_out_is_refused(tmp_path):
    first = open_results(tmp_path / "out", "fit", [])
    try:
        with pytest.raises(ConfigError, match="another bondid run"):
            open_results(tmp_path / "out", "fit", [])
    finally:
        first.close()
    open_results(tmp_path / "out", "fit", []).close()  # free again once released


def test_new_folder_appears_whole_with_its_manifest(tmp_path):
    res = open_results(tmp_path / "new", "fit", [])
    res.path("fit.json").write_text("{}")
    res.path("bode.png").write_bytes(b"x")
    assert not (tmp_path / "new").exists()  # staged, not visible yet
    res.commit(main="fit.json")
    m = read_manifest(tmp_path / "new", "fit")
    assert m is not None and sorted(m["files_by_name"]) == ["bode.png", "fit.json"]
    assert sorted(os.listdir(tmp_path)) == ["new"]  # no lock, no staging folder left


def test_rerun_replaces_the_previous_run_and_keeps_other_files(tmp_path):
    out = tmp_path / "out"
    res = open_results(out, "fit", [])
    res.path("fit.json").write_text('{"run": 1}')
    res.path("bode_old.png").write_bytes(b"1")
    res.commit()
    (out / "notes.txt").write_text("the user's own file")
    res = open_results(out, "fit", [])
    res.path("fit.json").write_text('{"run": 2}')
    res.commit()
    assert sorted(os.listdir(out)) == ["fit.json", "fit.manifest.json", "notes.txt"]
    assert json.loads((out / "fit.json").read_text()) == {"run": 2}


def test_abandoned_run_leaves_nothing_and_stale_staging_is_cleaned(tmp_path):
    out = tmp_path / "out"
    res = open_results(out, "fit", [])
    res.path("fit.json").write_text("{}")
    stale = tmp_path / ".out.bondid-tmp-99999-deadbeef"  # what a SIGKILL leaves
    stale.mkdir()
    (stale / "fit.json").write_text("")
    res.close()  # an error or Ctrl-C before the commit
    assert not out.exists()
    open_results(out, "fit", []).close()
    assert sorted(os.listdir(tmp_path)) == []


def test_manifest_detects_a_changed_file(tmp_path):
    res = open_results(tmp_path / "o", "sensitivity", [])
    res.path("sensitivity.json").write_text("{}")
    res.commit()
    (tmp_path / "o" / "sensitivity.json").write_text('{"tampered": true}')
    with pytest.raises(DataError, match="differs"):
        read_manifest(tmp_path / "o", "sensitivity")


KINDS = ("mass", "com", "inertia", "stiffness", "damping")


@settings(max_examples=15, deadline=None)
@given(st.lists(st.sampled_from(range(50)), min_size=1, max_size=6, unique=True))
def test_every_default_bound_is_finite(indices):
    from bondid.model.document import UrdfDocument
    from bondid.model.parameters import select_parameters
    from bondid.optim.bounds import default_bounds

    from .conftest import BONDER

    doc = UrdfDocument.load(BONDER)
    every = select_parameters(doc, ["all", "x.*", "y.*"], [])
    names = [every[i % len(every)] for i in indices]
    names = list(dict.fromkeys(names))
    lo, hi = default_bounds(doc, names, f_max_hz=3000.0)
    assert np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi)


def test_failed_ipopt_still_writes_fit_json(inputs, run, tmp_path, monkeypatch):
    """IPOPT failing outright (here forced after a real solve) keeps its best feasible
    iterate: fit.json has status "failed", the best point, and why; exit 1."""
    from bondid.optim import ipopt

    real = ipopt._stats

    def failing(solver, n_recorded):
        return "Diverging_Iterates", real(solver, n_recorded)[1]

    monkeypatch.setattr(ipopt, "_stats", failing)
    out = tmp_path / "fit"
    argv = fast_args("fit", inputs["model"], [inputs["d0"]], out)
    argv[argv.index("--max-iter") + 1] = "10"
    code, _, err = run("fit", *argv)
    assert code == 1 and "failed" in err
    fit = json.loads((out / "fit.json").read_text())
    assert fit["status"] == "failed" and fit["solver_status"] == "Diverging_Iterates"
    assert "Diverging_Iterates" in fit["failure"]
    p = fit["parameters"][0]
    assert p["fitted"] is not None and p["lower"] <= p["fitted"] <= p["upper"]
    assert fit["cost_final"] <= fit["cost_initial"]  # the best point, not the last one
    assert read_manifest(out, "fit") is not None


def test_fit_without_any_iterate_still_says_why(inputs, run, tmp_path, monkeypatch):
    """Every run failed before IPOPT reached a feasible point: fit.json still tells."""
    from bondid.exceptions import SolverError
    from bondid.fit import multistart

    def fail(*a, **kw):
        raise SolverError(
            "all 1 fit run(s) failed; start 0: Restoration_Failed", "Restoration_Failed"
        )

    monkeypatch.setattr(multistart, "run_multistart", fail)
    out = tmp_path / "fit"
    code, _, err = run("fit", *fast_args("fit", inputs["model"], [inputs["d0"]], out))
    assert code == 1 and "Restoration_Failed" in err
    fit = json.loads((out / "fit.json").read_text())
    assert fit["status"] == "failed" and "Restoration_Failed" in fit["failure"]
    assert fit["parameters"][0]["initial"] == 200000.0 and fit["parameters"][0]["fitted"] is None
