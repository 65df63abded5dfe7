"""Measured-data files (CSV, UFF 58), model checks and synthetic measurement noise."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bondid.data import (
    FrfData,
    add_measurement_noise,
    check_against_model,
    default_channel_map,
    read_csv,
    read_frf,
    read_uff58,
    write_csv,
    write_frf,
    write_uff58,
)
from bondid.exceptions import ChannelError, DataError, OperatingPointError

JOINTS = ("x", "y", "z")


def _sample(quantity: str = "receptance", n_freq: int = 200, seed: int = 0) -> FrfData:
    """3x3 FRFs over 300 orders of magnitude, with a missing channel and partial coherence."""
    rng = np.random.default_rng(seed)
    f = np.geomspace(1.0, 4000.0, n_freq)
    shape = (3, 3, n_freq)
    H = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * 10.0 ** rng.uniform(
        -150, 150, shape
    )
    H.real[0, 0, 3] = -0.0  # a signed zero must survive
    H[1, 2] = np.nan  # channel y.z absent
    coh = rng.uniform(size=shape)
    coh[1, 2] = np.nan
    coh[2, 0] = np.nan  # z.x has no coherence
    op = {"x": 0.1, "y": -1.0 / 3.0, "z": 2.0e-7}
    return FrfData(f, JOINTS, JOINTS, H, quantity, op, coh)


def _same_bits(a: np.ndarray, b: np.ndarray, *, zero_sign: bool = True) -> bool:
    """Bit-identical where finite (or equal, if not ``zero_sign``), NaN at the same places."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    fa, fb = np.isfinite(a), np.isfinite(b)
    if not np.array_equal(fa, fb):
        return False
    if not zero_sign:
        return bool(np.array_equal(a[fa], b[fb]))
    return bool(np.array_equal(a[fa].view(np.uint8), b[fb].view(np.uint8)))


def _assert_same(r: FrfData, d: FrfData, *, zero_sign: bool = True) -> None:
    assert r.outputs == d.outputs and r.inputs == d.inputs
    assert r.quantity == d.quantity and r.operating_point == d.operating_point
    assert _same_bits(r.freq_hz, d.freq_hz)
    assert _same_bits(r.H, d.H, zero_sign=zero_sign)
    assert r.coherence is not None and d.coherence is not None
    assert _same_bits(r.coherence, d.coherence)


# -- round trips ------------------------------------------------------------------------
def test_csv_round_trip_is_bit_identical(tmp_path: Path) -> None:
    d = _sample("mobility")
    path = write_csv(d, tmp_path / "m.csv")
    r = read_csv(path)
    _assert_same(r, d)
    assert r.source == str(path)
    assert np.signbit(r.H.real[0, 0, 3])
    assert "y.z" not in r.channels and len(r.channels) == 8
    header = path.read_text().splitlines()[5].split(",")
    assert "y.z.re" not in header and "z.x.coh" not in header and "z.z.coh" in header


def test_csv_keeps_joint_order_and_empty_joints(tmp_path: Path) -> None:
    d = _sample()
    H = d.H.copy()
    H[0, 0] = np.nan  # first header column is then x.y: first use would give inputs (y, x, z)
    H[:, 2] = np.nan  # input z has no channel at all
    d2 = FrfData(d.freq_hz, JOINTS, JOINTS, H, d.quantity, d.operating_point, None)
    r = read_frf(write_frf(d2, tmp_path / "o.csv"))
    assert r.inputs == JOINTS and r.coherence is None
    assert _same_bits(r.H, d2.H)


def test_csv_without_order_lines_uses_first_appearance(tmp_path: Path) -> None:
    p = tmp_path / "hand.csv"
    p.write_text("# bondid-frf: 1\nfreq_hz,y.x.re,y.x.im,x.y.re,x.y.im\n1.0,1,2,3,4\n2.0,5,6,7,8\n")
    r = read_csv(p)
    assert r.outputs == ("y", "x") and r.inputs == ("x", "y")
    assert r.quantity == "receptance" and r.operating_point == {}
    assert r.channel("x.y")[1] == 7 + 8j and np.isnan(r.channel("x.x")).all()


