"""Modal identification, mode pairing, anti-resonances and the gap figure (bondid.diagnose)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from bondid.cost import db_rms
from bondid.data import FrfData
from bondid.diagnose.gap import band_mask, gap_bands, gap_report
from bondid.modal.identify import (
    antiresonance_shifts,
    antiresonances,
    identify_modes,
    model_modes,
    pair_modes,
)
from bondid.modes.bands import Feature

ROOT = Path(__file__).resolve().parents[1]
NAMES = ("a", "b", "c")


def features(res: list[float], anti: list[float]) -> list[Feature]:
    """Undamped resonances and anti-resonances at the given frequencies [Hz]."""
    return [Feature(f, 0.0, "resonance") for f in res] + [
        Feature(f, 0.0, "anti-resonance") for f in anti
    ]


def three_dof() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M, K, D of a 3-DOF chain with non-proportional damping (modes 29, 64, 91 Hz)."""
    M = np.diag([1.0, 2.0, 1.5])
    K = np.array([[3e5, -1e5, 0.0], [-1e5, 2.5e5, -1.2e5], [0.0, -1.2e5, 1.5e5]])
    D = 1e-4 * K + 2.0 * M
    D[0, 0] += 3.0
    return M, K, D


def receptance(M: np.ndarray, K: np.ndarray, D: np.ndarray, f: np.ndarray) -> np.ndarray:
    w = 2 * np.pi * f
    Z = K[None] - (w**2)[:, None, None] * M[None] + 1j * w[:, None, None] * D[None]
    return np.moveaxis(np.linalg.inv(Z), 0, 2)


def true_poles(M: np.ndarray, K: np.ndarray, D: np.ndarray) -> np.ndarray:
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    return lam[np.argsort(np.abs(lam))]


def noisy(H: np.ndarray, rel: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    e = rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)
    return H * (1.0 + rel * e / np.sqrt(2.0))


@pytest.fixture(scope="module")
def synthetic() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    M, K, D = three_dof()
    f = np.geomspace(5.0, 400.0, 600)
    return f, receptance(M, K, D, f), true_poles(M, K, D)


def _check(modes, lam, f_tol: float, z_tol: float) -> None:
    assert len(modes) == lam.size
    for m, lr in zip(modes, lam, strict=True):
        fn, zeta = abs(lr) / (2 * np.pi), -lr.real / abs(lr)
        assert m.f_hz == pytest.approx(fn, rel=f_tol)
        assert m.zeta == pytest.approx(zeta, rel=z_tol)


def test_synthetic_noise_free_exact(synthetic) -> None:
    f, H, lam = synthetic
    modes = identify_modes(FrfData(f, NAMES, NAMES, H))
    _check(modes, lam, 1e-3, 1e-2)
    # residues: the modal expansion rebuilds the FRF near each resonance
    for m, lr in zip(modes, lam, strict=True):
        s = 1j * lr.imag
        M, K, D = three_dof()
        Z = K - (s.imag**2) * M + s * D
        Hr = np.linalg.inv(Z)
        own = m.residues / (s - lr)
        assert np.linalg.norm(own) == pytest.approx(np.linalg.norm(Hr), rel=0.3)


def test_synthetic_two_percent_noise(synthetic) -> None:
    f, H, lam = synthetic
    modes = identify_modes(FrfData(f, NAMES, NAMES, noisy(H, 0.02, 3)))
    _check(modes, lam, 0.01, 0.05)


def test_drive_points_alone_give_the_modes(synthetic) -> None:
    """No output row complete (only the diagonal measured, 2 % noise): every channel is
    identified alone; the poles are the system's, the absent channels' residues NaN and
    undetermined."""
    f, H, lam = synthetic
    Hd = noisy(H, 0.02, 4)
    off = ~np.eye(3, dtype=bool)
    Hd[off] = np.nan
    modes = identify_modes(FrfData(f, NAMES, NAMES, Hd))
    _check(modes, lam, 0.01, 0.05)
    for m in modes:
        assert np.all(np.isnan(m.residues[off])) and not np.any(m.determined[off])
        assert np.all(np.isfinite(np.diag(m.residues)))


