"""The constrained fit (bondid.fit): round trips, constraints, gradient, errors."""

from __future__ import annotations

import re

import numpy as np
import pytest

from bondid.consistency import is_consistent, link_hull
from bondid.consistency.log_cholesky import pi_from_theta
from bondid.data.measurement import FrfData
from bondid.data.noise import add_measurement_noise
from bondid.exceptions import ConfigError, ParameterError, SolverError
from bondid.fit import default_bounds, fit
from bondid.linear.affine import build_affine_model
from bondid.model import (
    UrdfDocument,
    get_parameters,
    link_inertial,
    select_parameters,
    set_parameter,
)
from bondid.optim import FitProblem, SearchResult, run_search
from bondid.optim.schedules import CONTINUATION_BANDS, continuation

URDF = "urdf/bonder.urdf"
OPS = [{}, {"x": 0.05, "y": -0.03, "z": 0.1}]
# identifiable from the 3x3 data at the two poses (checked with the Jacobian's SVD)
INERTIAL = [
    "x_stage.mass",
    "y_stage.mass",
    "z_stage.mass",
    "x_stage.com.z",
    "y_stage.inertia.ixx",
    "z_stage.inertia.ixx",
]
REL = {"mass": 0.5, "com": 0.6, "inertia": 0.6, "stiffness": 0.6, "damping": 0.6}


def continuation_fit(
    doc: UrdfDocument, data: list[FrfData], names: list[str], *, on_stage=None, **kw
) -> SearchResult:
    """The band-continuation search (default schedule) on a problem built from ``kw``."""
    problem = FitProblem(doc, data, names, **kw)
    return run_search(problem, continuation(problem), on_step=on_stage)


@pytest.fixture(scope="module")
def bonder() -> UrdfDocument:
    return UrdfDocument.load(URDF)


def synth(doc: UrdfDocument, n_freq: int, noise_seed: int | None = None) -> list[FrfData]:
    f = np.logspace(0, np.log10(4000.0), n_freq)
    out = []
    for k, op in enumerate(OPS):
        am = build_affine_model(doc, op)
        H = am.linear_model().frf(f)
        coh = None
        if noise_seed is not None:
            H, coh = add_measurement_noise(H, f, rel=0.02, floor_db=None, rng=noise_seed + k)
        out.append(FrfData(f, am.outputs, am.inputs, H, operating_point=op, coherence=coh))
    return out


def perturbed_start(
    doc: UrdfDocument, names: list[str], seed: int = 5, inertial: float = 0.1
) -> np.ndarray:
    """±30 % on joint parameters, ±``inertial`` on inertial ones (random signs)."""
    truth = get_parameters(doc, names)
    rng = np.random.default_rng(seed)
    frac = np.array([inertial if n.split(".")[0].endswith("_stage") else 0.3 for n in names])
    return truth * (1.0 + frac * rng.choice([-1.0, 1.0], size=truth.size))


@pytest.fixture(scope="module")
def names(bonder: UrdfDocument) -> list[str]:
    return select_parameters(bonder, ["parasitic", *INERTIAL])


#: Starts of the ±30 %-on-every-parameter round trips (the seeds of their random signs). A
#: local fit from these lands in another basin (measured: the direct fit's cost stays > 0.1);
#: the band continuation reaches the truth (measured: from 17 of 18 such starts).
FAR_SEEDS = (6, 9)


@pytest.mark.parametrize("seed", FAR_SEEDS)
def test_noise_free_round_trip_far_start(bonder: UrdfDocument, names: list[str], seed: int) -> None:
    """±30 % on every one of the 22 parameters: band continuation, then the full fit."""
    truth = get_parameters(bonder, names)
    lo, hi = default_bounds(bonder, names, rel=REL)
    start = perturbed_start(bonder, names, seed=seed, inertial=0.3)
    assert np.allclose(np.abs(start / truth - 1.0), 0.3)
    data = synth(bonder, 300)
    stages: list[str] = []
    res = continuation_fit(
        bonder, data, names, start=start, lower=lo, upper=hi,
        on_stage=lambda st: stages.append(st.name),
    ).result  # fmt: skip
    assert res.success, res.status
    rel_err = np.abs(res.fitted - truth) / np.abs(truth)
    assert np.max(rel_err) < 1e-6, dict(zip(names, rel_err, strict=True))
    assert res.cost_final < 1e-12 < res.cost_initial
    np.testing.assert_array_equal(res.initial, start)
    assert len(stages) == CONTINUATION_BANDS and stages[-1] == "all"


