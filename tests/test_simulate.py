"""Synthetic measurements: `python -m bondid.simulate` and the bundled data."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from bondid.data import read_frf
from bondid.linear import linearise
from bondid.model import UrdfDocument
from bondid.simulate import log_grid, main, simulate

ROOT = Path(__file__).resolve().parents[1]
BONDER = ROOT / "urdf" / "bonder.urdf"


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def test_noise_free_simulation_is_the_model_frf(tmp_path):
    out = tmp_path / "exact.csv"
    before = _sha(BONDER)
    assert (
        main(
            [
                "--model",
                str(BONDER),
                "--out",
                str(out),
                "--noise",
                "0",
                "--freq",
                "1:4000:300",
                "--q",
                "x=0.02",
                "y=-0.01",
            ]
        )
        == 0
    )
    assert _sha(BONDER) == before
    data = read_frf(out)
    lm = linearise(UrdfDocument.load(BONDER), {"x": 0.02, "y": -0.01})
    np.testing.assert_array_equal(data.H, lm.frf(log_grid(1, 4000, 300)))  # full precision
    assert data.operating_point == {"x": 0.02, "y": -0.01}
    assert data.channels == [f"{o}.{i}" for o in "xyz" for i in "xyz"]


def test_noise_is_reproducible_by_seed_and_realistic():
    doc = UrdfDocument.load(BONDER)
    f = log_grid(1, 4000, 800)
    a = simulate(doc, {}, f, noise=0.02, seed=7)
    b = simulate(doc, {}, f, noise=0.02, seed=7)
    c = simulate(doc, {}, f, noise=0.02, seed=8)
    exact = simulate(doc, {}, f, noise=0.0)
    np.testing.assert_array_equal(a.H, b.H)
    assert not np.array_equal(a.H, c.H)
    rel = np.abs(a.H - exact.H) / np.abs(exact.H)
    diag = [0, 1, 2]
    # drive points: a few % error away from anti-resonances; weak cross-terms: much noisier
    assert np.median(rel[diag, diag]) < 0.05
    assert np.median(rel[2, 0]) > 3 * np.median(rel[diag, diag])
    assert np.all((a.coherence >= 0) & (a.coherence <= 1))
    assert np.median(a.coherence[2, 0]) < np.median(a.coherence[0, 0])


def test_uff_output_and_bad_input(tmp_path, capsys):
    out = tmp_path / "m.uff"
    assert main(["--model", str(BONDER), "--out", str(out), "--freq", "10:100:20"]) == 0
    assert read_frf(out).H.shape == (3, 3, 20)
    assert main(["--model", str(BONDER), "--out", str(tmp_path / "x.csv"), "--q", "w=1"]) == 2
    assert "'w'" in capsys.readouterr().err
    assert main(["--model", str(tmp_path / "none.urdf"), "--out", str(tmp_path / "x.csv")]) == 2
    with pytest.raises(SystemExit) as exc:
        main(["--model", str(BONDER), "--out", str(tmp_path / "x.csv"), "--freq", "5:1:3"])
    assert exc.value.code == 2
    assert main(["--model", str(BONDER), "--out", str(BONDER)]) == 2  # never overwrite input


def test_bundled_data_match_their_truth_model():
    """data/ was made by tools/make_bundled_data.py from data/truth/bonder_truth.urdf."""
    truth = UrdfDocument.load(ROOT / "data" / "truth" / "bonder_truth.urdf")
    for name in ("bonder_q0.csv", "bonder_q1.csv"):
        data = read_frf(ROOT / "data" / name)
        H = linearise(truth, data.operating_point).frf(data.freq_hz)
        rel = np.abs(data.H - H) / np.abs(H)
        assert data.freq_hz.size == 2000 and data.coherence is not None
        assert np.median(rel[[0, 1, 2], [0, 1, 2]]) < 0.05


def test_bonder_frf_matches_python_control():
    import control

    lm = linearise(UrdfDocument.load(BONDER), {"x": 0.05, "y": -0.03, "z": 0.1})
    f = log_grid(1, 4000, 2000)
    H = lm.frf(f)
    A, B, C, D = lm.state_space()
    ref = np.asarray(control.ss(A, B, C, D).frequency_response(2 * np.pi * f).complex)
    ref = ref.reshape(H.shape)
    err = np.linalg.norm(H - ref, axis=(0, 1)) / np.linalg.norm(ref, axis=(0, 1))
    assert err.max() < 1e-9
