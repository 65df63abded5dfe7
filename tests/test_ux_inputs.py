"""What a user types and what the files say: operating points given for files that state none,
channels chosen file by file, ``--channels`` in both spellings, headlines never nan/inf."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from test_channel_rule import _data

from bondid.cost.selection import CostOptions, informative_only, used_points
from bondid.data import FrfData, read_frf, write_csv
from bondid.data.io import states_operating_point
from bondid.exceptions import ConfigError, OperatingPointError
from bondid.fit.headline import headline_lines
from bondid.fit.options import build_parser, resolve_settings
from bondid.fit.outputs import _sq_db, _wrms, no_figure_reason
from bondid.fit.study import study_from_dict
from bondid.linear import build_affine_model
from bondid.model import UrdfDocument
from bondid.setup.operating_points import given_operating_points, parse_option
from bondid.validation.pose import pose_dependent_joints

ROOT = Path(__file__).resolve().parents[1]
BONDER = ROOT / "urdf" / "bonder.urdf"
#: where the bonder's data of these tests were "measured"
POSE = {"y": 0.1, "z": 0.05}


def test_operating_point_option_forms():
    assert parse_option("a.uff=x=0.1,y=0.3") == ("a.uff", {"x": 0.1, "y": 0.3})
    assert parse_option("a.uff=x=0.1 y=-2e-3") == ("a.uff", {"x": 0.1, "y": -0.002})
    assert parse_option("a.uff=") == ("a.uff", {})  # stated: the neutral pose
    with pytest.raises(OperatingPointError, match=r"--operating-point 'x=0\.1'"):
        parse_option("x=0.1")  # no file: "x" is taken as the file, "0.1" is no JOINT=VALUE
    with pytest.raises(ConfigError, match="FILE=JOINT=VALUE"):
        parse_option("a.uff")


def test_pose_dependence_of_the_bonder():
    """Moving y or z moves masses relative to the x guide's compliant rotations (M changes);
    x carries the whole upper machine and changes nothing the model sees."""
    doc = UrdfDocument.load(BONDER)
    joints = pose_dependent_joints(doc)
    assert joints == ["y", "z"]
    # the check's own figure: M at y = 0.01 differs from M at 0 by more than its tolerance
    m0 = build_affine_model(doc, {}).linear_model().M
    m1 = build_affine_model(doc, {"x": 0.3}).linear_model().M
    assert np.allclose(m0, m1, rtol=0, atol=1e-12 * np.abs(m0).max())


def _bonder_csv(tmp_path: Path, name: str, op: dict[str, float]) -> Path:
    """Bonder data at ``POSE`` written as CSV, then its ``# operating_point`` line removed
    (a file from a tool that does not write one)."""
    doc = UrdfDocument.load(BONDER)
    f = np.geomspace(5.0, 500.0, 40)
    H = build_affine_model(doc, POSE).linear_model().frf(f)
    path = write_csv(FrfData(f, ("x", "y", "z"), ("x", "y", "z"), H, operating_point=op),
                     tmp_path / name)  # fmt: skip
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(x for x in lines if not x.startswith("# operating_point")))
    return path


def test_a_file_without_operating_point_is_named_and_can_be_given_one(tmp_path: Path):
    doc = UrdfDocument.load(BONDER)
    path = _bonder_csv(tmp_path, "pose.csv", POSE)
    assert not states_operating_point(path)
    ds = read_frf(path)
    assert ds.operating_point == {}
    found = given_operating_points(doc, [ds], {})
    assert len(found) == 1 and str(path) in found[0] and "--operating-point" in found[0]
    assert "y, z" in found[0]
    # the command line's form gives it; no warning then, and the file keeps its data
    ds = read_frf(path)
    given = dict([parse_option(f"{path}=y=0.1,z=0.05")])
    assert given_operating_points(doc, [ds], given) == []
    assert ds.operating_point == POSE
    # a file that states its pose (even the neutral one) is not warned about
    stated = write_csv(FrfData(ds.freq_hz, ds.outputs, ds.inputs, ds.H), tmp_path / "q0.csv")
    assert states_operating_point(stated)
    assert given_operating_points(doc, [read_frf(stated)], {}) == []
    # a FILE that is none of the data files, or a joint the model lacks: bad input
    with pytest.raises(ConfigError, match="not one of the data files"):
        given_operating_points(doc, [read_frf(path)], {"other.csv": {"y": 0.1}})
    with pytest.raises(OperatingPointError, match="lacks"):
        given_operating_points(doc, [read_frf(path)], {str(path): {"nope": 0.1}})


def test_study_and_command_line_operating_points(tmp_path: Path):
    study = study_from_dict(
        {"operating_points": {"a.csv": {"y": 0.1}, "b.csv": "y=0.2 z=0.01"}}, base=tmp_path
    )
    assert study.operating_points == {
        str(tmp_path / "a.csv"): {"y": 0.1},
        str(tmp_path / "b.csv"): {"y": 0.2, "z": 0.01},
    }
    args = build_parser().parse_args(
        ["--model", "m.urdf", "--data", "a.csv", "--operating-point", "a.csv=y=0.3",
         "--channels", "x.x", "y.y", "--channels", "z.z,x.y"]
    )  # fmt: skip
    s = resolve_settings(args)
    assert s.operating_points == {"a.csv": {"y": 0.3}}
    assert s.channels == ["x.x", "y.y", "z.z", "x.y"]


def test_channels_both_spellings_in_every_command_that_takes_them():
    from bondid.fleet.cli import build_parser as fleet_parser
    from bondid.sensitivity.__main__ import _parser as sens_parser

    for parser, head in (
        (sens_parser(), ["--model", "m", "--data", "d.csv"]),
        (fleet_parser(), ["--model", "m", "--machines", "f", "--out", "o"]),
    ):
        a = parser.parse_args([*head, "--channels", "x.x", "x.y"])
        b = parser.parse_args([*head, "--channels", "x.x,x.y"])
        assert a.channels == b.channels == "x.x,x.y"


def test_a_channel_informative_at_one_pose_is_used_there():
    """b.a is pure noise at the first pose and clean at the second: left out of the first
    file only (the rule applied per file, not by name across files)."""
    noisy = _data({}, 1, swamped=(1, 0))
    clean = _data({"a": 0.1}, 2, swamped=None)
    noisy.source, clean.source = "pose0.csv", "pose1.csv"
    opts, left, note = informative_only([noisy, clean], CostOptions())
    assert left == {"pose0.csv": {"b.a": left["pose0.csv"]["b.a"]}}
    assert left["pose0.csv"]["b.a"] < 0.5 and "b.a" in note and "pose0.csv" in note
    assert used_points(noisy, opts)[1, 0].sum() == 0
    assert used_points(clean, opts)[1, 0].sum() == clean.freq_hz.size
    assert used_points(noisy, opts)[0, 0].sum() == noisy.freq_hz.size


def test_no_finite_figure_is_named_never_printed_as_nan():
    """A model FRF of exactly zero (no path from the input to the output) has no dB error:
    the point is left out of the figure, no RuntimeWarning, and the channel is named."""
    Hs = np.array([1.0 + 0j, 0.0, 2.0])
    Hm = np.array([1.1 + 0j, 0.5, 2.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        e = _sq_db(Hs, Hm)
        why = no_figure_reason(Hs, Hm)
    assert np.isnan(e[1]) and np.isfinite(e[[0, 2]]).all()
    assert "zero" in why and "1 of 3" in why
    # the weighted RMS over the finite points only: the known answer of the two left
    expected = math.sqrt((e[0] + e[2]) / 2)
    assert _wrms([e], [np.ones(3)]) == pytest.approx(expected, rel=1e-12)
    db = {"weighting": "auto", "initial": float("nan"), "final": float("inf"),
          "noise_level": 0.5, "no_figure": ["x.y in a.uff (initial model): " + why],
          "unweighted": {"initial": None, "final": 1.0}}  # fmt: skip
    text = "\n".join(headline_lines(db))
    assert "nan" not in text.lower() and "inf" not in text.lower()
    assert "no finite figure for x.y in a.uff" in text
