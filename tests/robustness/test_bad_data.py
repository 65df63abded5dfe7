"""Data that cannot be a measurement of the model: exit 2 naming file, row and column in fit,
sensitivity and diagnose (issue 16, point 3); suspicious data warn; NaN rows can be dropped."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from .conftest import fast_args, one_line_reason


def _edit_csv(src: Path, dst: Path, edits: dict[tuple[int, str], str], scale=None) -> Path:
    """Copy a bondid CSV, replacing cells ``(data row 1-based, column) → text``; ``scale``
    ``(column prefix, factor)`` multiplies whole columns."""
    lines = src.read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    cols = lines[head].split(",")
    for k in range(head + 1, len(lines)):
        cells = lines[k].split(",")
        row = k - head
        if scale is not None:
            for j, c in enumerate(cols):
                if c.startswith(scale[0]) and not c.endswith(".coh"):
                    cells[j] = repr(float(cells[j]) * scale[1])
        for (r, c), text in edits.items():
            if r == row:
                cells[cols.index(c)] = text
        lines[k] = ",".join(cells)
    dst.write_text("\n".join(lines) + "\n")
    return dst


def _one_row(src: Path, dst: Path) -> Path:
    lines = src.read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    dst.write_text("\n".join(lines[: head + 2]) + "\n")
    return dst


# case → (builder(d0, tmp) → list of data files, words the reason must hold)
CASES = {
    "cell_1e300": (
        lambda d, t: [_edit_csv(d, t / "a.csv", {(10, "x.y.re"): "1e300"})],
        ("a.csv", "data row 10", "x.y"),
    ),
    "point_1e-300": (
        lambda d, t: [_edit_csv(d, t / "b.csv", {(7, "y.y.re"): "1e-300", (7, "y.y.im"): "0"})],
        ("b.csv", "data row 7", "y.y"),
    ),
    "channel_x1e300": (
        lambda d, t: [_edit_csv(d, t / "c.csv", {}, scale=("x.x.", 1e300))],
        ("c.csv", "x.x", "decades above the model"),
    ),
    "exact_zero": (
        lambda d, t: [_edit_csv(d, t / "z.csv", {(3, "z.z.re"): "0", (3, "z.z.im"): "0"})],
        ("z.csv", "data row 3", "z.z", "magnitude 0"),
    ),
    "infinite": (
        lambda d, t: [_edit_csv(d, t / "i.csv", {(4, "x.x.im"): "inf"})],
        ("i.csv", "x.x.im"),
    ),
    "nan": (
        lambda d, t: [_edit_csv(d, t / "n.csv", {(5, "y.x.re"): "nan"})],
        ("n.csv", "y.x.re", "--drop-nan"),
    ),
    "single_frequency": (lambda d, t: [_one_row(d, t / "one.csv")], ("one.csv", "frequenc")),
    "same_file_twice": (lambda d, t: [d, d], ("d0.csv", "twice")),
    "same_content": (
        lambda d, t: [d, Path(shutil.copy(d, t / "copy.csv"))],
        ("copy.csv", "same content"),
    ),
}


@pytest.mark.parametrize("command", ["fit", "sensitivity", "diagnose"])
@pytest.mark.parametrize("case", list(CASES))
def test_bad_data_exit_2_naming_file_row_column(command, case, inputs, run, tmp_path):
    build, words = CASES[case]
    files = build(inputs["d0"], tmp_path)
    out = tmp_path / "out"
    code, _, err = run(command, *fast_args(command, inputs["model"], files, out))
    assert code == 2, err
    reason = one_line_reason(err)
    for w in words:
        assert w in reason, reason
    assert "np.float64" not in reason and not out.exists()


def test_drop_nan_is_an_option_of_every_data_command(inputs, run, tmp_path):
    bad = _edit_csv(inputs["d0"], tmp_path / "n.csv", {(5, "y.x.re"): "nan"})
    for command in ("fit", "sensitivity", "diagnose"):
        argv = [*fast_args(command, inputs["model"], [bad], None), "--drop-nan"]
        code, _, err = run(command, *argv)
        assert code in (0, 1) and "bad input" not in err, (command, err)


def test_a_channel_three_decades_off_is_a_warning(inputs, run, tmp_path):
    odd = _edit_csv(inputs["d0"], tmp_path / "w.csv", {}, scale=("y.y.", 1e4))
    out = tmp_path / "fit"
    code, stdout, err = run("fit", *fast_args("fit", inputs["model"], [odd], out))
    assert code in (0, 1), err
    assert "warning:" in stdout and "y.y" in stdout and "units" in stdout
    saved = json.loads((out / "fit.json").read_text())["warnings"]
    assert any("y.y" in w and "decades above" in w for w in saved)


@pytest.fixture(scope="module")
def clean_frf():
    from bondid.model.document import UrdfDocument
    from bondid.simulate import log_grid, simulate

    from .conftest import BONDER

    doc = UrdfDocument.load(BONDER)
    ds = simulate(doc, {}, log_grid(5.0, 3000.0, 30), noise=0.02, seed=3)
    ds.source = "mem.csv"
    return doc, ds


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    row=st.integers(0, 29),
    cell=st.integers(0, 8),
    decades=st.floats(6.5, 290.0),
    up=st.booleans(),
    phase=st.floats(-3.0, 3.0),
)
def test_any_impossible_cell_is_named(clean_frf, row, cell, decades, up, phase):
    """A cell more than 6 decades from its channel's median is refused, wherever it is."""
    from bondid.exceptions import DataError
    from bondid.validation.data import check_values

    _, ds = clean_frf
    bad = ds.H.copy()
    a, b = divmod(cell, 3)
    median = np.median(np.abs(ds.H[a, b]))
    bad[a, b, row] = median * 10.0 ** (decades if up else -decades) * np.exp(1j * phase)
    frf = type(ds)(ds.freq_hz, ds.outputs, ds.inputs, bad, ds.quantity, {}, None, "mem.csv")
    with pytest.raises(DataError) as info:
        check_values(frf)
    msg = str(info.value)
    assert f"data row {row + 1} " in msg and f"{ds.outputs[a]}.{ds.inputs[b]}" in msg


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(scale=st.floats(-2.5, 2.5), row=st.integers(0, 29))
def test_plausible_data_passes(clean_frf, scale, row):
    from bondid.validation.data import check_data

    doc, ds = clean_frf
    H = ds.H.copy()
    H[0, 0, row] *= 10.0**scale  # an outlier within reason
    frf = type(ds)(ds.freq_hz, ds.outputs, ds.inputs, H, ds.quantity, {}, None, "mem.csv")
    warnings = check_data(doc, [frf])
    assert all("decades" not in w for w in warnings)
