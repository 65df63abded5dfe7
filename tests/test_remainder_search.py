"""describe_remainder as a whole: nothing claimed on pure noise, two causes found and ranked,
several data sets, and the JSON form."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from test_remainder_systems import FREQ, NAMES, measured, receptance, system

from bondid.data import FrfData
from bondid.diagnose.remainder import KINDS, Settings, describe_remainder

S = 2j * np.pi * FREQ
X, Y, Z = 0, 1, 2
#: tolerances (relative) of the figures in the mixed case
TAU_REL = 0.05
K_REL = 0.1


@functools.lru_cache(maxsize=1)
def model() -> np.ndarray:
    return receptance(*system())


@pytest.mark.parametrize(
    ("rel", "floor_db", "seed", "coherence"),
    [(0.01, -70.0, 11, True), (0.05, -40.0, 12, True), (0.02, -50.0, 13, False)],
)
def test_pure_noise_around_the_exact_model_gives_no_finding(rel, floor_db, seed, coherence):
    d = measured(model(), seed, rel=rel, floor_db=floor_db)
    if not coherence:  # the noise then comes from the data's own estimate
        d = FrfData(d.freq_hz, d.outputs, d.inputs, d.H)
    rem = describe_remainder(d, model())
    assert rem.findings == [], rem.sentences()
    if coherence:  # the exact noise: the whole is at its level too (the data's own estimate
        # misjudges the floor of a weak cross channel here, which no finding may take for
        # an effect)
        assert not rem.excess.above_noise
        assert rem.sentences()[0].endswith("at the noise level, nothing left to describe")


def test_two_causes_are_both_found_and_ranked():
    M, K, D = system()
    K, D = K.copy(), D.copy()
    K[X, X] += 3000.0
    D[X, X] += 8.0
    H = receptance(M, K, D)
    H[Z] *= np.exp(-S * 100e-6)
    rem = describe_remainder(measured(H, 3), model())
    kinds = [f.kind for f in rem.causes]
    assert set(kinds[:2]) == {"stiffness_offset", "delay"}, rem.sentences()
    shares = [f.share for f in rem.causes]
    assert shares == sorted(shares, reverse=True)
    assert sum(shares[:2]) > 0.9
    assert rem.explained_share > 0.9
    delay = next(f for f in rem.causes if f.kind == "delay")
    spring = next(f for f in rem.causes if f.kind == "stiffness_offset")
    assert delay.location.names == ("z",) and abs(delay.tau_s / 100e-6 - 1) < TAU_REL
    assert spring.drive == "x" and abs(spring.stiffness / 3000.0 - 1) < K_REL
    assert not rem.after.above_noise  # with both corrected, the rest is noise


def test_a_cause_is_found_jointly_over_two_data_sets():
    """Two operating points (the x mass differs between them), one lag on input z in both."""
    M, K, D = system()
    M2 = M.copy()
    M2[X, X] += 0.3
    models = [model(), receptance(M2, K, D)]
    sets = []
    for k, Hm in enumerate(models):
        H = Hm.copy()
        H[:, Z] /= 1 + S / (2 * np.pi * 600.0)
        sets.append(measured(H, 20 + k))
    rem = describe_remainder(sets, models, settings=Settings(modes=False))
    top = rem.causes[0]
    assert top.kind == "lag" and top.location.names == ("z",)
    assert abs(top.f_c_hz / 600.0 - 1) < 0.02
    assert top.share > 0.9


def test_outputs_that_are_not_drives_and_missing_channels():
    """Two accelerometer-like outputs (no collocated drive: no drive finding can be formed)
    and a channel absent from the file: a delay on one output is still found."""
    C = np.array([[1.0, 0.2, 0.0], [0.1, 0.0, 1.0]])
    Hm = np.einsum("oa,abf->obf", C, model())
    H = Hm.copy()
    H[1] *= np.exp(-S * 80e-6)
    d = measured(np.concatenate([H, H[:1]]), 5)  # (3, 3): the third row is dropped below
    d = FrfData(d.freq_hz, ("a1", "a2"), NAMES, d.H[:2], coherence=d.coherence[:2])
    d.H[0, 1] = np.nan
    d.coherence[0, 1] = np.nan
    rem = describe_remainder(d, Hm, settings=Settings(modes=False))
    top = rem.causes[0]
    assert top.kind == "delay" and top.location.names == ("a2",)
    assert abs(top.tau_s / 80e-6 - 1) < TAU_REL
    assert "a1.y" not in rem.excess.as_dict()["by_channel"]


def test_json_form_holds_the_documented_keys():
    H = model().copy()
    H[X] *= 10 ** (1.0 / 20)
    rem = describe_remainder(measured(H, 4), model(), settings=Settings(modes=False))
    out = json.loads(json.dumps(rem.as_dict(), allow_nan=False))
    assert set(out) >= {"primary", "excess", "after", "explained_share", "findings", "summary",
                        "notes"}  # fmt: skip
    assert out["primary"]["kind"] == "gain_offset"
    assert (out["primary"]["side"], out["primary"]["names"]) == ("output", ["x"])
    ex = out["excess"]
    assert set(ex) >= {"db_rms", "noise_db", "ratio", "above_noise", "by_channel", "by_output",
                       "by_input", "by_band", "where"}  # fmt: skip
    assert set(ex["by_channel"]) == {f"{o}.{i}" for o in NAMES for i in NAMES}
    assert set(ex["where"]) == {"bands", "channels"}
    for f in out["findings"]:
        assert f["kind"] in KINDS
        assert set(f) >= {"kind", "text", "share", "location", "band_hz", "advice",
                          "significance", "figures", "alternatives"}  # fmt: skip
    gain = out["findings"][0]
    assert gain["kind"] == "gain_offset" and abs(gain["figures"]["gain_db"] - 1.0) < 0.05
    assert gain["significance"]["significant"] is True
    assert out["summary"] == rem.sentences() and all(isinstance(s, str) for s in out["summary"])


def test_accelerance_data_give_the_same_remainder_as_receptance():
    from bondid.data.quantity import convert_quantity

    H = model().copy()
    H[:, Y] *= 10 ** (-0.8 / 20)  # the y drive's force constant 0.8 dB low
    d = measured(H, 6)
    acc = FrfData(d.freq_hz, d.outputs, d.inputs,
                  convert_quantity(d.H, FREQ, "receptance", "accelerance"),
                  quantity="accelerance", coherence=d.coherence)  # fmt: skip
    settings = Settings(modes=False)
    rec = describe_remainder(d, model(), settings=settings)
    acc_rem = describe_remainder(
        acc, convert_quantity(model(), FREQ, "receptance", "accelerance"), settings=settings
    )
    assert rec.causes[0].kind == acc_rem.causes[0].kind == "gain_offset"
    assert acc_rem.causes[0].location.names == ("y",) and acc_rem.causes[0].location.side == "input"
    assert abs(acc_rem.causes[0].gain_db - rec.causes[0].gain_db) < 1e-9
    assert abs(acc_rem.excess.db_rms - rec.excess.db_rms) < 1e-9
