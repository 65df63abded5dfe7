"""Proportional (Rayleigh) damping ``D = D_joints + α·M + β·K``: the model's FRF against
closed forms and a peer, exact derivatives, the start estimate, the model element, the
damping models of ``--damping`` and their errors, and known-answer fits."""

from __future__ import annotations

import json

import numpy as np
import pytest
from models import frf_jacobian_errors, one_mass
from test_ties_mix import _strip

from bondid.cost.problem import FrfProblem
from bondid.exceptions import ConfigError, ModelError, ParameterError
from bondid.linear.affine import build_affine_model
from bondid.linear.linear_model import underdamped
from bondid.linear.parameter_map import ParameterMap
from bondid.linear.rayleigh import fit_coefficients, rayleigh_start
from bondid.model import UrdfDocument
from bondid.model.parameters import get_parameter, parameter_names, select_parameters, set_parameter
from bondid.model.rayleigh import Rayleigh, model_rayleigh, set_rayleigh
from bondid.optim.problem import FitProblem
from bondid.setup.damping import damping_free, damping_from_study, declare_damping
from bondid.simulate import simulate

#: two exact computations of one FRF (round-off only, relative)
EXACT_TOL = 1e-10
#: against python-control's state-space evaluation (relative, matrix norm per frequency)
TOL_PEER = 1e-9
#: analytic Jacobians against central differences (relative to the column's largest entry)
JAC_FD_TOL = 1e-6
#: the start estimate on a proportionally damped model recovers its α, β (relative)
START_RTOL = 1e-6
#: a fit at 1 % noise recovers α and β within this many of its own std …
RECOVER_SIGMAS = 4.0
#: … and within this fraction of the truth
RECOVER_RTOL = 0.05
#: the fitted db_rms is "at the noise level" within this factor of the predicted level
AT_NOISE = 1.10

ALPHA, BETA = 0.8, 2e-4  # the truth's coefficients, 1/s and s
FREQ = np.geomspace(2.0, 200.0, 90)


def _proportional(alpha: float = ALPHA, beta: float = BETA, dampers: bool = False):
    """The strip (bending and torsion joints, a patch and an accelerometer) with Rayleigh
    damping, its joint dampers kept or set to 0."""
    doc = _strip(0.3)
    if not dampers:
        for j in doc.movable_joint_names:
            doc.set_damping(j, 0.0)
    set_rayleigh(doc, Rayleigh(alpha, beta))
    return doc


# -- the model's FRF ------------------------------------------------------------------------
def test_one_mass_with_rayleigh_damping_is_the_closed_form():
    m, k, d, alpha, beta = 0.5, 2e3, 0.3, 1.5, 4e-4
    doc = one_mass(m, k, d)
    set_rayleigh(doc, Rayleigh(alpha, beta))
    H = build_affine_model(doc).linear_model().frf(FREQ)[0, 0]
    w = 2 * np.pi * FREQ
    expected = 1.0 / (k - m * w**2 + 1j * w * (d + alpha * m + beta * k))
    assert np.max(np.abs(H - expected) / np.abs(expected)) < EXACT_TOL


def test_strip_with_rayleigh_damping_is_a_direct_solve_and_matches_python_control():
    """D assembled by bondid = the joint dampers + α·M + β·K of the model without the element,
    solved directly with numpy; and the state-space peer (python-control) agrees."""
    control = pytest.importorskip("control")
    doc = _proportional(dampers=True)
    plain = _strip(0.3)
    lm0 = build_affine_model(plain).linear_model()
    M, K, D0, B, C = lm0.M, lm0.K, lm0.D, lm0.B, lm0.C
    w = 2 * np.pi * FREQ
    Z = (
        K[None]
        - w[:, None, None] ** 2 * M[None]
        + 1j * w[:, None, None] * (D0 + ALPHA * M + BETA * K)[None]
    )
    direct = np.einsum("on,fni->oif", C, np.linalg.solve(Z, np.broadcast_to(B, (w.size, *B.shape))))
    lm = build_affine_model(doc).linear_model()
    H = lm.frf(FREQ)
    assert np.max(np.abs(H - direct)) <= EXACT_TOL * np.max(np.abs(direct))
    A, Bs, Cs, Ds = lm.state_space()
    resp = control.ss(A, Bs, Cs, Ds).frequency_response(w)
    peer = np.asarray(resp.complex).reshape(H.shape)
    err = np.linalg.norm(H - peer, axis=(0, 1)) / np.linalg.norm(peer, axis=(0, 1))
    assert np.max(err) < TOL_PEER


