"""describe_remainder on synthetic data with one known cause each: the finding's kind, where
it lies and its figure, within named tolerances.

The model is the synthetic machine of test_remainder_systems (three free drives x, y, z and
modes at 150, 430 and 900 Hz); the "measured" data are its exact FRF with the cause applied,
1 % relative noise and a floor 70 dB below the response.
"""

from __future__ import annotations

import functools

import numpy as np
from test_remainder_systems import FREQ, measured, receptance, system

from bondid.diagnose.remainder import Remainder, describe_remainder

#: tolerances of the recovered figures (relative unless named in dB)
F_REL = 0.02  # a mode's frequency, a filter's corner
ZETA_REL = 0.3  # a mode's damping
TAU_REL = 0.02  # a delay
LAG_REL = 0.05  # a lag time
GAIN_DB = 0.05  # a gain offset [dB]
K_REL = 0.05  # a stiffness
MASS_REL = 0.05  # a mass
EPS_REL = 0.05  # a leakage ratio
SLOPE_ABS = 0.02  # a power-law exponent
NOTCH_DB = 1.5  # a notch's depth [dB]
#: the share of the excess the main finding must explain
MAIN_SHARE = 0.8

S = 2j * np.pi * FREQ
X, Y, Z = 0, 1, 2


@functools.lru_cache(maxsize=1)
def model() -> np.ndarray:
    return receptance(*system())


def describe(H_true: np.ndarray, seed: int = 1) -> Remainder:
    return describe_remainder(measured(H_true, seed), model())


def main(rem: Remainder):
    """The cause that explains the most (every finding is ranked by its share)."""
    causes = rem.causes
    assert causes, rem.sentences()
    top = causes[0]
    assert top.share >= MAIN_SHARE, rem.sentences()
    assert top.significance is not None and top.significance.significant
    return top


def confined_to(rem: Remainder) -> set[tuple[str, str]]:
    return {(f.location.side, f.location.names[0]) for f in rem.findings if f.kind == "confined"}


def resonance(f0: float, zeta: float, b: float = 0.0) -> np.ndarray:
    """``(1 + b s/ω₀)/(1 + 2ζ s/ω₀ + (s/ω₀)²)`` on :data:`FREQ`."""
    x = S / (2 * np.pi * f0)
    return (1 + b * x) / (1 + 2 * zeta * x + x * x)


def test_sensor_on_a_compliant_bracket_is_a_mode_seen_only_in_its_output_row():
    H = model().copy()
    H[Y] *= resonance(1100.0, 0.02, b=0.04)  # the head's absolute transmissibility
    rem = describe(H)
    top = main(rem)
    assert top.kind == "missing_mode"
    assert abs(top.f_hz / 1100.0 - 1) < F_REL
    assert abs(top.zeta / 0.02 - 1) < ZETA_REL
    assert top.seen.confined() == ("output", ["y"])
    assert set(top.seen.channels) == {"y.x", "y.y", "y.z"}
    assert top.nearest is not None and not top.nearest.paired
    assert "only in output row y (3 of 3 channels)" in top.text
    assert ("output", "y") in confined_to(rem)


def test_structural_mode_missing_in_the_model_is_seen_across_rows_and_columns():
    phi = np.array([1.0, 0.6, -0.8])
    wr, zr = 2 * np.pi * 620.0, 0.01
    w = 2 * np.pi * FREQ
    extra = np.outer(phi, phi)[:, :, None] / (10.0 * (wr**2 - w**2 + 2j * zr * wr * w))
    rem = describe(model() + extra)
    top = main(rem)
    assert top.kind == "missing_mode" and top.form == "additive"
    assert abs(top.f_hz / 620.0 - 1) < F_REL
    assert abs(top.zeta / 0.01 - 1) < ZETA_REL
    assert top.seen.confined() == ("spread", [])
    assert len(top.seen.outputs) == 3 and len(top.seen.inputs) == 3
    assert not confined_to(rem)


def test_a_model_mode_absent_in_the_data_is_spurious():
    phi = np.array([1.0, 0.6, -0.8])
    wr, zr = 2 * np.pi * 620.0, 0.01
    w = 2 * np.pi * FREQ
    extra = np.outer(phi, phi)[:, :, None] / (10.0 * (wr**2 - w**2 + 2j * zr * wr * w))
    rem = describe_remainder(measured(model(), 1), model() + extra)
    top = main(rem)
    assert top.kind == "spurious_mode"
    assert abs(top.f_hz / 620.0 - 1) < F_REL
    assert top.scale is not None and top.scale < 0.25


