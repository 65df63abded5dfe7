"""The example-robot-data recipe (examples/robot_recipe): a stock UR5 has no joint springs,
the recipe's has its modes, and its FRF equals python-control's of the same M, D, K."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

RECIPE = Path(__file__).resolve().parents[1] / "examples" / "robot_recipe" / "robot_recipe.py"


def _recipe():
    spec = importlib.util.spec_from_file_location("robot_recipe", RECIPE)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["robot_recipe"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_ur5_recipe_modes_and_frf_against_python_control(tmp_path: Path, capsys):
    control = pytest.importorskip("control")
    rr = _recipe()
    f = np.geomspace(2.0, 400.0, 60)
    r = rr.run("ur5", stiffness=2e4, damping=5.0, freq_hz=f)
    # as shipped: six rigid-body DOFs at 0 Hz and gravity's negative stiffness
    assert sum(m.kind == "rigid" for m in r.stock_modes.modes) == 6
    assert any("unstable" in w for w in r.stock_warnings)
    # with springs: six vibration modes, none at 0 Hz, stable
    vib = r.modes.vibration_modes()
    assert len(vib) == 6 and all(m.f_hz > 1.0 for m in vib) and r.warnings == []
    # the FRF against a state-space model of the same matrices (python-control)
    from bondid.linear import build_affine_model

    lm = build_affine_model(r.doc, r.pose).linear_model()
    n = lm.M.shape[0]
    Minv = np.linalg.inv(lm.M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ lm.K, -Minv @ lm.D]])
    B = np.vstack([np.zeros_like(lm.B), Minv @ lm.B])
    C = np.hstack([lm.C, np.zeros_like(lm.C)])
    sys_ss = control.ss(A, B, C, np.zeros((C.shape[0], B.shape[1])))
    H_ref = sys_ss(2j * np.pi * f)
    err = np.abs(r.frf.H - H_ref).max() / np.abs(H_ref).max()
    assert err < 1e-9
    # the mode frequencies are where the undamped problem K φ = ω² M φ puts them (5 % with
    # this light damping)
    import scipy.linalg as sl

    f_undamped = np.sqrt(np.clip(sl.eigh(lm.K, lm.M, eigvals_only=True), 0, None)) / (2 * np.pi)
    assert np.allclose(sorted(m.f_hz for m in vib), f_undamped, rtol=0.05)
    # the script end to end: the files a user gets
    argv = ["ur5", "--out", str(tmp_path), "--points", "20", "--no-plot"]
    assert rr.main([*argv, "--q", "shoulder_lift_joint=-1.2"]) == 0
    out = capsys.readouterr().out
    assert "ur5 as shipped: 4 modes at 0 Hz" in out and "unstable" in out  # gravity: 2 unstable
    from bondid.data import read_frf

    back = read_frf(tmp_path / "frf.csv")
    assert back.operating_point == {"shoulder_lift_joint": -1.2} and back.H.shape == (6, 6, 20)
    assert (tmp_path / "ur5.urdf").is_file()