def test_cross_check_with_sdypy_ema(synthetic) -> None:
    EMA = pytest.importorskip("sdypy.EMA", reason="sdypy-EMA (peer LSCF) is not installed")
    M, K, D = three_dof()
    f_lin = np.linspace(0.0, 200.0, 1001)  # sdypy works on a linear grid from 0 Hz
    H_lin = receptance(M, K, D, np.maximum(f_lin, 1e-9))
    for rel in (0.0, 0.02):
        Hn = noisy(H_lin, rel, 5) if rel else H_lin
        ours = identify_modes(FrfData(f_lin[25:], NAMES, NAMES, Hn[:, :, 25:]))
        peer = EMA.Model(
            frf=Hn.reshape(9, -1), freq=f_lin, lower=5, upper=150, pol_order_high=12,
            frf_form="receptance",
        )  # fmt: skip
        peer.get_poles(show_progress=False)
        peer.select_closest_poles([m.f_hz for m in ours])
        tol_f, tol_z = (1e-4, 1e-3) if rel == 0 else (0.01, 0.1)
        for m, fp, zp in zip(ours, peer.nat_freq, peer.nat_xi, strict=True):
            assert m.f_hz == pytest.approx(fp, rel=tol_f)
            assert m.zeta == pytest.approx(zp, rel=tol_z)


# -- the bonder ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bonder():
    from bondid.linear import build_affine_model
    from bondid.model.document import UrdfDocument
    from bondid.simulate import simulate

    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    lm = build_affine_model(doc).linear_model()
    data = simulate(doc, noise=0.0)
    return doc, lm, data, identify_modes(data)


def test_bonder_noise_free_modes_recovered(bonder) -> None:
    _, lm, data, ident = bonder
    mm = model_modes(lm, freq_hz=data.freq_hz)
    assert len(mm) == 9  # 12.5 Hz arm mode + 8 parasitic modes
    rows = pair_modes(ident, mm, f_band=(1.0, 4000.0))
    assert [r["status"] for r in rows] == ["paired"] * 9
    for r in rows:
        assert abs(r["df_rel"]) < 1e-3
        assert r["mac"] > 0.99
        assert r["zeta_measured"] == pytest.approx(r["zeta_model"], rel=1e-2)


def test_pair_model_with_itself(bonder) -> None:
    _, lm, data, _ = bonder
    mm = model_modes(lm, freq_hz=data.freq_hz)
    rows = pair_modes(mm, mm)
    assert all(r["status"] == "paired" for r in rows) and len(rows) == len(mm)
    assert all(r["mac"] == pytest.approx(1.0, abs=1e-9) for r in rows)


def test_spurious_only_where_the_data_would_show_the_mode(bonder) -> None:
    _, lm, data, _ = bonder
    blind = FrfData(data.freq_hz, data.outputs, data.inputs, data.H, coherence=0 * data.H.real)
    clear = FrfData(data.freq_hz, data.outputs, data.inputs, data.H, coherence=1 + 0 * data.H.real)
    assert pair_modes([], model_modes(lm, data=blind)) == []  # nothing could have been seen
    rows = pair_modes([], model_modes(lm, data=clear))
    assert [r["status"] for r in rows] == ["spurious"] * 9


def test_stiffened_parasitic_joint_gives_missing_mode(bonder) -> None:
    from bondid.linear import build_affine_model

    doc, _, data, ident = bonder
    stiff = doc.copy()
    stiff.set_stiffness("z_bearing_ry", 1e9)  # its 2066 Hz mode leaves the band
    lm_stiff = build_affine_model(stiff).linear_model()
    rows = pair_modes(ident, model_modes(lm_stiff, freq_hz=data.freq_hz), f_band=(1.0, 4000.0))
    missing = [r for r in rows if r["status"] == "missing"]
    assert len(missing) == 1
    assert missing[0]["f_measured_hz"] == pytest.approx(2066.4, rel=0.01)
    assert not [r for r in rows if r["status"] == "spurious"]  # the moved mode is unobservable


@pytest.mark.parametrize("seed", [0, 1])
def test_channels_with_unequal_floors_keep_their_modes(bonder, seed: int) -> None:
    """A flat floor 40 dB below each channel's median, no coherence (the information weights
    stand in for it, as in a diagnosis): the direct channels are noise above a few hundred Hz,
    the cross channels still carry the modes. The whole matrix alone found 1 of the 9."""
    from bondid.data.weights import with_weights_as_coherence
    from bondid.simulate import simulate

    doc, lm, _, _ = bonder
    data = simulate(doc, noise=0.02, floor_db=-40.0, floor_ref="median", seed=seed,
                    coherence=False)  # fmt: skip
    ident = identify_modes(with_weights_as_coherence(data))
    rows = pair_modes(ident, model_modes(lm, freq_hz=data.freq_hz), f_band=(1.0, 4000.0))
    status = [r["status"] for r in rows]
    assert "missing" not in status  # no mode the machine does not have
    assert status.count("paired") >= 8
    # the two modes at 852 and 900 Hz may be seen as one; the others pair closely
    close = [r for r in rows if r["mac"] and r["mac"] > 0.9 and abs(r["df_rel"]) < 0.01]
    assert len(close) >= 7