def test_uff_round_trip_is_exact(tmp_path: Path) -> None:
    d = _sample("accelerance")
    path = write_uff58(d, tmp_path / "a.uff")
    # binary 58b keeps every bit; only pyuff's re + 1j*im reassembly drops the sign of a
    # zero real part (H.real[0, 0, 3] = -0.0 comes back as +0.0)
    _assert_same(read_uff58(path), d, zero_sign=False)
    _assert_same(read_frf(path), d, zero_sign=False)


def test_uff_records_and_ascii_precision(tmp_path: Path) -> None:
    import pyuff

    d = _sample("mobility")
    path = write_uff58(d, tmp_path / "a.unv", binary=False)
    recs = pyuff.UFF(str(path)).read_sets()
    frf = [s for s in recs if s["func_type"] == 4]
    coh = [s for s in recs if s["func_type"] == 6]
    assert len(frf) == 8 and len(coh) == 7
    assert {s["ordinate_spec_data_type"] for s in frf} == {11}  # velocity
    assert {s["orddenom_spec_data_type"] for s in frf} == {13}  # excitation force
    assert all(s["ord_data_type"] == 6 for s in frf)  # complex double
    r = read_uff58(path)
    # pyuff's ASCII layout: frequency E13.5 (6 digits), values E20.11 (12 digits)
    np.testing.assert_allclose(r.freq_hz, d.freq_hz, rtol=5.0001e-6, atol=0)
    m = np.isfinite(d.H)
    for part in (np.real, np.imag):
        err = np.abs(part(r.H[m]) - part(d.H[m]))
        assert np.all(err <= 5.0001e-12 * np.abs(part(d.H[m])))
    assert np.nanmax(np.abs(r.coherence - d.coherence)) <= 5.0001e-12


def test_uff_channel_map_nodes_directions_and_signs(tmp_path: Path) -> None:
    cmap = default_channel_map(
        ["x", "y", "z"],
        [[1, 0, 0], [0, -1, 0], [0.1, 0, 0.99]],
        ["prismatic", "prismatic", "revolute"],
    )
    assert cmap == {"x": (1, 1), "y": (2, -2), "z": (3, 6)}
    d = _sample()
    path = write_uff58(d, tmp_path / "m.uff", channel_map=cmap)
    _assert_same(read_uff58(path, channel_map=cmap), d, zero_sign=False)
    _assert_same(read_uff58(path), d, zero_sign=False)  # bondid ID lines name the channels
    r = read_uff58(path, channel_map=dict(cmap, y=(2, 2)))  # y measured the other way round
    assert np.array_equal(r.H[0, 1], -d.H[0, 1]) and np.array_equal(r.H[1, 0], -d.H[1, 0])
    assert np.array_equal(r.H[1, 1], d.H[1, 1])  # both ends flipped
    with pytest.raises(ChannelError, match=r"m\.uff: record 1: response node 1 direction 1"):
        read_uff58(path, channel_map={"y": (2, -2), "z": (3, 6)})


def test_foreign_uff_needs_a_channel_map(tmp_path: Path) -> None:
    import pyuff

    path = tmp_path / "foreign.uff"
    f = np.linspace(10.0, 100.0, 5)
    rec = {
        "type": 58, "binary": 1, "func_type": 4, "rsp_node": 7, "rsp_dir": 3, "ref_node": 7,
        "ref_dir": 3, "x": f, "data": (1 + 2j) * f, "ordinate_spec_data_type": 11,
        "orddenom_spec_data_type": 13, "abscissa_spacing": 0,
    }  # fmt: skip
    pyuff.UFF(str(path)).write_sets([rec], mode="add")
    with pytest.raises(DataError, match=r"foreign\.uff: record 1 .*channel_map"):
        read_uff58(path)
    r = read_frf(path, channel_map={"z": (7, 3)})
    assert r.quantity == "mobility" and r.channels == ["z.z"]
    assert np.array_equal(r.channel("z.z"), (1 + 2j) * f)


