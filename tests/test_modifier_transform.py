"""FRF modifiers as transforms ``H' = G ⊙ (L H R)``: signed (linear-scale) parameters and
output/input mixing, through the cost's exact Jacobian and the diagnosis's refit."""

from __future__ import annotations

import numpy as np
import pytest

from bondid.cost.modifier import FrfModifier, Mixing
from bondid.data.measurement import FrfData
from bondid.exceptions import ConfigError
from bondid.linear.affine import build_affine_model
from bondid.model import UrdfDocument, get_parameters, set_parameter
from bondid.optim import FitProblem, run_search
from bondid.optim.schedules import direct

URDF = "urdf/bonder.urdf"
OPS = [{}, {"x": 0.05, "y": -0.03, "z": 0.1}]
NAME = "x_guide_ry.stiffness"
#: central finite differences of the cost agree with the exact gradient to this (relative)
FD_REL = 1e-5


@pytest.fixture(scope="module")
def bonder() -> UrdfDocument:
    return UrdfDocument.load(URDF)


def _factor(theta, freq_hz, outputs, inputs):
    """A delay ``θ₀`` on output ``y`` (log-scale parameter); the others do not act here."""
    w = 2 * np.pi * np.asarray(freq_hz)
    G = np.ones((len(outputs), len(inputs), w.size), complex)
    dG = np.zeros((*G.shape, theta.size), complex)
    i = outputs.index("y")
    G[i] = np.exp(-1j * w * theta[0])
    dG[i, :, :, 0] = -1j * w * G[i]
    return G, dG


def _mixing(theta, outputs, inputs):
    """``L = I + E`` with ``E[x, y] = θ₁``, ``E[y, x] = θ₂``; ``R = I + F`` with
    ``F[z, x] = θ₃`` (input x also pushes on z)."""
    n, m = len(outputs), len(inputs)
    L, dL = np.eye(n, dtype=complex), np.zeros((n, n, theta.size), complex)
    R, dR = np.eye(m, dtype=complex), np.zeros((m, m, theta.size), complex)
    for k, (a, b) in ((1, ("x", "y")), (2, ("y", "x"))):
        L[outputs.index(a), outputs.index(b)] += theta[k]
        dL[outputs.index(a), outputs.index(b), k] = 1.0
    R[inputs.index("z"), inputs.index("x")] += theta[3]
    dR[inputs.index("z"), inputs.index("x"), 3] = 1.0
    return Mixing(L, dL, R, dR)


def _modifier(start) -> FrfModifier:
    return FrfModifier(
        _factor, ("tau", "e_xy", "e_yx", "f_zx"), tuple(start), (1e-7, -0.3, -0.3, -0.3),
        (1e-3, 0.3, 0.3, 0.3), (False, True, True, True), (1.0, 0.02, 0.02, 0.02), _mixing,
    )  # fmt: skip


def _data(doc: UrdfDocument, mod: FrfModifier, theta: np.ndarray, n: int = 80) -> list[FrfData]:
    f = np.logspace(0, np.log10(4000.0), n)
    out = []
    for op in OPS:
        am = build_affine_model(doc, op)
        H = mod.apply(theta, f, am.outputs, am.inputs, am.linear_model().frf(f))
        out.append(FrfData(f, am.outputs, am.inputs, H, operating_point=op))
    return out


def test_linear_and_log_parameters_map_to_the_fit_variables():
    mod = _modifier((2e-5, 0.0, 0.01, -0.02))
    theta0 = np.array(mod.start)
    theta = np.array([5e-5, 0.03, -0.01, 0.0])
    u = mod.u_of(theta, theta0)
    np.testing.assert_allclose(u, [np.log(2.5), 1.5, -1.0, 1.0], rtol=1e-14)
    np.testing.assert_allclose(mod.theta_of(u, theta0), theta, rtol=1e-14, atol=1e-17)
    np.testing.assert_allclose(mod.slope(theta), [5e-5, 0.02, 0.02, 0.02], rtol=0)
    assert mod.u_of(np.array([np.inf, np.inf, -np.inf, 0.0]), theta0)[:3].tolist() == [
        np.inf, np.inf, -np.inf]  # fmt: skip


@pytest.mark.parametrize(
    "kwargs",
    [dict(start=(0.0,), lower=(-1.0,), upper=(1.0,)),  # log scale: 0 not allowed
     dict(start=(0.0,), lower=(-1.0,), upper=(1.0,), linear=(True,), scale=(0.0,)),
     dict(start=(2.0,), lower=(-1.0,), upper=(1.0,), linear=(True,)),
     dict(start=(0.0,), lower=(-1.0,), upper=(1.0,), linear=(True, False))],
)  # fmt: skip
def test_bad_modifier_parameters_are_refused(kwargs):
    with pytest.raises(ConfigError):
        FrfModifier(_factor, ("a",), **kwargs)


