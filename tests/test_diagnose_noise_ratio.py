"""The refit's noise ratio with the noise level computed once per refit
(:attr:`bondid.diagnose.refit.Refit.noise_cost`) against the ratio computed from scratch at
each point (the noise-level cost of that point's problem)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from models import noisy_bonder_data

from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]


@pytest.fixture(scope="module")
def refit():  # type: ignore[no-untyped-def]
    """The parameter-only refit of the bonder on its own noisy data."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build
    from bondid.diagnose.refit import nominal_space

    doc = UrdfDocument.load(MODEL)
    data = noisy_bonder_data(doc, n=60)
    return build(doc.to_string(), nominal_space(doc, FEW, 4000.0), data, CostOptions(), (),
                 None).refit  # fmt: skip


def test_cached_ratio_equals_the_ratio_computed_at_each_point(refit, monkeypatch):
    """At the start and at points with the stage masses moved by up to 40 %, the ratio from
    the cached level equals (bit for bit) the one of ``noise_ratio`` on that point's problem,
    and the noise level itself is computed once for all those points."""
    from bondid.cost import noise_level
    from bondid.optim.noise import NoisePolicy

    def noise_ratio(p, cost, basis):  # type: ignore[no-untyped-def]
        return NoisePolicy(noise_level.noise_level_cost(p.frf, basis)).ratio_of(cost)

    def noise_ratio_at(refit, s):  # type: ignore[no-untyped-def]
        return NoisePolicy(refit.noise_cost).ratio_of(refit.data_cost(s))

    calls = []
    real = noise_level.noise_level_cost

    def counted(*a, **k):  # type: ignore[no-untyped-def]
        calls.append(1)
        return real(*a, **k)

    s0 = refit.state0
    states = [s0]
    for f in (0.6, 0.9, 1.4):
        s = s0.copy()
        s.x[:3] *= f
        states.append(s)
    expected = []
    for s in states:
        p = refit.at(s)
        expected.append(noise_ratio(p, p.data_cost(p.z0), basis="weights"))
    monkeypatch.setattr(noise_level, "noise_level_cost", counted)
    got = [noise_ratio_at(refit, s) for s in states]
    assert got == expected
    assert all(r is not None and np.isfinite(r) for r in got)
    assert len(set(got)) == len(got)  # the points differ: the test compares distinct ratios
    assert len(calls) <= 1  # at most once (none if an earlier test already cached it)
    assert refit.noise_cost is refit.noise_cost