def _foreign_record(node: int, **fields: object) -> dict[str, object]:
    """A type-58 FRF record (mobility, 5 points) from node 1 to ``node``, as vendors write."""
    f = np.linspace(10.0, 100.0, 5)
    rec: dict[str, object] = {
        "type": 58, "binary": 1, "func_type": 4, "rsp_node": node, "rsp_dir": 1,
        "ref_node": 1, "ref_dir": 1, "x": f, "data": (1 + 2j) * f,
        "ordinate_spec_data_type": 11, "orddenom_spec_data_type": 13, "abscissa_spacing": 0,
    }  # fmt: skip
    rec.update(fields)
    return rec


def _write_foreign(path: Path, records: list[dict[str, object]]) -> Path:
    import pyuff

    pyuff.UFF(str(path)).write_sets(records, mode="add")
    return path


FOREIGN_MAP = {"a": (1, 1), "b": (2, 1)}


def test_foreign_uff_mixed_quantities_are_converted_to_the_first(tmp_path: Path) -> None:
    f = np.linspace(10.0, 100.0, 5)
    acc = _foreign_record(2, ordinate_spec_data_type=12, data=(3 - 1j) * f)  # accelerance
    path = _write_foreign(tmp_path / "mix.uff", [_foreign_record(1), acc])
    r = read_uff58(path, channel_map=FOREIGN_MAP)
    assert r.quantity == "mobility" and r.outputs == ("a", "b") and r.inputs == ("a",)
    # mobility = accelerance / (j omega)
    expected = (3 - 1j) * f / (2j * np.pi * f)
    np.testing.assert_allclose(r.channel("b.a"), expected, rtol=1e-15, atol=0)


def test_uff_nan_points_raise_or_are_dropped() -> None:
    # pyuff writes NaN as 0, so the rule is checked on arrays as read from a file
    from bondid.data.uff_format import _drop_nan_points

    f = np.linspace(10.0, 100.0, 5)
    H = np.full((2, 1, 5), np.nan + 0j)  # channel b.a absent (NaN everywhere)
    H[0, 0] = (1 + 2j) * f
    H[0, 0, 2] = np.nan
    C = np.full(H.shape, 0.5)
    with pytest.raises(DataError, match=r"m\.uff: NaN at point 3 \(55 Hz\).*--drop-nan"):
        _drop_nan_points(Path("m.uff"), f, H, C, False)
    freq, H2, C2 = _drop_nan_points(Path("m.uff"), f, H, C, True)
    keep = [0, 1, 3, 4]
    assert np.array_equal(freq, f[keep]) and np.array_equal(H2[0, 0], (1 + 2j) * f[keep])
    assert C2 is not None and C2.shape == (2, 1, 4) and np.isnan(H2[1, 0]).all()
    H[0, 0] = np.nan
    H[0, 0, 0] = 1.0
    H[1, 0, 1:] = 1.0
    with pytest.raises(DataError, match="every frequency holds a NaN"):
        _drop_nan_points(Path("m.uff"), f, H, None, True)


@pytest.mark.parametrize(
    ("second", "error", "pattern"),
    [
        ({}, ChannelError, r"record 2: channel a\.a already given by record 1"),
        ({"rsp_node": 2, "x": np.linspace(10.0, 101.0, 5)}, DataError, "record 2: frequency grid"),
        ({"rsp_node": 2, "ordinate_spec_data_type": 1}, DataError, "record 2: ordinate data"),
        (
            {"func_type": 6, "data": np.array([0.5, 0.9, 1.2, 0.3, 0.1])},
            DataError,
            r"record 2: point 3: coherence 1\.2 outside 0\.\.1",
        ),
        (
            {"rsp_node": 2, "func_type": 6, "data": np.full(5, 0.5)},
            DataError,
            r"coherence without FRF for channels b\.a",
        ),
    ],
)
def test_bad_foreign_uff_records(
    tmp_path: Path, second: dict[str, object], error: type, pattern: str
) -> None:
    path = _write_foreign(tmp_path / "bad.uff", [_foreign_record(1), _foreign_record(1, **second)])
    with pytest.raises(error, match=pattern):
        read_uff58(path, channel_map=FOREIGN_MAP)


