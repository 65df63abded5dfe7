"""The damping law of the remainder: modes both have, damped otherwise in the data, read as
one law (``damping_law``) — on the synthetic machine of test_remainder_systems, whose modal
damping is set per mode, and on findings built by hand."""

from __future__ import annotations

import numpy as np
import pytest
from test_remainder_systems import F_FLEX, measured, receptance, system

from bondid.diagnose.remainder import describe_remainder
from bondid.diagnose.remainder.base import Location
from bondid.diagnose.remainder.damping_law import Pair, damping_law, pairs_of
from bondid.diagnose.remainder.mode_finding import ModeFinding

#: the fitted exponent of ζ ∝ f^b against the law the data were built with
EXPONENT_ABS = 0.15
#: the loss factor the finding suggests against twice the data's damping ratio (relative)
ETA_REL = 0.15


def _law(zeta_data):
    rem = describe_remainder(measured(receptance(*system(zeta=zeta_data)), 1),
                             receptance(*system()))  # fmt: skip
    laws = [f for f in rem.findings if f.kind == "damping_law"]
    return rem, laws


def test_the_same_ratio_at_every_mode_reads_as_a_loss_factor():
    """Data damped 0.8 % at each of the three modes, a model at 2, 1.5 and 2 %: one law,
    constant, with the loss factor to try; the primary finding is still a mode."""
    rem, laws = _law((0.008, 0.008, 0.008))
    assert len(laws) == 1, rem.sentences()
    law = laws[0]
    assert law.law == "constant" and law.damping == "structural"
    assert abs(law.exponent) < EXPONENT_ABS
    assert np.allclose(law.f_hz, F_FLEX, rtol=0.02)
    eta = 2 * np.exp(np.mean(np.log(law.zeta)))
    assert eta == pytest.approx(0.016, rel=ETA_REL)
    assert "--damping structural" in law.text and rem.sentences()[1] == law.text + (
        f" ({round(100 * law.share)} % of the excess)"
    )
    assert rem.primary()["kind"] != "damping_law"


def test_a_ratio_growing_with_frequency_reads_as_stiffness_proportional():
    zeta = tuple(0.006 * f / F_FLEX[0] for f in F_FLEX)  # ζ ∝ f: β·K
    rem, laws = _law(zeta)
    assert len(laws) == 1, rem.sentences()
    assert laws[0].law == "stiffness-proportional" and laws[0].damping == "rayleigh-only"
    assert laws[0].exponent == pytest.approx(1.0, abs=EXPONENT_ABS)


def test_damping_as_modelled_gives_no_law():
    rem, laws = _law((0.02, 0.015, 0.02))
    assert not laws, rem.sentences()


def _mode(f):
    return ModeFinding("misplaced_mode", "", 0.2, Location("global", (), ("x.x",)), None, "",
                       None, f_hz=f, status="misplaced", form="model mode")  # fmt: skip


def test_a_law_needs_paired_modes_damped_otherwise_and_a_claimed_one():
    """Three pairs, two damped otherwise at their own frequency: a law (its share the claimed
    modes' there); a pair whose frequency moved by more than its bandwidth does not count as
    damping; with nothing claimed there, or with too few pairs, no law."""
    pairs = [Pair(100.0, 0.01, 100.0, 0.03), Pair(300.0, 0.01, 300.5, 0.02),
             Pair(700.0, 0.011, 700.0, 0.011)]  # fmt: skip
    law = damping_law([_mode(100.0), _mode(300.2)], pairs)
    assert law is not None and law.law == "constant" and law.off == [True, True, False]
    assert law.share == pytest.approx(0.4) and law.location.channels == ("x.x",)
    assert law.exponent_model == pytest.approx(
        np.polyfit(np.log([100, 300, 700]), np.log([0.03, 0.02, 0.011]), 1)[0]
    )
    moved = [*pairs[:1], Pair(300.0, 0.01, 330.0, 0.02), pairs[2]]
    assert damping_law([_mode(100.0), _mode(300.0)], moved) is None
    assert damping_law([_mode(500.0)], pairs) is None
    assert damping_law([_mode(100.0)], pairs[:2]) is None


def test_pairs_of_several_data_sets_merge():
    rows = [
        [{"status": "paired", "f_measured_hz": 100.0, "zeta_measured": 0.01,
          "f_model_hz": 101.0, "zeta_model": 0.02},
         {"status": "missing", "f_measured_hz": 200.0, "zeta_measured": 0.01,
          "f_model_hz": None, "zeta_model": None}],
        [{"status": "paired", "f_measured_hz": 100.5, "zeta_measured": 0.04,
          "f_model_hz": 101.5, "zeta_model": 0.02}],
    ]  # fmt: skip
    (p,) = pairs_of(rows)
    assert p.f_hz == pytest.approx(np.sqrt(100.0 * 100.5))
    assert p.zeta == pytest.approx(0.02) and p.zeta_model == pytest.approx(0.02)
