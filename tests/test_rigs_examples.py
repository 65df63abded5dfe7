"""The worked examples on rigs (examples/): each generator runs on a small version and its
physics has a known answer; the check script runs on a quick fit of one of them."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from bondid.data.io import read_frf
from bondid.model import UrdfDocument

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
#: the generators' beam and plate against the handbook formula of their first mode (the
#: plate's Ritz model and the accelerometer's mass move it by less than this)
HANDBOOK_RTOL = 0.03


def _module(path: Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_free_free_beam_generator(tmp_path):
    beam = _module(EXAMPLES / "free_free_beam" / "make_beam.py")
    assert beam.main([str(tmp_path), "--lines", "2001", "--f-max", "500",
                      "--model", str(tmp_path / "chain.urdf")]) == 0  # fmt: skip
    truth = json.loads((tmp_path / "truth_modes.json").read_text())
    # Euler–Bernoulli free–free bar: f1 = (4.7300)² / (2π L²) √(EI / ρA)
    EI = beam.E_TRUE * beam.WIDTH * beam.THICK**3 / 12
    rhoA = beam.RHO_TRUE * beam.WIDTH * beam.THICK
    f1 = 4.730040745**2 / (2 * math.pi * beam.LENGTH**2) * math.sqrt(EI / rhoA)
    assert truth["bending_modes_hz"][0] == pytest.approx(f1, rel=HANDBOOK_RTOL)
    dense, thin = read_frf(tmp_path / "hammer_dense.csv"), read_frf(tmp_path / "hammer_thinned.csv")
    assert dense.freq_hz.size == 2000 and dense.notes  # the 0 Hz line dropped, with a note
    assert thin.freq_hz.size < dense.freq_hz.size / 4
    assert dense.outputs == ("acc",) and dense.inputs == tuple(f"h{k}" for k in range(9))
    doc = UrdfDocument.load(tmp_path / "chain.urdf")
    assert [p.name for p in doc.points][:9] == [f"h{k}" for k in range(9)]


def test_cantilever_plate_generator(tmp_path):
    plate = _module(EXAMPLES / "cantilever_plate" / "make_plate.py")
    assert plate.main([str(tmp_path), "--lines", "201",
                       "--model", str(tmp_path / "plate.urdf")]) == 0  # fmt: skip
    truth = json.loads((tmp_path / "truth_modes.json").read_text())
    D = plate.E * plate.H**3 / (12 * (1 - plate.NU**2))
    f1 = 1.875104069**2 / (2 * math.pi * plate.L**2) * math.sqrt(D / (plate.RHO * plate.H))
    assert truth["plate_modes_hz"][0] == pytest.approx(f1, rel=HANDBOOK_RTOL)
    data = read_frf(tmp_path / "plate.csv")
    assert data.H.shape == (2, 2, 201) and data.quantity == "accelerance"
    # the amplifier's lag: with it the phase of the driving channels falls by ~60° at 20 Hz
    assert math.degrees(math.atan(20.0 / plate.LAG_HZ)) == pytest.approx(60.0, abs=1.0)
    UrdfDocument.load(tmp_path / "plate.urdf")


def test_storey_frame_generator_writes_a_vendor_file_the_map_reads(tmp_path):
    frame = _module(EXAMPLES / "storey_frame" / "make_frame.py")
    assert frame.main([str(tmp_path), "--lines", "121",
                       "--model", str(tmp_path / "frame.urdf")]) == 0  # fmt: skip
    from bondid.fit.study import load_study

    cmap = load_study(EXAMPLES / "storey_frame" / "study.toml").uff_map
    data = read_frf(tmp_path / "frame.uff", channel_map=cmap)
    assert set(data.outputs) == set(frame.NODES) and set(data.inputs) == set(frame.REFERENCES)
    # the driving points: accelerometer and hammer on one node and direction
    assert np.isfinite(data.H[data.outputs.index("a3x"), data.inputs.index("h3x")]).all()
    truth = json.loads((tmp_path / "truth_modes.json").read_text())
    assert len(truth["modes_hz"]) == 6


def test_rig_check_runs_on_a_quick_fit(tmp_path):
    """One parameter of the small plate's fit, then the check's figures."""
    from bondid.fit.cli import main

    plate = _module(EXAMPLES / "cantilever_plate" / "make_plate.py")
    plate.main([str(tmp_path / "data"), "--lines", "201",
                "--model", str(tmp_path / "plate_chain.urdf")])  # fmt: skip
    study = (EXAMPLES / "cantilever_plate" / "study.toml").read_text()
    (tmp_path / "study.toml").write_text(study)
    out = tmp_path / "out"
    args = ["--study", str(tmp_path / "study.toml"), "--free", "b0.stiffness",
            "--fallback", "0", "--presolve", "0", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    check = _module(EXAMPLES / "rig_check.py")
    assert check.main([str(out), "--truth", str(tmp_path / "data" / "truth_modes.json")]) == 0
    got = json.loads((out / "check.json").read_text())
    assert got["success"] and got["noise_level"] > 0 and (out / "resonances.png").is_file()
    assert len(got["truth_modes"]) == 6  # the plate's five modes in the band and the fixture
    assert got["data_resonances"] and got["model_modes_hz"]


#: the 16-segment chain's nominal bending modes against the generator's finite-element bar:
#: the handbook modulus (70 against 68.9 GPa) alone puts them 0.8 % high
FINER_CHAIN_RTOL = 0.015


def test_a_finer_beam_chain_keeps_the_points_and_resolves_the_sixth_mode(tmp_path):
    import pinocchio as pin

    from bondid.modes.__main__ import main as modes_main

    beam = _module(EXAMPLES / "free_free_beam" / "make_beam.py")
    with pytest.raises(ValueError, match="multiple of 8"):
        beam.chain_urdf(12)
    xs = {}
    for n in (8, 16):
        path = tmp_path / f"chain{n}.urdf"
        path.write_text(beam.chain_urdf(n))
        model = pin.buildModelFromUrdf(str(path))
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        xs[n] = [data.oMf[model.getFrameId(f"p{k}")].translation[0] for k in range(9)]
        assert modes_main(["--model", str(path), "--floating-base", "--out",
                           str(tmp_path / f"m{n}"), "--quiet", "--no-html"]) == 0  # fmt: skip
    # every hammer point at x = k L / 8 in both chains
    np.testing.assert_allclose(xs[16], np.arange(9) * beam.LENGTH / 8, atol=1e-12)
    np.testing.assert_allclose(xs[8], xs[16], atol=1e-12)
    truth = np.array(beam.truth_modes_hz(1000.0))
    for n, expect_within in ((8, False), (16, True)):
        modes = json.loads((tmp_path / f"m{n}" / "modes.json").read_text())["modes"]
        f = np.array([m["f_hz"] for m in modes if m["f_hz"] > 10.0][: truth.size])
        within = bool(np.all(np.abs(f / truth - 1.0) < FINER_CHAIN_RTOL))
        assert within is expect_within, (n, f / truth - 1.0)
