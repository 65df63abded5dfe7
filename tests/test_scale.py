"""Dense data: memory linear in the lines, windowed order statistics, block-wise Jacobians."""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable

import numpy as np
from models import two_mass_chain

from bondid.cost import CostOptions, FrfProblem
from bondid.data import FrfData, add_measurement_noise
from bondid.data.noise_estimate import estimate_noise
from bondid.data.noise_floor import window_quantile
from bondid.data.weights import information_weights
from bondid.linear import build_affine_model
from bondid.linear.parameter_map import ParameterMap
from bondid.model import get_parameters

#: peak memory at 4× the lines over the peak at 1×: linear is 4, a dense (n × window)
#: matrix whose window grows with the lines would be 16
LINEAR_RATIO_MAX = 6.0
NAMES = ["body_a.mass", "body_b.mass", "a.stiffness", "b.stiffness", "a.damping", "b.damping"]


def _data(n: int, seed: int = 0) -> FrfData:
    doc = two_mass_chain(1.0, 0.5, 1.0e5, 7.7, 2.0e5, 6.3)
    f = np.geomspace(1.0, 4000.0, n)
    H = build_affine_model(doc, {}).linear_model().frf(f)
    Hn, coh = add_measurement_noise(H, f, rel=0.02, floor_db=-70.0, rng=seed)
    return FrfData(f, ("a", "b"), ("a", "b"), Hn, coherence=coh)


def _peak_bytes(fn: Callable[[], object]) -> int:
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        fn()
        return tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


def test_noise_estimate_and_weights_memory_linear_in_lines() -> None:
    small, large = _data(3000), _data(12000)
    for what, fn in (
        ("noise estimate", lambda ds: estimate_noise(ds.freq_hz, ds.H)),
        ("weights", lambda ds: information_weights(ds, "auto")),
    ):
        fn(_copy(_data(200)))  # imports and one-off tables are not the data's memory
        # fresh copies: the weights would otherwise reuse the cached estimate
        a = _peak_bytes(lambda f=fn: f(_copy(small)))  # type: ignore[misc]
        b = _peak_bytes(lambda f=fn: f(_copy(large)))  # type: ignore[misc]
        assert b / a <= LINEAR_RATIO_MAX, f"{what}: {b / a:.1f}× the memory at 4× the lines"


def _copy(ds: FrfData) -> FrfData:
    return FrfData(ds.freq_hz.copy(), ds.outputs, ds.inputs, ds.H.copy(), coherence=ds.coherence)


def test_window_quantile_matches_sorting_each_window() -> None:
    rng = np.random.default_rng(2)
    n = 700
    x = rng.standard_normal(n) * np.exp(rng.uniform(-20, 20, n))
    k = np.arange(n)
    lo = np.maximum.accumulate(np.maximum(k - rng.integers(0, 40, n), 0))
    hi = np.minimum.accumulate(np.minimum(k + 1 + rng.integers(0, 40, n), n)[::-1])[::-1]
    hi = np.maximum.accumulate(np.maximum(hi, lo + 1))
    for q, how in ((0.5, "lower"), (0.5, "midpoint"), (0.25, "lower")):
        got = window_quantile(x, lo, hi, q, how)
        want = [np.quantile(x[a:b], q, method=how) for a, b in zip(lo, hi, strict=True)]
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=0)  # midpoint: last bit


def test_blockwise_jacobian_of_a_channel_subset_equals_the_full_grid_rows() -> None:
    """A channel subset takes the point-wise path, the full grid the grid path: the same
    rows, scaled by the normalisation (each problem's cost is a weighted mean)."""
    ds = _data(700)
    doc = two_mass_chain(1.1, 0.45, 0.9e5, 8.0, 2.2e5, 6.0)
    full = FrfProblem(doc, [ds], CostOptions())
    sub = FrfProblem(doc, [ds], CostOptions(channels=["a.a", "b.b"]))
    assert full.blocks[0].flat is None and sub.blocks[0].flat is not None
    pmap = ParameterMap(doc, full.affines[0], NAMES)
    x = np.asarray(get_parameters(doc, NAMES), float) * 1.05
    r_f, J_f = full.residual_and_jacobian(pmap, x)
    r_s, J_s = sub.residual_and_jacobian(pmap, x)
    n = ds.freq_hz.size
    rows = np.concatenate([p * 4 * n + c * n + np.arange(n) for p in (0, 1) for c in (0, 3)])
    scale = np.sqrt(sub.total_weight / full.total_weight)
    np.testing.assert_allclose(r_s * scale, r_f[rows], rtol=1e-12, atol=0)
    np.testing.assert_allclose(J_s * scale, J_f[rows], rtol=1e-10, atol=1e-12 * abs(J_f).max())
    np.testing.assert_allclose(r_s, sub.residual(pmap, x), rtol=1e-12)