def test_mac_compares_the_channels_the_data_determine(bonder) -> None:
    """A measured mode's residue entries in channels that are noise at its frequency do not
    spoil the pairing: the MAC is taken on the entries both modes determine."""
    from dataclasses import replace

    from bondid.modal.pairing import mac_matrix

    _, lm, data, _ = bonder
    mm = model_modes(lm, freq_hz=data.freq_hz)
    m = mm[-1]
    noise_at = np.zeros(m.residues.shape, bool)
    noise_at[0, 0] = noise_at[1, 1] = True  # two direct channels: noise at this mode
    junk = np.where(noise_at, 50.0 * np.abs(m.residues).max() * (1 + 1j), m.residues)
    spoiled = replace(m, residues=junk)
    assert mac_matrix([spoiled], [m])[0, 0] < 0.5
    known = replace(spoiled, determined=~noise_at)
    assert mac_matrix([known], [m])[0, 0] == pytest.approx(1.0, abs=1e-12)
    assert mac_matrix([replace(m, determined=~noise_at)], [m])[0, 0] == pytest.approx(1.0)


def test_antiresonance_of_two_mass_chain() -> None:
    # ground -k1- m1 -k2- m2, force and sensor on m1: anti-resonance at sqrt(k2/m2)/2π
    m1, m2, k1, k2 = 2.0, 0.5, 4e5, 1e5
    M, K = np.diag([m1, m2]), np.array([[k1 + k2, -k2], [-k2, k2]])
    D = 2e-5 * K
    f = np.geomspace(10.0, 500.0, 1500)
    H = receptance(M, K, D, f)
    expected = np.sqrt(k2 / m2) / (2 * np.pi)
    found = antiresonances(f, noisy(H[0, 0], 0.01, 1))
    assert len(found) == 1 and found[0] == pytest.approx(expected, rel=5e-3)
    data = FrfData(f, ("p", "q"), ("p", "q"), H)
    rows = antiresonance_shifts(data, H * (1 + 0j))
    assert [r["channel"] for r in rows] == ["p.p", "q.q"]
    assert all(r["df_rel"] == pytest.approx(0.0) for r in rows)
    assert rows[1]["f_measured_hz"] == pytest.approx(
        np.sqrt((k1 + k2) / m1) / (2 * np.pi), rel=5e-3
    )


def test_gap_report_matches_direct_db_rms(bonder) -> None:
    _, lm, data, _ = bonder
    Hm = noisy(data.H, 0.05, 2)
    meas = FrfData(data.freq_hz, data.outputs, data.inputs, Hm)
    Hs = lm.frf(data.freq_hz)
    bands = gap_bands(data.freq_hz, features([12.5, 416.0, 558.0], [300.0]))
    rep = gap_report(meas, Hs, bands)
    assert rep.db_rms == pytest.approx(db_rms(Hs, Hm), rel=1e-12)
    direct = 20 / np.log(10) * np.abs(np.log(Hm[0, 1] / Hs[0, 1]))
    assert rep.by_channel["x.y"] == pytest.approx(np.sqrt(np.mean(direct**2)), rel=1e-12)
    # bands partition the points: the pooled band figures give back the total
    n = np.array([b["n_points"] for b in rep.by_band])
    sq = np.array([b["db_rms"] ** 2 for b in rep.by_band])
    assert n.sum() == rep.n_points == 9 * data.freq_hz.size
    assert np.sqrt(np.sum(n * sq) / n.sum()) == pytest.approx(rep.db_rms, rel=1e-12)
    assert rep.residual_db.shape == (9, data.freq_hz.size)
    # two data sets pool; a perfect model gives 0
    rep2 = gap_report([meas, meas], [Hs, Hs])
    assert rep2.db_rms == pytest.approx(rep.db_rms, rel=1e-12) and len(rep2.channels) == 18
    assert gap_report(meas, Hm).db_rms == pytest.approx(0.0, abs=1e-12)


def test_gap_bands_cover_range() -> None:
    f = np.geomspace(1.0, 4000.0, 2000)
    res, anti = [12.5, 416.0, 558.0, 591.0, 2066.0, 3990.0], [300.0, 550.0]
    bands = gap_bands(f, features(res, anti))
    assert bands[0][0] == f[0] and bands[-1][1] == f[-1]
    assert all(b[1] == n[0] for b, n in itertools.pairwise(bands))
    assert all(b[0] < b[1] for b in bands)
    counts = sum(
        np.count_nonzero(band_mask(f, b, k == len(bands) - 1)) for k, b in enumerate(bands)
    )
    assert counts == f.size  # every frequency in exactly one band
    for x in [*res, *anti]:
        assert any(b[0] <= x * 0.9 and x * 1.1 <= b[1] for b in bands) or x > 3400
    assert gap_bands(f, []) == [(1.0, 4000.0)]