def test_modes_of_a_proportional_model_have_the_rayleigh_ratios():
    """ζ_i = α/(2ω_i) + βω_i/2 exactly for D = αM + βK (and |λ_i| = ω_i)."""
    lm = build_affine_model(_proportional()).linear_model()
    modes = underdamped(lm.M, lm.K, lm.D)
    assert len(modes) == 4
    for f, zeta in modes:
        w = 2 * np.pi * f
        assert zeta == pytest.approx(ALPHA / (2 * w) + BETA * w / 2, rel=1e-9)


# -- exact derivatives ----------------------------------------------------------------------
NAMES = ["rayleigh.alpha", "rayleigh.beta", "b0.stiffness", "t1.stiffness", "s0.mass",
         "s0.com.x", "s1.inertia.ixx", "t0.damping"]  # fmt: skip


def test_frf_jacobian_includes_the_rayleigh_terms():
    """dH/dp with α·∂M/∂p and β·∂K/∂p in the damping, and dH/dα, dH/dβ, against central
    differences of the plain engine."""
    doc = _proportional(0.6, 3e-4, dampers=True)
    frf_error, errors = frf_jacobian_errors(doc, NAMES, FREQ, ("acc", "patch"))
    assert frf_error <= EXACT_TOL
    assert all(e <= JAC_FD_TOL for e in errors.values()), errors


@pytest.mark.parametrize("gain", [False, True])
def test_residual_jacobian_with_rayleigh_matches_finite_differences(gain):
    """The cost's Jacobian rows (the whole-grid path, and with a free gain the selected-points
    path) in the named parameters."""
    doc = _proportional(0.6, 3e-4, dampers=True)
    names = list(NAMES)
    if gain:
        doc.set_gain("gain.in.patch", 2.0)
        names.append("gain.in.patch")
    data = simulate(_proportional(dampers=True), freq_hz=FREQ, outputs=("acc", "patch"))
    problem = FrfProblem(doc, [data])
    pmap = ParameterMap(doc, problem.affines[0], names)
    x0 = pmap.p0
    r0, J = problem.residual_and_jacobian(pmap, x0)
    assert np.allclose(r0, problem.residual(pmap, x0), rtol=0, atol=1e-12)
    for k, name in enumerate(names):
        h = 1e-6 * abs(x0[k])
        e = np.zeros_like(x0)
        e[k] = h
        fd = (problem.residual(pmap, x0 + e) - problem.residual(pmap, x0 - e)) / (2 * h)
        assert np.max(np.abs(J[:, k] - fd)) <= JAC_FD_TOL * np.max(np.abs(J[:, k])), name


def test_fit_problem_jacobian_in_the_decision_vector():
    """The fit's decision vector (scaled Rayleigh entries, Cholesky bodies) with a tie."""
    doc = _proportional(0.6, 3e-4, dampers=True)
    data = simulate(_proportional(dampers=True), freq_hz=FREQ, outputs=("acc", "patch"))
    names = ["rayleigh.alpha", "rayleigh.beta", "b0.stiffness", "s0.mass", "b0.damping"]
    problem = FitProblem(doc, [data], names, ties={"b0.damping": [("b1.damping", 1.0)]})
    z0 = problem.z0 * 1.1
    r0, J = problem.residual_and_jacobian(z0)
    top = np.abs(J).max()  # a body entry the FRF hardly sees: round-off against the largest
    fixed = problem.lbz == problem.ubz  # held entries: IPOPT never moves them, J is 0 there
    assert np.all(J[:, fixed] == 0.0)
    for k in np.flatnonzero(~fixed):
        h = 1e-6 * max(abs(z0[k]), 1.0)
        e = np.zeros_like(z0)
        e[k] = h
        fd = (problem.residual(z0 + e) - problem.residual(z0 - e)) / (2 * h)
        scale = max(np.max(np.abs(J[:, k])), 1e-3 * top)
        assert np.max(np.abs(J[:, k] - fd)) <= JAC_FD_TOL * scale, k
    assert np.allclose(r0, problem.residual(z0), rtol=0, atol=1e-12)