def test_quantity_conversion_round_trip(tmp_path: Path) -> None:
    d = _sample("receptance")
    mob = d.to_quantity("mobility")
    w = 2 * np.pi * d.freq_hz[7]
    assert mob.H[0, 1, 7] == pytest.approx(1j * w * d.H[0, 1, 7], rel=1e-15)
    for name in ("mob.csv", "mob.uff"):
        r = read_frf(write_frf(mob, tmp_path / name))
        assert r.quantity == "mobility"
        back = r.to_quantity("receptance")
        m = np.isfinite(d.H)
        np.testing.assert_allclose(back.H[m], d.H[m], rtol=1e-15, atol=0)


# -- bad input --------------------------------------------------------------------------
GOOD = "# bondid-frf: 1\n# quantity: receptance\n# operating_point: x=0.0\n"
HEADER = "freq_hz,x.x.re,x.x.im,x.x.coh\n"
ROWS = "1.0,1e-6,2e-6,0.9\n2.0,3e-6,4e-6,0.8\n3.0,5e-6,6e-6,0.7\n"
BODY = HEADER + ROWS


def _rows(old: str, new: str) -> str:
    """The good file with ``old`` replaced by ``new`` in the data rows."""
    return GOOD + HEADER + ROWS.replace(old, new)


@pytest.mark.parametrize(
    ("text", "error", "pattern"),
    [
        ("", DataError, "empty file"),
        ("# quantity: receptance\n" + HEADER + ROWS, DataError, "missing '# bondid-frf: 1'"),
        (GOOD, DataError, "no header row"),
        (GOOD.replace("receptance", "compliance") + BODY, DataError, "line 2: unknown quantity"),
        (GOOD.replace("x=0.0", "x=0.0 y") + BODY, OperatingPointError, "line 3: malformed"),
        (GOOD.replace("x=0.0", "x=zero") + BODY, OperatingPointError, "line 3: .*not a number"),
        (GOOD + "f,x.x.re,x.x.im\n" + ROWS, DataError, "line 4 .*'freq_hz'"),
        (GOOD + "freq_hz,x.x.re,x.y.im\n1.0,1,2\n", DataError, "'x.x.re' has no .*'x.x.im'"),
        (GOOD + "freq_hz,x.x.mag,x.x.im\n1.0,1,2\n", DataError, "column 2 'x.x.mag'"),
        (GOOD + "freq_hz,xx.re,xx.im\n1.0,1,2\n", ChannelError, "column 2 'xx.re'.*OUT.IN"),
        (_rows("4e-6", "abc"), DataError, r"line 6 \(data row 2\), column 'x.x.im'"),
        (_rows("4e-6", "nan"), DataError, "line 6 .*column 'x.x.im': NaN"),
        (_rows("4e-6", ""), DataError, "line 6 .*column 'x.x.im': NaN"),
        (_rows(",0.8", ""), DataError, "line 6 .*3 cells"),
        (_rows("3.0,", "1.5,"), DataError, "line 7: unsorted"),
        (_rows("2.0,", "1.0,"), DataError, "line 6: duplicate"),
        # (a 0 Hz first line is an analyser's DC line: dropped, not an error)
        (_rows("1.0,", "-1.0,"), DataError, "line 5: .*not positive"),
        (_rows("0.8", "1.2"), DataError, r"line 6, column 'x\.x\.coh': coherence 1\.2 outside"),
        (GOOD + HEADER, DataError, "no data rows"),
    ],
)  # fmt: skip
def test_bad_csv_input(tmp_path: Path, text: str, error: type, pattern: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(error, match=pattern) as info:
        read_frf(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_drop_nan_drops_rows_quietly(tmp_path: Path) -> None:
    path = tmp_path / "nan.csv"
    path.write_text(_rows("4e-6", "nan"))
    r = read_csv(path, drop_nan=True)
    assert np.array_equal(r.freq_hz, [1.0, 3.0])
    assert np.array_equal(r.H[0, 0], [1e-6 + 2e-6j, 5e-6 + 6e-6j])
    assert np.array_equal(r.coherence[0, 0], [0.9, 0.7])


def test_bad_files_and_names(tmp_path: Path) -> None:
    with pytest.raises(DataError, match=r"nowhere\.csv: no such file"):
        read_frf(tmp_path / "nowhere.csv")
    with pytest.raises(DataError, match=r"nowhere\.uff: no such file"):
        read_uff58(tmp_path / "nowhere.uff")
    with pytest.raises(DataError, match=r"data\.txt: unknown data file suffix '\.txt'.*\.csv"):
        read_frf(tmp_path / "data.txt")
    empty = tmp_path / "empty.uff"
    empty.write_text("")
    with pytest.raises(DataError, match=r"empty\.uff: empty file"):
        read_frf(empty)
    d = _sample()
    bad = FrfData(d.freq_hz, ("x.1", "y", "z"), JOINTS, d.H)
    for name in ("dot.csv", "dot.uff"):
        with pytest.raises(ChannelError, match=rf"{name}: invalid joint name 'x\.1'"):
            write_frf(bad, tmp_path / name)
        assert not (tmp_path / name).exists()
    partial = d.H.copy()
    partial[0, 0, 5] = np.nan
    with pytest.raises(DataError, match=r"channel x\.x is NaN at some frequencies"):
        write_csv(FrfData(d.freq_hz, JOINTS, JOINTS, partial), tmp_path / "p.csv")


def test_check_against_model() -> None:
    d = _sample()
    d.source = "meas.csv"
    check_against_model(d, inputs=JOINTS, outputs=JOINTS, joints=(*JOINTS, "px"))
    with pytest.raises(ChannelError, match=r"meas\.csv: channel 'z\.x'.*valid outputs: x, y"):
        check_against_model(d, inputs=JOINTS, outputs=("x", "y"), joints=JOINTS)
    with pytest.raises(ChannelError, match=r"channel 'x\.y': 'y' is not a model input"):
        check_against_model(d, inputs=("x", "z"), outputs=JOINTS, joints=JOINTS)
    with pytest.raises(OperatingPointError, match=r"meas\.csv: .*joint 'z'.*valid joints: x, y"):
        check_against_model(d, inputs=JOINTS, outputs=JOINTS, joints=("x", "y"))


# -- noise ------------------------------------------------------------------------------
def _two_dof_drive_point(f: np.ndarray) -> np.ndarray:
    """Receptance H11 of a 2-DOF chain (ground-k1-m1-k2-m2): resonances and an anti-resonance."""
    w = 2 * np.pi * f
    m1, m2, k1, k2, c1, c2 = 1.0, 0.5, 1e6, 4e5, 20.0, 8.0
    z11 = k1 + k2 - w**2 * m1 + 1j * w * (c1 + c2)
    z22 = k2 - w**2 * m2 + 1j * w * c2
    z12 = -(k2 + 1j * w * c2)
    return (z22 / (z11 * z22 - z12**2))[None, None, :]


def test_noise_reproducible_and_exact_without_noise() -> None:
    f = np.geomspace(10, 1000, 400)
    H = _two_dof_drive_point(f)
    a = add_measurement_noise(H, f, rng=3)
    b = add_measurement_noise(H, f, rng=np.random.default_rng(3))
    c = add_measurement_noise(H, f, rng=4)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])
    for floor in (None, -np.inf):
        Hn, coh = add_measurement_noise(H, f, rel=0.0, floor_db=floor, rng=0)
        assert np.array_equal(Hn, H) and np.array_equal(coh, np.ones(H.shape))