def test_noise_free_round_trip(bonder: UrdfDocument, names: list[str]) -> None:
    """Direct fit from a near start (±10 % on the inertial parameters): one local solve."""
    truth = get_parameters(bonder, names)
    lo, hi = default_bounds(bonder, names, rel=REL)
    seen: list[tuple[int, float]] = []
    res = fit(
        bonder,
        synth(bonder, 300),
        names,
        start=perturbed_start(bonder, names),
        lower=lo,
        upper=hi,
        progress=lambda i, c: seen.append((i, c)),
    )
    assert res.success, res.status
    rel_err = np.abs(res.fitted - truth) / np.abs(truth)
    assert np.max(rel_err) < 1e-6, dict(zip(names, rel_err, strict=True))
    assert res.cost_final < 1e-12 < res.cost_initial
    # the direct fit matched the phase everywhere: no presolved second fit
    assert any("presolve skipped" in n for n in res.notes), res.notes
    assert len(res.cost_history) == res.iterations + 1 == len(seen)
    assert res.cost_history[-1] == pytest.approx(res.cost_final, abs=1e-12)
    # the fitted document carries the fitted values; the input is untouched
    np.testing.assert_allclose(get_parameters(res.document, names), res.fitted, rtol=1e-12)
    assert get_parameters(bonder, names) == pytest.approx(truth, rel=0)
    js = res.to_json_dict()
    assert {p["name"] for p in js["parameters"]} == set(names)
    assert js["status"] == res.status and js["iterations"] == res.iterations


def test_presolve_crosses_the_sign_wall_of_a_cross_term(bonder: UrdfDocument) -> None:
    """At the second operating point the static gain of y.z changes sign between
    z_stage.com.z = −2 mm (truth) and −4 mm (start): the log cost has a wall there. The direct
    fit stalls at the wall; the presolved one reaches the truth."""
    truth = bonder.copy()
    set_parameter(truth, "z_stage.com.z", -0.002)
    data = [d for d in synth(truth, 300) if d.operating_point]
    names = ["z_stage.com.z"]
    lo, hi = np.array([-0.008]), np.array([0.0])
    direct = fit(bonder, data, names, lower=lo, upper=hi, presolve_iter=0)
    assert abs(direct.fitted[0] + 0.002) > 1e-3  # stuck on the start's side of the wall
    both = fit(bonder, data, names, lower=lo, upper=hi)
    assert both.fitted[0] == pytest.approx(-0.002, rel=1e-6)
    assert both.cost_final < 1e-12 < direct.cost_final
    assert any("kept the presolved one" in n for n in both.notes), both.notes


def test_noisy_round_trip_within_three_std(bonder: UrdfDocument, names: list[str]) -> None:
    """±30 % on every parameter, 2 % noise: band continuation, each within 3 std."""
    truth = get_parameters(bonder, names)
    lo, hi = default_bounds(bonder, names, rel=REL)
    res = continuation_fit(
        bonder,
        synth(bonder, 300, noise_seed=11),
        names,
        start=perturbed_start(bonder, names, seed=FAR_SEEDS[0], inertial=0.3),
        lower=lo,
        upper=hi,
    ).result
    assert res.success, res.status
    assert np.all(np.isfinite(res.std)) and np.all(res.std > 0)
    z = (res.fitted - truth) / res.std
    assert np.max(np.abs(z)) < 3.0, dict(zip(names, np.round(z, 2), strict=True))
    # the correlation matrix is a correlation matrix
    C = res.correlation
    np.testing.assert_allclose(np.diag(C), 1.0)
    np.testing.assert_allclose(C, C.T, atol=1e-12)
    assert np.min(np.linalg.eigvalsh(C)) > -1e-9


def _com_outside_truth(doc: UrdfDocument) -> UrdfDocument:
    """The bonder with the x_stage CoM moved to y = 0.16 m (its box reaches |y| = 0.1 m)."""
    text = doc.to_string()
    new, count = re.subn(
        r'(<link name="x_stage">\s*<inertial>\s*<origin xyz=")[^"]*"',
        r'\g<1>0.011 0.16 -0.004"',
        text,
    )
    assert count == 1
    return UrdfDocument.from_string(new)


def test_com_outside_hull_ends_on_hull(bonder: UrdfDocument) -> None:
    truth = _com_outside_truth(bonder)
    hull = link_hull(bonder.link("x_stage"))
    assert hull is not None
    _, c_true, _ = link_inertial(truth, "x_stage")
    assert not hull.contains(c_true)
    names = ["x_stage.com.x", "x_stage.com.y", "x_stage.com.z"]
    res = fit(
        bonder,
        synth(truth, 200),
        names,
        lower=np.full(3, -1.0),
        upper=np.full(3, 1.0),
    )
    assert res.success, res.status
    m, c, I_c = link_inertial(res.document, "x_stage")
    assert hull.contains(c, -1e-8)  # IPOPT may relax a bound by ~1e-8 (scaled)
    assert hull.distance(c) < 1e-6  # on the boundary: the data pull it outwards
    assert c[1] > 0.09
    from bondid.consistency import pi_from_urdf

    assert is_consistent(pi_from_urdf(m, c, I_c))
    assert "x_stage com in hull" in res.active_constraints
    # the fixed parameters of x_stage kept their URDF values
    assert m == pytest.approx(link_inertial(bonder, "x_stage")[0], rel=1e-12)
    np.testing.assert_allclose(I_c, link_inertial(bonder, "x_stage")[2], rtol=1e-6, atol=1e-12)