# -- the start -------------------------------------------------------------------------------
def test_least_squares_recovers_the_coefficients_from_exact_ratios():
    f = np.array([3.0, 12.0, 40.0, 150.0])
    w = 2 * np.pi * f
    a, b = fit_coefficients(f, ALPHA / (2 * w) + BETA * w / 2)
    assert a == pytest.approx(ALPHA, rel=START_RTOL)
    assert b == pytest.approx(BETA, rel=START_RTOL)


def test_start_of_a_proportionally_damped_model_is_its_own_coefficients():
    start = rayleigh_start(build_affine_model(_proportional()), (1.0, 300.0))
    assert start.alpha == pytest.approx(ALPHA, rel=START_RTOL)
    assert start.beta == pytest.approx(BETA, rel=START_RTOL)
    assert "4 mode(s)" in start.how


def test_start_without_damping_is_small_and_positive():
    doc = _strip(0.3)
    for j in doc.movable_joint_names:
        doc.set_damping(j, 0.0)
    start = rayleigh_start(build_affine_model(doc), (1.0, 300.0))
    assert start.alpha > 0 and start.beta > 0 and "no damped mode" in start.how
    # each alone gives at most half a percent in the band's modes
    for f, _ in underdamped(*(getattr(build_affine_model(doc).linear_model(), m) for m in "MKD")):
        w = 2 * np.pi * f
        assert start.alpha / (2 * w) <= 0.005 + 1e-12 and start.beta * w / 2 <= 0.005 + 1e-12


# -- the model element and the parameters ------------------------------------------------------
def test_element_is_a_pair_of_parameters_and_survives_write_and_read(tmp_path):
    doc = _proportional()
    assert {"rayleigh.alpha", "rayleigh.beta"} <= set(parameter_names(doc))
    assert "rayleigh.alpha" not in parameter_names(_strip(0.3))
    assert get_parameter(doc, "rayleigh.beta") == BETA
    set_parameter(doc, "rayleigh.alpha", 1.25)
    doc.write(tmp_path / "s.urdf")
    back = UrdfDocument.load(tmp_path / "s.urdf")
    assert model_rayleigh(back) == Rayleigh(1.25, BETA)
    assert set(select_parameters(back, ["rayleigh.*"])) == {"rayleigh.alpha", "rayleigh.beta"}
    assert "rayleigh.alpha" in select_parameters(back, ["default"])
    # other URDF readers ignore the element: Pinocchio builds the same model
    assert back.build_pinocchio_model().nv == _strip(0.3).build_pinocchio_model().nv


def test_negative_coefficient_is_refused():
    with pytest.raises(ParameterError, match="negative"):
        set_parameter(_proportional(), "rayleigh.beta", -1e-6)


@pytest.mark.parametrize(
    ("element", "needle"),
    [
        ('<rayleigh_damping alpha="-1" beta="0"/>', "alpha '-1' is not a finite number >= 0"),
        ('<rayleigh_damping alpha="0" beta="x"/>', "beta 'x' is not a finite number"),
        ('<rayleigh_damping alpha="1" gamma="0"/>', "unknown attribute 'gamma'"),
        ('<rayleigh_damping alpha="1"/><rayleigh_damping beta="1"/>', "2 <rayleigh_damping>"),
    ],
)
def test_bad_elements_name_the_file_and_what_is_valid(element, needle):
    xml = _strip(0.3).to_string().replace("</robot>", element + "</robot>")
    doc = UrdfDocument.from_string(xml, source="m.urdf")
    with pytest.raises(ModelError, match=needle) as err:
        build_affine_model(doc)
    assert str(err.value).startswith("m.urdf")


# -- the damping models --------------------------------------------------------------------------
def test_rayleigh_only_zeroes_the_dampers_and_starts_from_their_modal_damping():
    doc = _strip(0.3)
    how = declare_damping(doc, "rayleigh-only", band_hz=(1.0, 300.0))
    assert how is not None and how.startswith("least squares")
    assert all(doc.damping(j) == 0.0 for j in doc.movable_joint_names)
    r = model_rayleigh(doc)
    assert r is not None and r.alpha > 0 and r.beta > 0
    free, fixed = damping_free(doc, "rayleigh-only", ["all", "*.damping"], [])
    assert not [n for n in select_parameters(doc, free, fixed) if n.endswith(".damping")]


