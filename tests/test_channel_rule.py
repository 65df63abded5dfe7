"""Channels under the noise floor left out of a cost unless named: the one rule of
``bondid.fit``, ``bondid.sensitivity`` and ``bondid.diagnose``
(:func:`bondid.data.weights.informative_channels`)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from test_fit_cli import MODEL_XML, TRUTH

from bondid.cost.selection import CostOptions, informative_only
from bondid.data import FrfData, write_csv
from bondid.data.weights import MIN_CHANNEL_WEIGHT, channel_median_weights, informative_channels
from bondid.fit.cli import main
from bondid.linear import build_affine_model
from bondid.model import UrdfDocument, get_parameter, set_parameter

#: relative complex noise of every channel
REL_NOISE = 0.02
#: the swamped channel's noise: this many times its true median |H| (40 dB above it)
SWAMP = 100.0
N_FREQ = 200


def _truth() -> UrdfDocument:
    doc = UrdfDocument.from_string(MODEL_XML)
    for n, v in TRUTH.items():
        set_parameter(doc, n, v)
    return doc


def _data(op: dict[str, float], seed: int, swamped: tuple[int, int] | None = (1, 0)) -> FrfData:
    """The chain's truth at ``op`` with 2 % relative noise; the channel ``swamped`` (output,
    input) replaced by a sensor floor 40 dB above its signal (pure noise)."""
    f = np.geomspace(2.0, 300.0, N_FREQ)
    H = build_affine_model(_truth(), op).linear_model().frf(f)
    rng = np.random.default_rng(seed)
    if swamped is not None:
        level = SWAMP * np.median(np.abs(H[swamped]))
        z = rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
        H[swamped] = level * z / np.sqrt(2)
    z = rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)
    H = H * (1 + REL_NOISE * z / np.sqrt(2))
    return FrfData(f, ("a", "b"), ("a", "b"), H, operating_point=op)


def test_a_channel_of_pure_noise_is_left_out_and_the_others_kept() -> None:
    ds = [_data({}, 1), _data({"a": 0.1}, 2)]
    med = channel_median_weights(ds)
    assert list(med) == ["a.a", "a.b", "b.a", "b.b"]
    assert med["b.a"] < MIN_CHANNEL_WEIGHT
    for c in ("a.a", "a.b", "b.b"):
        assert med[c] > 0.9  # 2 % relative noise: ~34 dB SNR
    keep, left_out = informative_channels(ds)
    assert keep == ["a.a", "a.b", "b.b"] and list(left_out) == ["b.a"]
    assert math.isclose(left_out["b.a"], med["b.a"])
    # no weights, no rule; named channels are never dropped
    assert informative_channels(ds, "none") == (["a.a", "a.b", "b.a", "b.b"], {})
    named = CostOptions(channels=["b.a", "a.a"])
    assert informative_only(ds, named) == (named, {}, "")
    opts, out, note = informative_only(ds, CostOptions())
    assert list(opts.channels or ()) == keep and "b.a" in note
    # the rule applied file by file: b.a left out of each (data sets without a file name)
    assert list(out) == ["data0", "data1"] and all(list(v) == ["b.a"] for v in out.values())


def test_every_channel_under_the_floor_keeps_them_all_with_a_note() -> None:
    ds = _data({}, 3, swamped=None)
    ds = FrfData(ds.freq_hz, ds.outputs, ds.inputs, ds.H, coherence=np.full(ds.H.shape, 0.1))
    opts = CostOptions(weighting="coherence")
    got, out, note = informative_only([ds], opts)
    assert got is opts and out == {} and "all are fitted" in note


@pytest.fixture(scope="module")
def swamped_files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    d = tmp_path_factory.mktemp("swamped")
    model = d / "chain.urdf"
    model.write_text(MODEL_XML, encoding="utf-8")
    files = [write_csv(_data(op, 10 + k), d / f"pose{k}.csv")
             for k, op in enumerate(({}, {"a": 0.1}))]  # fmt: skip
    return model, files


def _fit(model: Path, files: list[Path], out: Path, *extra: str) -> dict:
    argv = ["--model", model, "--data", *files, "--out", out, "--quiet",
            "--free", "parasitic", "--prior", "0", *extra]  # fmt: skip
    assert main([str(a) for a in argv]) == 0
    return json.loads((out / "fit.json").read_text())


def test_the_fit_leaves_the_swamped_channel_out_and_says_so(swamped_files, tmp_path, capsys):
    model, files = swamped_files
    res = _fit(model, files, tmp_path / "auto")
    assert list(res["channels_left_out"]) == ["b.a"]
    assert any("b.a" in w and "--channels" in w for w in res["warnings"])
    assert set(res["db_rms"]["by_channel"]) == {"a.a", "a.b", "b.b"}
    fitted = UrdfDocument.load(tmp_path / "auto" / "fitted.urdf")
    # the known answer within the 2 % noise's reach
    assert math.isclose(get_parameter(fitted, "p.stiffness"), TRUTH["p.stiffness"], rel_tol=0.05)
    # named channels: fitted as asked, nothing left out
    named = _fit(model, files, tmp_path / "named", "--channels", "a.a,a.b,b.a,b.b")
    assert named["channels_left_out"] == {}
    assert set(named["db_rms"]["by_channel"]) == {"a.a", "a.b", "b.a", "b.b"}
    capsys.readouterr()