def test_gradient_matches_central_differences(bonder: UrdfDocument) -> None:
    names = [
        "x_stage.mass",
        "x_stage.com.y",
        "z_stage.inertia.ixx",
        "x_guide_ry.stiffness",
        "y_guide_rz.damping",
    ]
    truth = _com_outside_truth(bonder)  # any data that do not fit the start exactly
    problem = FitProblem(bonder, synth(truth, 120), names)
    nlp = problem.nlp()
    z0 = problem.z0 + 0.05 * np.random.default_rng(0).standard_normal(problem.z0.size)
    g = nlp.gradient(z0)
    fd = np.zeros_like(g)  # the entries IPOPT holds (fixed variables) have a zero gradient
    movable = problem.evaluator.cols
    assert movable.size < z0.size  # the bodies' held CoM and inertia entries are fixed
    for k in movable:
        h = 1e-6 * max(1.0, abs(z0[k]))
        e = np.zeros_like(z0)
        e[k] = h
        fd[k] = (nlp.cost(z0 + e) - nlp.cost(z0 - e)) / (2 * h)
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-7 * np.max(np.abs(g)))
    # every z is physically consistent (log-Cholesky)
    for blk in problem.layout.blocks:
        assert is_consistent(pi_from_theta(blk.theta(z0 + 3.0)))


def test_unknown_name_and_kinematic_placement(bonder: UrdfDocument) -> None:
    data = synth(bonder, 50)
    with pytest.raises(ParameterError, match=r"x_stage\.volume"):
        fit(bonder, data, ["x_stage.volume"])
    with pytest.raises(ConfigError, match="kinematic"):
        fit(bonder, data, ["x_guide_ry.origin.z"])
    with pytest.raises(ConfigError, match="twice"):
        fit(bonder, data, ["x.damping", "x.damping"])


def test_solver_failure_keeps_ipopt_status(bonder: UrdfDocument) -> None:
    data = synth(bonder, 50)
    # izz of x_stage must exceed |ixx - iyy| = 0.0038 kg m² (triangle inequality): infeasible
    with pytest.raises(SolverError) as info:
        fit(
            bonder,
            data,
            ["x_stage.inertia.izz"],
            lower=np.array([1e-4]),
            upper=np.array([2e-4]),
            start=np.array([1.5e-4]),
        )
    assert info.value.status in ("Infeasible_Problem_Detected", "Restoration_Failed")
    # an iteration limit is returned, not raised
    names = ["x_guide_ry.stiffness", "y_guide_rx.stiffness"]
    res = fit(bonder, data, names, start=get_parameters(bonder, names) * 1.3, max_iter=1)
    assert not res.success and res.status == "Maximum_Iterations_Exceeded"


def test_default_bounds(bonder: UrdfDocument) -> None:
    names = ["x_stage.mass", "x.stiffness", "x_guide_ry.stiffness", "x_stage.com.x", "z.damping"]
    lo, hi = default_bounds(
        bonder, names, rel={"x_guide_*": 0.1}, absolute={"z.damping": (0.0, 1.0)}
    )
    np.testing.assert_allclose(lo[0:3], [1.67 * 0.5, 0.0, 2e5 * 0.9])
    np.testing.assert_allclose(hi[[0, 2]], [1.67 * 1.5, 2e5 * 1.1])
    # a zero stiffness has nothing to be relative to: finite, from the joint's inertia
    from bondid.linear.affine import build_affine_model
    from bondid.optim.bounds import DEFAULT_F_MAX, STIFF_FACTOR

    am = build_affine_model(bonder, {})
    m_xx = am.mass_matrix()[am.dofs.index("x"), am.dofs.index("x")]
    assert hi[1] == pytest.approx(STIFF_FACTOR * m_xx * (2 * np.pi * DEFAULT_F_MAX) ** 2)
    # CoM: room relative to the hull size when the value is small (hull diagonal ~0.33 m)
    assert hi[3] - lo[3] > 2 * 0.5 * 0.011
    assert (lo[4], hi[4]) == (0.0, 1.0)


def test_infeasible_prior_is_projected_and_noted(bonder: UrdfDocument) -> None:
    truth = _com_outside_truth(bonder)
    names = ["x_stage.com.x", "x_stage.com.y", "x_stage.com.z"]
    res = fit(truth, synth(truth, 60), names, lower=np.full(3, -1.0), upper=np.full(3, 1.0))
    assert any("x_stage" in n and "projected" in n for n in res.notes)
    hull = link_hull(bonder.link("x_stage"))
    assert hull is not None
    assert hull.contains(link_inertial(res.document, "x_stage")[1], -1e-8)