def test_noise_levels_and_coherence() -> None:
    f = np.geomspace(10, 1000, 4000)
    H = _two_dof_drive_point(f)
    # relative error alone: E|H_noisy/H - 1|^2 = rel^2
    Hn, _ = add_measurement_noise(H, f, rel=0.05, floor_db=None, rng=1)
    assert np.mean(np.abs(Hn / H - 1) ** 2) == pytest.approx(0.05**2, rel=0.1)
    # floor alone: E|H_noisy - H|^2 = (peak * 10^(floor/20))^2
    Hn, coh = add_measurement_noise(H, f, rel=0.0, floor_db=-40.0, rng=2)
    sigma = np.abs(H).max() * 1e-2
    assert np.mean(np.abs(Hn - H) ** 2) == pytest.approx(sigma**2, rel=0.1)
    assert np.all((coh >= 0) & (coh <= 1))
    i_res = int(np.argmax(np.abs(H[0, 0])))
    i_anti = int(np.argmin(np.abs(H[0, 0, (f > 100) & (f < 300)]))) + int(np.argmax(f > 100))
    assert coh[0, 0, i_res] > 0.999 and coh[0, 0, i_anti] < 0.5


def test_noise_coherence_is_signal_over_signal_plus_noise() -> None:
    # known answers of gamma^2 = S / (S + rel^2 S + sigma^2), 0 where there is no power
    from bondid.data.noise import _snr_coherence

    S = np.array([1.0, 4.0, 0.0, 0.0, 1e-300])
    sigma = np.array([0.0, 1.0, 0.0, 2.0, 0.0])
    got = _snr_coherence(S, 0.1, sigma)
    expected = [1 / 1.01, 4 / (4 * 1.01 + 1), 0.0, 0.0, 1 / 1.01]
    np.testing.assert_allclose(got, expected, rtol=1e-14, atol=0)
    # with rel = 0 and no floor the coherence of any power is exactly 1
    assert np.array_equal(_snr_coherence(S[:2], 0.0, np.zeros(2)), [1.0, 1.0])