def test_mixing_derivatives_match_finite_differences(bonder):
    mod = _modifier((2e-5, 0.0, 0.0, 0.0))
    am = build_affine_model(bonder, OPS[1])
    f = np.geomspace(5.0, 3000.0, 9)
    H = am.linear_model().frf(f)
    theta = np.array([3e-5, 0.02, -0.03, 0.05])
    mixing = mod.mix(theta, am.outputs, am.inputs)
    assert mixing is not None
    # L H R written out per frequency
    LHR = np.stack([mixing.left @ H[:, :, k] @ mixing.right for k in range(f.size)], axis=2)
    np.testing.assert_allclose(mixing.apply(H), LHR, rtol=1e-13)
    d = mixing.dtheta(H, theta.size)
    for k in range(1, 4):
        h = np.where(np.arange(4) == k, 1e-6, 0.0)
        hi = mod.mix(theta + h, am.outputs, am.inputs)
        lo = mod.mix(theta - h, am.outputs, am.inputs)
        assert hi is not None and lo is not None
        fd = (hi.apply(H) - lo.apply(H)) / 2e-6
        np.testing.assert_allclose(d[..., k], fd, rtol=1e-8, atol=1e-12 * np.abs(H).max())


def test_a_mixing_modifier_keeps_the_exact_gradient_and_is_recovered(bonder):
    """Known answer: data of the model with a spring 5 % off, a 50 µs delay on y, output
    cross-talk ``E[x, y] = 0.03``, ``E[y, x] = −0.02`` and input cross-talk ``F[z, x] = 0.04``;
    the fit from no cross-talk and a 20 µs delay has the exact gradient (also through a free
    transducer gain) and recovers every value."""
    truth_theta = np.array([5e-5, 0.03, -0.02, 0.04])
    truth = bonder.copy()
    k0 = get_parameters(bonder, [NAME])[0]
    set_parameter(truth, NAME, 1.05 * k0)
    mod = _modifier((2e-5, 0.0, 0.0, 0.0))
    data = _data(truth, mod, truth_theta)
    gained = bonder.copy()
    gained.set_gain("gain.out.y", 1.0)
    problem = FitProblem(gained, data, [NAME, "gain.out.y"], modifier=mod)
    nlp = problem.nlp()
    z0 = problem.z0 + 0.05
    g = nlp.gradient(z0)
    h = 1e-6
    fd = np.array([(nlp.cost(z0 + e) - nlp.cost(z0 - e)) / (2 * h) for e in h * np.eye(z0.size)])
    np.testing.assert_allclose(g, fd, rtol=FD_REL, atol=FD_REL * np.max(np.abs(g)))
    res = run_search(problem, direct()).result
    assert res.success, res.status
    got = np.array([res.modifiers[n] for n in mod.names])
    np.testing.assert_allclose(got, truth_theta, rtol=1e-6, atol=1e-9)
    assert res.parameter(NAME) == pytest.approx(1.05 * k0, rel=1e-6)
    assert res.parameter("gain.out.y") == pytest.approx(1.0, rel=1e-6)
    # the modified FRF of the fitted problem is the data (used_frf goes through the mixing)
    p = problem.restrict(start=res.fitted, theta=got)
    assert p.data_cost(p.z0) < 1e-12


def test_composed_mixing_of_several_candidates_matches_finite_differences():
    """Two output mixings (the first applied first) and a gain: the composed matrix is their
    product, its derivative matches central differences."""
    from bondid.diagnose.augmented import ComposedModifier
    from bondid.diagnose.effects import get_effect

    doc = UrdfDocument.load(URDF)
    mis = get_effect("sensor_misalignment").candidates(doc)[0]  # x,y
    gain = next(c for c in get_effect("transducer_gain").candidates(doc) if c.location == "in.z")
    mod = ComposedModifier([mis, gain, mis])
    assert mod.mixes
    outs, ins = ("x", "y", "z"), ("x", "y", "z")
    v = np.array([0.02, -0.05, 0.1, 0.03, 0.04])
    m = mod.mixing(v, outs, ins)
    assert m is not None and m.right is None
    L1 = np.eye(3)
    L1[0, 1], L1[1, 0] = 0.02, -0.05
    L2 = np.eye(3)
    L2[0, 1], L2[1, 0] = 0.03, 0.04
    np.testing.assert_allclose(m.left, L2 @ L1, rtol=1e-15)
    for k in range(v.size):
        h = np.where(np.arange(v.size) == k, 1e-6, 0.0)
        hi, lo = mod.mixing(v + h, outs, ins), mod.mixing(v - h, outs, ins)
        assert hi is not None and lo is not None and m.dleft is not None
        np.testing.assert_allclose(m.dleft[..., k], (hi.left - lo.left) / 2e-6, atol=1e-9)
