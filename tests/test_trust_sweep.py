"""A fast part of the hostile-user sweep (``tools/sweep_inputs.py``): each case runs as its
own process in a fresh sandbox and must end without a traceback, crash or hang, with the
expected exit code and one line, touching nothing outside ``--out`` (issue 61)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parents[1] / "tools"
sys.path.insert(0, str(TOOLS))

import sweep_cases  # noqa: E402
import sweep_inputs  # noqa: E402
import sweep_sandbox  # noqa: E402

FAST = (
    "model_fifo-modes", "model_deep_200k-modes", "model_chain_3000-modes",
    "model_spring_1e300-modes", "model_limits_inverted-modes", "unknown_option-fit",
    "version_typo-modes", "q_nan-modes", "fit_json_list-report", "png_fifo-report",
    "png_link_out-report", "out_link_loop", "manifest_users_file", "report_manifest_traversal",
    "lock_file_link", "sigkill_in_commit",
)  # fmt: skip


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return sweep_sandbox.make_base(tmp_path_factory.mktemp("sweep") / "_base")


@pytest.mark.parametrize("name", FAST)
def test_sweep_case(name, base, tmp_path):
    (case,) = [c for c in sweep_cases.CASES if c.name == name]
    run = sweep_inputs.run_case(case, base, tmp_path, timeout=300)
    assert run.skipped is None
    assert run.problems == [], run


def test_the_table_counts_each_problem_once_per_run():
    runs = [
        sweep_inputs.Run("a", "g", "fit", "bad", 2, 1.0, None, [], []),
        sweep_inputs.Run("b", "g", "fit", "bad", 0, 1.0, None, [], ["accepted", "touched"]),
        sweep_inputs.Run("c", "h", "fit", "bad", None, 0.0, None, [], [], skipped="no root"),
    ]
    rows = {line.split()[0]: line.split()[1:] for line in sweep_inputs.table(runs).splitlines()}
    head = ["runs", *sweep_inputs.PROBLEMS, "clean", "skipped"]
    g = dict(zip(head, map(int, rows["g"]), strict=True))
    assert g["runs"] == 2 and g["accepted"] == 1 and g["touched"] == 1 and g["clean"] == 1
    total = dict(zip(head, map(int, rows["total"]), strict=True))
    assert total["skipped"] == 1 and total["runs"] == 2