def test_rayleigh_keeps_the_dampers_and_frees_them_only_by_name():
    doc = _strip(0.3)
    declare_damping(doc, "rayleigh", band_hz=(1.0, 300.0))
    assert doc.damping("b0") == 0.002
    free, fixed = damping_free(doc, "rayleigh", ["default"], [])
    names = select_parameters(doc, free, fixed)
    assert {"rayleigh.alpha", "rayleigh.beta"} <= set(names)
    assert not [n for n in names if n.endswith(".damping")]
    free, fixed = damping_free(doc, "rayleigh", ["default", "b*.damping"], [])
    assert {"b0.damping", "b1.damping"} == {
        n for n in select_parameters(doc, free, fixed) if n.endswith(".damping")
    }


def test_model_keeps_and_joints_drops_the_element():
    doc = _proportional()
    assert declare_damping(doc, "model") is None and model_rayleigh(doc) is not None
    assert declare_damping(doc, "rayleigh") == "the model's <rayleigh_damping>"
    assert model_rayleigh(doc) == Rayleigh(ALPHA, BETA)
    declare_damping(doc, "joints")
    assert model_rayleigh(doc) is None


@pytest.mark.parametrize(
    ("value", "needle"),
    [
        ("viscous", "damping.kind 'viscous'; valid: model, joints, rayleigh, rayleigh-only"),
        ({"kind": "rayleigh", "alpha": 1.0}, "give both alpha"),
        ({"kind": "rayleigh", "alpha": -1.0, "beta": 0.0}, "alpha -1.0 is not a finite"),
        ({"kind": "model", "alpha": 1.0, "beta": 0.0}, "need kind rayleigh"),
        ({"kind": "rayleigh", "zeta": 0.01}, "damping.zeta: unknown key"),
        (3, "is not a kind or a table"),
    ],
)
def test_bad_study_damping_names_the_key(value, needle):
    with pytest.raises(ConfigError, match=needle) as err:
        damping_from_study(value, "s.toml")
    assert str(err.value).startswith("s.toml")


def test_bad_values_exit_2(tmp_path, capsys):
    from bondid.data.io import write_frf
    from bondid.fit.cli import main

    _strip(0.3).write(tmp_path / "m.urdf")
    write_frf(simulate(_proportional(), freq_hz=FREQ, outputs=("acc",)), tmp_path / "d.csv")
    base = ["--model", str(tmp_path / "m.urdf"), "--data", str(tmp_path / "d.csv"), "--quiet"]
    assert main([*base, "--damping", "modal"]) == 2
    (tmp_path / "s.toml").write_text('damping = {kind = "rayleigh", alpha = -1, beta = 0}\n')
    assert main([*base, "--study", str(tmp_path / "s.toml")]) == 2
    assert "damping: Rayleigh alpha -1 is not a finite number >= 0" in capsys.readouterr().err
    bad = _strip(0.3).to_string().replace("</robot>", '<rayleigh_damping alpha="nan"/></robot>')
    (tmp_path / "bad.urdf").write_text(bad)
    assert main(["--model", str(tmp_path / "bad.urdf"), *base[2:]]) == 2