def test_gain_offset_of_one_output_row():
    H = model().copy()
    H[X] *= 10 ** (1.5 / 20)
    rem = describe(H)
    top = main(rem)
    assert top.kind == "gain_offset"
    assert top.location.side == "output" and top.location.names == ("x",)
    assert abs(top.gain_db - 1.5) < GAIN_DB
    assert ("output", "x") in confined_to(rem)


def test_delay_on_one_output_row():
    H = model().copy()
    H[Z] *= np.exp(-S * 100e-6)
    rem = describe(H)
    top = main(rem)
    assert top.kind == "delay"
    assert top.location.side == "output" and top.location.names == ("z",)
    assert abs(top.tau_s / 100e-6 - 1) < TAU_REL
    assert top.std_s < 0.1 * top.tau_s


def test_first_order_lag_on_one_input_column():
    H = model().copy()
    H[:, Y] /= 1 + S / (2 * np.pi * 800.0)
    rem = describe(H)
    top = main(rem)
    assert top.kind == "lag" and top.order == 1
    assert top.location.side == "input" and top.location.names == ("y",)
    assert abs(top.time_s * 2 * np.pi * 800.0 - 1) < LAG_REL
    assert ("input", "y") in confined_to(rem)


def test_second_order_amplifier_on_one_input_column():
    H = model().copy()
    H[:, X] *= resonance(1500.0, 0.5)
    rem = describe(H)
    top = main(rem)
    assert top.kind == "lag" and top.order == 2
    assert top.location.side == "input" and top.location.names == ("x",)
    assert abs(top.f_c_hz / 1500.0 - 1) < F_REL
    assert top.zeta is not None and abs(top.zeta / 0.5 - 1) < ZETA_REL


def test_sensor_misalignment_is_leakage_from_the_other_output():
    H = model().copy()
    H[Y] = H[Y] + 0.03 * H[X]
    rem = describe(H)
    top = main(rem)
    assert top.kind == "leakage"
    assert top.location.side == "output" and (top.target, top.source) == ("y", "x")
    assert abs(top.epsilon / 0.03 - 1) < EPS_REL


def test_spring_and_damper_in_parallel_with_a_drive():
    M, K, D = system()
    K, D = K.copy(), D.copy()
    K[X, X] += 3000.0  # a cable carrier on x: spring and damper to ground
    D[X, X] += 8.0
    rem = describe(receptance(M, K, D))
    top = main(rem)
    assert top.kind == "stiffness_offset"
    assert top.location.side == "drive" and top.drive == "x"
    assert abs(top.stiffness / 3000.0 - 1) < K_REL
    assert abs(top.damping / 8.0 - 1) < K_REL


def test_mass_the_model_lacks_on_a_drive():
    M, K, D = system()
    M = M.copy()
    M[Y, Y] += 0.5
    rem = describe(receptance(M, K, D))
    top = main(rem)
    assert top.kind == "mass_offset"
    assert top.drive == "y"
    assert abs(top.mass / 0.5 - 1) < MASS_REL
    assert top.stiffness == 0.0


def test_sensor_wired_with_the_wrong_polarity():
    H = model().copy()
    H[Y] *= -1.0
    top = main(describe(H))
    assert top.kind == "gain_offset" and top.reversed
    assert top.location.side == "output" and top.location.names == ("y",)
    assert abs(top.gain_db) < GAIN_DB


def test_velocity_read_as_displacement_is_a_power_law_gain():
    H = model().copy()
    H[Z] *= S  # the z sensor gives velocity; the file says receptance
    top = main(describe(H))
    assert top.kind == "gain_slope"
    assert top.location.side == "output" and top.location.names == ("z",)
    assert abs(top.alpha - 1.0) < SLOPE_ABS
    assert "a velocity taken for a displacement" in top.text


def test_notch_filter_in_one_drive():
    H = model().copy()
    x = S / (2 * np.pi * 1200.0)
    H[:, X] *= (1 + 2 * 0.01 * x + x * x) / (1 + 2 * 0.3 * x + x * x)
    top = main(describe(H))
    assert top.kind == "notch"
    assert top.location.side == "input" and top.location.names == ("x",)
    assert abs(top.f_hz / 1200.0 - 1) < F_REL
    assert abs(top.depth_db - 20 * np.log10(0.01 / 0.3)) < NOTCH_DB
