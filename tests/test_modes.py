"""Modal analysis: closed forms, the bonder's README table, peers, modes.json and the CLI."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from models import one_mass, two_mass_chain

from bondid.linear import build_affine_model
from bondid.model import UrdfDocument
from bondid.modes import modal_analysis
from bondid.modes.__main__ import main as modes_main

BONDER = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"

# README table of urdf/bonder.urdf at q = 0: (f [Hz], zeta, main joint), vibration modes
BONDER_TABLE = [
    (12.50, 0.084, "z"),
    (416.2, 0.010, "y_guide_rz"),
    (558.2, 0.018, "y_guide_rx"),
    (591.4, 0.015, "x_guide_ry"),
    (712.6, 0.012, "z_bearing_rz"),
    (852.2, 0.021, "x_guide_ty"),
    (899.6, 0.023, "x_guide_ty"),
    (1655.0, 0.042, "y_guide_tx"),
    (2066.4, 0.016, "z_bearing_ry"),
]


@pytest.fixture(scope="module")
def bonder():
    doc = UrdfDocument.load(BONDER)
    lm = build_affine_model(doc, {}).linear_model()
    return lm, modal_analysis(lm, {})


def _run(argv):
    try:
        return modes_main([str(a) for a in argv])
    except SystemExit as exc:  # argparse errors
        return exc.code


def test_one_mass_closed_form():
    m, k, d = 2.0, 8.0e3, 4.0
    lm = build_affine_model(one_mass(m, k, d), {}).linear_model()
    res = modal_analysis(lm)
    assert len(res.modes) == 1
    mode = res.modes[0]
    wn, zeta = math.sqrt(k / m), d / (2 * math.sqrt(k * m))
    assert mode.kind == "vibration"
    assert mode.f_hz == pytest.approx(wn / (2 * math.pi), rel=1e-12)
    assert mode.zeta == pytest.approx(zeta, rel=1e-10)
    assert mode.shape == pytest.approx(np.array([1.0]))
    # one mode: its participation is the receptance at the damped frequency, exactly
    wd = wn * math.sqrt(1 - zeta**2)
    h = 1.0 / abs(k - m * wd**2 + 1j * wd * d)
    assert mode.participation[0, 0] == pytest.approx(h, rel=1e-9)
    assert mode.dominance[0, 0] == pytest.approx(1.0, rel=1e-9)


def test_two_mass_chain_matches_quadratic_eigenproblem():
    import scipy.linalg as sl

    lm = build_affine_model(two_mass_chain(1.0, 0.5, 4e4, 3.0, 1e4, 8.0), {}).linear_model()
    res = modal_analysis(lm)
    n = lm.nv
    # peer: generalised eigenproblem of the quadratic (K + sD + s²M) φ = 0, no M⁻¹
    Aq = np.block([[np.zeros((n, n)), np.eye(n)], [-lm.K, -lm.D]])
    Bq = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), lm.M]])
    lam = sl.eigvals(Aq, Bq)
    lam = np.sort(lam[lam.imag > 0].imag)
    ours = np.sort([m.eigenvalue.imag for m in res.modes])
    assert ours == pytest.approx(lam, rel=1e-10)
    for mode in res.modes:  # each shape solves the quadratic eigenproblem
        s = mode.eigenvalue
        r = (lm.K + s * lm.D + s**2 * lm.M) @ mode.shape
        assert np.linalg.norm(r) < 1e-9 * np.linalg.norm(lm.K) * np.linalg.norm(mode.shape)
        assert np.max(np.abs(mode.shape)) == pytest.approx(1.0)


def test_rigid_modes_listed_at_zero():
    # no spring to ground: one rigid-body mode (λ = 0) and a real velocity-decay mode
    lm = build_affine_model(two_mass_chain(1.0, 0.5, 0.0, 3.0, 1e4, 8.0), {}).linear_model()
    res = modal_analysis(lm)
    kinds = [m.kind for m in res.modes]
    assert kinds == ["rigid", "real", "vibration"]
    rigid = res.modes[0]
    assert rigid.f_hz == 0.0 and rigid.zeta is None
    assert np.all(np.isnan(rigid.participation))
    # rigid shape: both bodies move together (joint a moves, joint b does not stretch)
    assert abs(rigid.shape[0]) == pytest.approx(1.0) and abs(rigid.shape[1]) < 1e-9
    assert res.modes[1].zeta == pytest.approx(1.0)
    # free body without damping either: a defective double zero must not break anything
    lm0 = build_affine_model(two_mass_chain(1.0, 0.5, 0.0, 0.0, 1e4, 8.0), {}).linear_model()
    res0 = modal_analysis(lm0)
    assert [m.f_hz for m in res0.modes[:2]] == [0.0, 0.0]
    assert res0.modes[2].kind == "vibration"


def test_bonder_reproduces_readme_table(bonder):
    _lm, res = bonder
    assert [m.kind for m in res.modes[:4]] == ["rigid", "rigid", "real", "real"]
    assert {res.modes[0].dominant_dof, res.modes[1].dominant_dof} == {"x", "y"}
    assert res.modes[2].f_hz == pytest.approx(0.06, abs=0.005)
    assert res.modes[3].f_hz == pytest.approx(0.16, abs=0.005)
    vib = res.vibration_modes()
    assert len(vib) == len(BONDER_TABLE)
    for mode, (f, zeta, joint) in zip(vib, BONDER_TABLE, strict=True):
        assert mode.f_hz == pytest.approx(f, abs=0.06)
        assert mode.zeta == pytest.approx(zeta, abs=0.0006)
        assert mode.dominant_dof == joint
    f = [m.f_hz for m in res.modes]
    assert f == sorted(f)


def test_bonder_poles_match_python_control(bonder):
    control = pytest.importorskip("control")
    lm, res = bonder
    sys_ = control.ss(*lm.state_space())
    poles = np.asarray(sys_.poles())
    ours = []
    for m in res.modes:
        ours.append(m.eigenvalue)
        if m.kind == "vibration":
            ours.append(np.conj(m.eigenvalue))
    ours_sorted = np.array(sorted(ours, key=lambda z: (round(z.real, 3), z.imag)))
    ref_sorted = np.array(sorted(poles, key=lambda z: (round(z.real, 3), z.imag)))
    assert len(ours) == lm.nv * 2
    assert np.max(np.abs(ours_sorted - ref_sorted)) < 1e-6 * np.max(np.abs(poles))


def test_bonder_modal_expansion_rebuilds_the_frf(bonder):
    lm, res = bonder
    freq = np.geomspace(1.0, 4000.0, 300)
    H = lm.frf(freq)
    Hm = res.frf(freq)
    # scale of channel i.j: sqrt(|H_ii H_jj|) (cross-terms are tiny sums of large terms)
    d = np.abs(np.einsum("iif->if", H))
    scale = np.sqrt(d[:, None, :] * d[None, :, :])
    assert np.max(np.abs(Hm - H) / scale) < 1e-8
    assert np.max(np.abs(np.einsum("iif->if", Hm - H)) / d) < 1e-10
    # the frequency-response peaks sit at the modes: |H(z.z)| peaks at the 12.5 Hz mode
    f = np.linspace(10.0, 15.0, 2001)
    hz = np.abs(lm.frf(f)[2, 2])
    z_mode = res.vibration_modes()[0]
    wd = z_mode.eigenvalue.imag / (2 * math.pi)
    assert abs(f[np.argmax(hz)] - wd) < 0.2


def test_modes_json_schema_and_exit_codes(tmp_path):
    out = tmp_path / "res"
    code = _run(["--model", BONDER, "--q", "x=0.01", "y=0", "--out", out, "--no-html", "--quiet"])
    assert code == 0
    data = json.loads((out / "modes.json").read_text())
    assert data["operating_point"] == {"x": 0.01, "y": 0.0}
    assert len(data["dofs"]) == 11 and data["outputs"] == ["x", "y", "z"]
    modes = data["modes"]
    assert [m["f_hz"] for m in modes] == sorted(m["f_hz"] for m in modes)
    assert modes[0]["f_hz"] == 0 and modes[0]["zeta"] is None
    for m in modes:
        assert set(m) >= {"f_hz", "zeta", "shape", "participation", "kind", "dominant_dof"}
        assert len(m["shape"]["re"]) == len(m["shape"]["im"]) == 11
        assert len(m["participation"]) == 9
    assert not (out / "modes.html").exists()
    # bad input: one line, exit 2
    assert _run(["--model", tmp_path / "missing.urdf", "--no-html"]) == 2
    assert _run(["--model", BONDER, "--q", "x0.01"]) == 2
    assert _run(["--model", BONDER, "--q", "nosuch=1"]) == 2
    assert _run(["--model", BONDER, "--mode", "99"]) == 2
    assert _run(["--model", BONDER, "--amplitude", "-1"]) == 2
    assert _run([]) == 2


def test_mode_html_is_offline_and_server_stops(tmp_path, capsys):
    from bondid.modes.viewer import build_mode_scene

    out = tmp_path / "res"
    code = _run(["--model", BONDER, "--out", out, "--quiet", "--mode", "7", "--fitted", BONDER])
    assert code == 0
    page = (out / "modes.html").read_text()
    assert "MeshCat.Viewer" in page and "mode 7" in page
    assert "<script src" not in page and "<link" not in page
    data = json.loads((out / "modes.json").read_text())
    assert data["modes"][6]["html"] == "modes.html"
    assert data["fitted"]["modes"][6]["f_hz"] == pytest.approx(data["modes"][6]["f_hz"])
    assert "12.503" in capsys.readouterr().out

    doc = UrdfDocument.load(BONDER)
    lm = build_affine_model(doc, {}).linear_model()
    res = modal_analysis(lm)
    scene = build_mode_scene(doc, res.q0, res.mode(5), res.dofs)
    pid = scene.server_pid
    assert pid is not None and scene.url.startswith("http://127.0.0.1")
    scene.close()
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)


def test_bands_from_features_merge_bands_with_too_few_points():
    """Known answer: a log grid of 40 points 1–1000 Hz (ratio 1.19 between points), two
    close resonances and a lone anti-resonance: the bands tile the range, and with
    ``min_points`` every band holds at least that many frequencies."""
    from bondid.modes.bands import Feature, automatic_bands, merge_spans

    f = np.geomspace(1.0, 1000.0, 40)
    feats = [Feature(100.0, 0.01, "resonance"), Feature(104.0, 0.01, "resonance"),
             Feature(300.0, 0.01, "anti-resonance", "x.x")]  # fmt: skip
    plain = automatic_bands(feats, f)
    assert [b.cls for b in plain] == ["below", "resonance", "between", "resonance", "above"]
    assert plain[1].features == feats[:2]  # the two close resonances share one window
    for few in (3, 6):
        bands = automatic_bands(feats, f, min_points=few)
        assert all(int(b.contains(f).sum()) >= few for b in bands)
        assert bands[0].f_lo_hz == 1.0 and bands[-1].f_hi_hz == 1000.0
        spans = [(b.f_lo_hz, b.f_hi_hz) for b in bands]
        assert merge_spans(spans) == [(1.0, 1000.0)]  # contiguous: they tile the range
        assert sum(len(b.features) for b in bands) == 3
    assert len(automatic_bands(feats, f, min_points=6)) < len(plain)