def test_sensitivity_takes_the_damping_model(tmp_path):
    """``bondid.sensitivity --damping rayleigh-only`` analyses α and β, not the dampers."""
    from bondid.data.io import write_frf
    from bondid.sensitivity.__main__ import main

    write_frf(simulate(_proportional(), freq_hz=FREQ, outputs=("acc",)), tmp_path / "d.csv")
    _strip(0.3).write(tmp_path / "m.urdf")
    out = tmp_path / "out"
    args = ["--model", str(tmp_path / "m.urdf"), "--data", str(tmp_path / "d.csv"),
            "--damping", "rayleigh-only", "--no-sweep", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    names = {p["name"] for p in json.loads((out / "sensitivity.json").read_text())["parameters"]}
    assert {"rayleigh.alpha", "rayleigh.beta"} <= names
    assert not [n for n in names if n.endswith(".damping")]


def test_diagnosis_refits_the_coefficients(tmp_path):
    """``bondid.diagnose --damping rayleigh-only``: the parameter refit moves α and β, and
    the refitted model carries them."""
    from bondid.data.io import write_frf
    from bondid.diagnose.cli import main

    data = simulate(_proportional(), freq_hz=FREQ, outputs=("acc",), noise=0.01, seed=3)
    write_frf(data, tmp_path / "d.csv")
    _strip(0.3).write(tmp_path / "m.urdf")
    out = tmp_path / "out"
    args = ["--model", str(tmp_path / "m.urdf"), "--data", str(tmp_path / "d.csv"),
            "--damping", "rayleigh-only", "--free", "*.stiffness", "--effects", "sensor_delay",
            "--workers", "1", "--no-plots", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    refit = model_rayleigh(UrdfDocument.load(out / "refit.urdf"))
    assert refit is not None
    assert refit.alpha == pytest.approx(ALPHA, rel=RECOVER_RTOL), refit
    assert refit.beta == pytest.approx(BETA, rel=RECOVER_RTOL), refit


# -- known answers ----------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["rayleigh-only", "rayleigh"])
def test_fit_recovers_alpha_and_beta_at_the_noise_level(tmp_path, kind):
    """Data of the strip damped by (α, β) = (0.8 1/s, 2e-4 s) — alone (``rayleigh-only``) or
    on top of its joint dampers (``rayleigh``) — with 1 % noise; the model starts from its
    joint dampers (no element), fits α, β and the springs."""
    from bondid.data.io import write_frf
    from bondid.fit.cli import main

    truth = _proportional(dampers=kind == "rayleigh")
    freq = np.geomspace(2.0, 200.0, 400)
    write_frf(
        simulate(truth, freq_hz=freq, outputs=("acc",), noise=0.01, seed=1), tmp_path / "d.csv"
    )
    _strip(0.3).write(tmp_path / "m.urdf")
    out = tmp_path / "out"
    args = ["--model", str(tmp_path / "m.urdf"), "--data", str(tmp_path / "d.csv"),
            "--damping", kind, "--free", "*.stiffness", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    fit = json.loads((out / "fit.json").read_text())
    got = {p["name"]: p for p in fit["parameters"]}
    for name, true in (("rayleigh.alpha", ALPHA), ("rayleigh.beta", BETA)):
        p = got[name]
        assert p["unit"] == ("1/s" if name.endswith("alpha") else "s")
        assert abs(p["fitted"] - true) <= RECOVER_SIGMAS * p["std"], (name, p)
        assert p["fitted"] == pytest.approx(true, rel=RECOVER_RTOL), (name, p)
    assert not [n for n in got if n.endswith(".damping")]
    assert fit["db_rms"]["final"] <= AT_NOISE * fit["db_rms"]["noise_level"]
    assert (
        fit["damping"]["kind"] == kind
        and fit["damping"]["alpha"] == got["rayleigh.alpha"]["fitted"]
    )
    refined = model_rayleigh(UrdfDocument.load(out / "fitted.urdf"))
    assert refined == Rayleigh(got["rayleigh.alpha"]["fitted"], got["rayleigh.beta"]["fitted"])


@pytest.mark.slow
def test_free_free_beam_recovers_proportional_damping(tmp_path):
    """The worked example's free-free chain (floating base, rigid-body modes at 0 Hz), its
    truth damped by α·M + β·K alone, accelerance at 1 % noise; the model as written (one
    damper per joint) fitted with ``--damping rayleigh-only``."""
    from pathlib import Path

    from bondid.data.io import write_frf
    from bondid.fit.cli import main
    from bondid.model.authoring import add_floating_base

    src = Path(__file__).resolve().parents[1] / "examples" / "free_free_beam" / "beam_chain.urdf"
    truth = UrdfDocument.load(src)
    add_floating_base(truth)
    for j in truth.movable_joint_names:
        truth.set_damping(j, 0.0)
    alpha, beta = 3.0, 4e-6
    set_rayleigh(truth, Rayleigh(alpha, beta))
    freq = np.geomspace(5.0, 1000.0, 600)
    data = simulate(truth, freq_hz=freq, outputs=("acc",), noise=0.01, seed=2,
                    quantity="accelerance")  # fmt: skip
    write_frf(data, tmp_path / "d.csv")
    out = tmp_path / "out"
    args = ["--model", str(src), "--floating-base", "--data", str(tmp_path / "d.csv"),
            "--damping", "rayleigh-only", "--free", "*.stiffness", "--quiet",
            "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    fit = json.loads((out / "fit.json").read_text())
    got = {p["name"]: p for p in fit["parameters"]}
    for name, true in (("rayleigh.alpha", alpha), ("rayleigh.beta", beta)):
        assert abs(got[name]["fitted"] - true) <= RECOVER_SIGMAS * got[name]["std"], name
        assert got[name]["fitted"] == pytest.approx(true, rel=RECOVER_RTOL), name
    assert fit["db_rms"]["final"] <= AT_NOISE * fit["db_rms"]["noise_level"]