def test_noise_floor_per_output_and_absent_channels() -> None:
    f = np.geomspace(10, 1000, 50)
    H1 = _two_dof_drive_point(f)[0, 0]
    H = np.stack([np.stack([H1, 1e-4 * H1, np.full_like(H1, np.nan)])])  # (1, 3, n_freq)
    _, coh_ch = add_measurement_noise(H, f, rel=0.0, floor_db=-60.0, rng=0)
    _, coh_out = add_measurement_noise(H, f, rel=0.0, floor_db=-60.0, rng=0, floor_ref="output")
    assert np.allclose(coh_ch[0, 0], coh_ch[0, 1])  # floor relative to each channel's own peak
    assert np.max(coh_out[0, 1]) < 0.1  # weak cross-term drowned by the sensor's floor
    assert np.isnan(coh_ch[0, 2]).all() and np.isnan(coh_out[0, 2]).all()


def test_a_dc_line_is_dropped_with_a_note(tmp_path: Path) -> None:
    """An analyser's 0 Hz line (CSV row or UFF point 1, mixed quantities too) is dropped, the
    rest read as it is, and the reader says so in ``notes`` (the commands' warnings); a 0 Hz
    line anywhere else, or a negative one, is still an error."""
    from bondid.validation.data import check_values

    d = _sample(n_freq=20)
    path = write_csv(d, tmp_path / "a.csv")
    lines = path.read_text().splitlines()
    first = next(k for k, x in enumerate(lines) if x[:1].isdigit())
    cells = lines[first].split(",")
    lines.insert(first, ",".join(["0.0", *cells[1:]]))
    (tmp_path / "dc.csv").write_text("\n".join(lines) + "\n")
    r = read_csv(tmp_path / "dc.csv")
    assert np.array_equal(r.freq_hz, d.freq_hz) and _same_bits(r.H, d.H)
    assert len(r.notes) == 1 and "dc.csv: line" in r.notes[0] and "0 Hz (DC)" in r.notes[0]
    sane = FrfData(r.freq_hz, ("x",), ("x",), np.ones((1, 1, r.freq_hz.size)), notes=r.notes)
    assert r.notes[0] in check_values(sane)
    assert read_csv(path).notes == ()
    lines.insert(first + 3, ",".join(["0.0", *cells[1:]]))
    (tmp_path / "dc2.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"not positive|strictly increasing"):
        read_csv(tmp_path / "dc2.csv")
    f = np.r_[0.0, np.linspace(10.0, 100.0, 5)]
    acc = _foreign_record(2, ordinate_spec_data_type=12, x=f, data=(3 - 1j) * (f + 1))
    mob = _foreign_record(1, x=f, data=(1 + 2j) * (f + 1))
    u = read_uff58(_write_foreign(tmp_path / "dc.uff", [mob, acc]), channel_map=FOREIGN_MAP)
    assert np.array_equal(u.freq_hz, f[1:]) and len(u.notes) == 1
    np.testing.assert_allclose(u.channel("a.a"), (1 + 2j) * (f[1:] + 1), rtol=1e-15)
    np.testing.assert_allclose(
        u.channel("b.a"), (3 - 1j) * (f[1:] + 1) / (2j * np.pi * f[1:]), rtol=1e-15
    )
