"""A structural loss factor ``η``: the stiffness ``K (1 + jη)``. The model's FRF against closed
forms and a direct solve, its viscous equivalent for the modes, exact derivatives against
central differences, the model element and ``--damping structural``, and a known-answer fit."""

from __future__ import annotations

import json

import numpy as np
import pytest
from models import central_columns, central_jacobian, frf_jacobian_errors, one_mass
from test_ties_mix import _strip

from bondid.cost.problem import FrfProblem
from bondid.exceptions import ConfigError, ModelError
from bondid.linear.affine import build_affine_model
from bondid.linear.linear_model import underdamped
from bondid.linear.parameter_map import ParameterMap
from bondid.model import UrdfDocument
from bondid.model.parameters import parameter_names
from bondid.model.rayleigh import Rayleigh, model_rayleigh, set_rayleigh
from bondid.optim.problem import FitProblem
from bondid.setup.damping import damping_free, damping_from_study, declare_damping
from bondid.simulate import simulate

#: two exact computations of one FRF (round-off only, relative)
EXACT_TOL = 1e-10
#: analytic Jacobians against central differences (relative to the column's largest entry)
JAC_FD_TOL = 1e-6
#: a fit at 1 % noise recovers η within this many of its own std …
RECOVER_SIGMAS = 4.0
#: … and within this fraction of the truth
RECOVER_RTOL = 0.05
#: the fitted db_rms is "at the noise level" within this factor of the predicted level
AT_NOISE = 1.10
#: the state space (viscous equivalent) against the exact FRF at the undamped natural
#: frequencies (relative, matrix norm): equal there but for the neighbouring modes' share
RESONANCE_TOL = 2e-3

ETA = 0.012  # the truth's loss factor: ζ = 0.6 % at every mode
FREQ = np.geomspace(2.0, 200.0, 90)


def _lossy(eta: float = ETA, dampers: bool = False, alpha: float = 0.0) -> UrdfDocument:
    """The strip (bending and torsion joints, a patch and an accelerometer) with a loss
    factor, its joint dampers kept or set to 0."""
    doc = _strip(0.3)
    if not dampers:
        for j in doc.movable_joint_names:
            doc.set_damping(j, 0.0)
    set_rayleigh(doc, Rayleigh(alpha, 0.0, eta))
    return doc


# -- the model's FRF ------------------------------------------------------------------------
def test_one_mass_with_a_loss_factor_is_the_closed_form():
    m, k, d, eta = 0.5, 2e3, 0.3, 0.02
    doc = one_mass(m, k, d)
    set_rayleigh(doc, Rayleigh(0.0, 0.0, eta))
    H = build_affine_model(doc).linear_model().frf(FREQ)[0, 0]
    w = 2 * np.pi * FREQ
    expected = 1.0 / (k * (1 + 1j * eta) - m * w**2 + 1j * w * d)
    assert np.max(np.abs(H - expected) / np.abs(expected)) < EXACT_TOL


def test_strip_with_a_loss_factor_is_a_direct_solve():
    """K(1 + jη) with K the stiffness of the model without the element (joint springs and
    gravity stiffness), solved directly with numpy, the joint dampers and α·M beside it."""
    doc = _lossy(dampers=True, alpha=0.5)
    lm0 = build_affine_model(_strip(0.3)).linear_model()
    M, K, D, B, C = lm0.M, lm0.K, lm0.D + 0.5 * lm0.M, lm0.B, lm0.C
    w = 2 * np.pi * FREQ
    Z = K[None] * (1 + 1j * ETA) - w[:, None, None] ** 2 * M[None] + 1j * w[:, None, None] * D
    expected = np.einsum(
        "on,fni->oif", C, np.linalg.solve(Z, np.broadcast_to(B, (w.size, *B.shape)))
    )
    H = build_affine_model(doc).linear_model().frf(FREQ)
    assert np.max(np.abs(H - expected)) <= EXACT_TOL * np.abs(expected).max()


def test_viscous_equivalent_damps_every_mode_by_half_the_loss_factor():
    """A loss factor alone: the modes and the state space see ζ = η/2 at every mode, at the
    undamped frequencies; without one, ``viscous()`` is the model itself."""
    lm = build_affine_model(_lossy()).linear_model()
    undamped = underdamped(lm.M, lm.K, np.zeros_like(lm.M))
    modes = underdamped(lm.M, lm.K, lm.viscous().D)
    assert len(modes) == len(undamped) == 4
    for (f, zeta), (f0, _) in zip(modes, undamped, strict=True):
        assert zeta == pytest.approx(ETA / 2, rel=1e-8)
        assert f * np.sqrt(1 - zeta**2) == pytest.approx(f0 * np.sqrt(1 - zeta**2), rel=1e-8)
    plain = build_affine_model(_strip(0.3)).linear_model()
    assert plain.G is None and plain.viscous() is plain


def test_state_space_matches_the_exact_frf_at_the_resonances():
    """python-control's response of the state space (the loss factor as its viscous
    equivalent) against the exact FRF: equal at each undamped natural frequency (where the
    equivalent dissipates as the loss factor does), apart elsewhere."""
    control = pytest.importorskip("control")
    lm = build_affine_model(_lossy()).linear_model()
    f0 = np.array([f for f, _ in underdamped(lm.M, lm.K, np.zeros_like(lm.M))])
    A, Bs, Cs, Ds = lm.state_space()
    sys = control.ss(A, Bs, Cs, Ds)

    def gap(freq):
        H = lm.frf(freq)
        peer = np.asarray(sys.frequency_response(2 * np.pi * freq).complex).reshape(H.shape)
        return np.linalg.norm(H - peer, axis=(0, 1)) / np.linalg.norm(H, axis=(0, 1))

    at_modes, between = gap(f0), gap(np.sqrt(f0[:-1] * f0[1:]))
    assert np.max(at_modes) < RESONANCE_TOL
    assert np.min(between) > 3 * np.max(at_modes)


def test_modal_analysis_reports_the_loss_factor_as_damping():
    from bondid.modes.analysis import modal_analysis

    result = modal_analysis(build_affine_model(_lossy()).linear_model())
    vib = result.vibration_modes()
    assert len(vib) == 4
    assert all(m.zeta == pytest.approx(ETA / 2, rel=1e-6) for m in vib)


# -- exact derivatives ----------------------------------------------------------------------
NAMES = ["rayleigh.eta", "rayleigh.alpha", "b0.stiffness", "t1.stiffness", "s0.mass",
         "s0.com.x", "s1.inertia.ixx", "t0.damping"]  # fmt: skip


def test_frf_jacobian_includes_the_loss_terms():
    """dH/dp with η·∂K/∂p in the hysteretic part, and dH/dη, against central differences of
    the plain engine."""
    doc = _lossy(dampers=True, alpha=0.4)
    frf_error, errors = frf_jacobian_errors(doc, NAMES, FREQ, ("acc", "patch"), floor=1e-3)
    assert frf_error <= EXACT_TOL
    assert all(e <= JAC_FD_TOL for e in errors.values()), errors


def test_residual_and_decision_vector_jacobians_with_a_loss_factor():
    """The cost's Jacobian in the named parameters, and the fit's decision vector (a scaled η
    entry, Cholesky bodies), against central differences."""
    doc = _lossy(dampers=True)
    data = simulate(_lossy(0.02, dampers=True), freq_hz=FREQ, outputs=("acc", "patch"))
    problem = FrfProblem(doc, [data])
    names = ["rayleigh.eta", "b0.stiffness", "s0.mass", "t0.damping"]
    pmap = ParameterMap(doc, problem.affines[0], names)
    x0 = pmap.p0
    _, J = problem.residual_and_jacobian(pmap, x0)
    fd = central_jacobian(problem, pmap, x0, 0.0)
    for k, name in enumerate(names):
        assert np.max(np.abs(J[:, k] - fd[:, k])) <= JAC_FD_TOL * np.max(np.abs(J[:, k])), name
    fit = FitProblem(doc, [data], names)
    z0 = fit.z0 * 1.1
    _, Jz = fit.residual_and_jacobian(z0)
    top = np.abs(Jz).max()
    free = fit.lbz != fit.ubz
    for k, col in central_columns(fit.residual, z0, 1.0):
        if free[k]:
            scale = max(np.max(np.abs(Jz[:, k])), 1e-3 * top)
            assert np.max(np.abs(Jz[:, k] - col)) <= JAC_FD_TOL * scale, k


# -- the model element and the damping model ------------------------------------------------
def test_the_loss_factor_is_a_parameter_only_when_declared(tmp_path):
    doc = _strip(0.3)
    set_rayleigh(doc, Rayleigh(0.5, 1e-4))
    assert "rayleigh.eta" not in parameter_names(doc)
    set_rayleigh(doc, Rayleigh(0.5, 1e-4, 0.01))
    assert "rayleigh.eta" in parameter_names(doc)
    doc.write(tmp_path / "m.urdf")
    assert model_rayleigh(UrdfDocument.load(tmp_path / "m.urdf")) == Rayleigh(0.5, 1e-4, 0.01)


@pytest.mark.parametrize("attr", ['eta="-0.1"', 'eta="x"', 'eta="nan"'])
def test_a_bad_loss_factor_names_the_file_and_what_is_valid(tmp_path, attr):
    doc = _strip(0.3)
    doc.write(tmp_path / "m.urdf")
    text = (tmp_path / "m.urdf").read_text()
    text = text.replace("</robot>", f'<rayleigh_damping alpha="0" beta="0" {attr}/></robot>')
    (tmp_path / "m.urdf").write_text(text)
    with pytest.raises(ModelError, match=r"m\.urdf.*eta.*>= 0 \(dimensionless\)"):
        model_rayleigh(UrdfDocument.load(tmp_path / "m.urdf"))


def test_structural_zeroes_the_dampers_and_frees_only_the_loss_factor():
    """The start is twice the median damping ratio the dampers gave the modes; α and β are
    held at 0 unless named."""
    doc = _strip(0.3)
    lm = build_affine_model(doc).linear_model()
    zetas = [z for _, z in underdamped(lm.M, lm.K, lm.D)]
    how = declare_damping(doc, "structural")
    declared = model_rayleigh(doc)
    assert declared is not None and declared.alpha == declared.beta == 0.0
    assert declared.eta == pytest.approx(2 * np.median(zetas), rel=1e-9)
    assert how is not None and "median" in how
    assert all(doc.damping(j) == 0.0 for j in doc.movable_joint_names)
    free, fixed = damping_free(doc, "structural", ["*.stiffness"], [])
    assert "rayleigh.eta" in free and "rayleigh.alpha" not in free
    assert {"rayleigh.alpha", "rayleigh.beta"} <= set(fixed)
    free, fixed = damping_free(doc, "structural", ["*.stiffness", "rayleigh.alpha"], [])
    assert "rayleigh.alpha" not in fixed


def test_study_declares_a_loss_factor_and_refuses_it_elsewhere():
    assert damping_from_study({"kind": "structural", "eta": 0.01}, "s.toml") == (
        "structural",
        (0.01,),
    )
    assert damping_from_study("structural", "s.toml") == ("structural", None)
    with pytest.raises(ConfigError, match=r"s\.toml: damping: eta needs kind structural"):
        damping_from_study({"kind": "rayleigh", "eta": 0.01}, "s.toml")
    with pytest.raises(ConfigError, match=r"s\.toml: damping: alpha and beta need kind"):
        damping_from_study({"kind": "structural", "alpha": 1.0, "beta": 0.0}, "s.toml")


# -- a known answer -------------------------------------------------------------------------
def test_fit_recovers_the_loss_factor_at_the_noise_level(tmp_path):
    """Data of the strip damped by a loss factor alone with 1 % noise; the model as written
    (one damper per joint) fitted with ``--damping structural`` and its springs free."""
    from bondid.data.io import write_frf
    from bondid.fit.cli import main

    freq = np.geomspace(2.0, 200.0, 400)
    write_frf(
        simulate(_lossy(), freq_hz=freq, outputs=("acc",), noise=0.01, seed=1), tmp_path / "d.csv"
    )
    _strip(0.3).write(tmp_path / "m.urdf")
    out = tmp_path / "out"
    args = ["--model", str(tmp_path / "m.urdf"), "--data", str(tmp_path / "d.csv"),
            "--damping", "structural", "--free", "*.stiffness", "--quiet",
            "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    fit = json.loads((out / "fit.json").read_text())
    got = {p["name"]: p for p in fit["parameters"]}
    eta = got["rayleigh.eta"]
    assert eta["unit"] == "1"
    assert abs(eta["fitted"] - ETA) <= RECOVER_SIGMAS * eta["std"], eta
    assert eta["fitted"] == pytest.approx(ETA, rel=RECOVER_RTOL), eta
    assert "rayleigh.alpha" not in got and not [n for n in got if n.endswith(".damping")]
    assert fit["db_rms"]["final"] <= AT_NOISE * fit["db_rms"]["noise_level"]
    assert fit["damping"]["kind"] == "structural" and fit["damping"]["eta"] == eta["fitted"]
    fitted = model_rayleigh(UrdfDocument.load(out / "fitted.urdf"))
    assert fitted == Rayleigh(0.0, 0.0, eta["fitted"])


def test_sensitivity_and_diagnosis_take_the_loss_factor(tmp_path):
    """``bondid.sensitivity --damping structural`` analyses η, not the dampers; ``bondid.diagnose
    --damping structural``'s parameter refit moves η to the truth's and keeps it."""
    from bondid.data.io import write_frf
    from bondid.diagnose.cli import main as diagnose
    from bondid.sensitivity.__main__ import main as sensitivity

    data = simulate(_lossy(), freq_hz=FREQ, outputs=("acc",), noise=0.01, seed=3)
    write_frf(data, tmp_path / "d.csv")
    _strip(0.3).write(tmp_path / "m.urdf")
    base = ["--model", str(tmp_path / "m.urdf"), "--data", str(tmp_path / "d.csv"),
            "--damping", "structural", "--quiet"]  # fmt: skip
    out = tmp_path / "sens"
    assert sensitivity([*base, "--no-sweep", "--out", str(out)]) == 0
    names = {p["name"] for p in json.loads((out / "sensitivity.json").read_text())["parameters"]}
    assert "rayleigh.eta" in names and not [n for n in names if n.endswith(".damping")]
    out = tmp_path / "diag"
    args = [*base, "--free", "*.stiffness", "--effects", "sensor_delay", "--workers", "1",
            "--no-plots", "--out", str(out)]  # fmt: skip
    assert diagnose(args) == 0
    refit = model_rayleigh(UrdfDocument.load(out / "refit.urdf"))
    assert refit is not None and refit.alpha == refit.beta == 0.0
    assert refit.eta == pytest.approx(ETA, rel=RECOVER_RTOL), refit


def test_free_mimic_multipliers_keep_a_held_loss_factor():
    """The multipliers of a free pivot rebuild the reduced model at every evaluation; the
    loss factor the model declares (held) stays in it: the model scores 0 on its own FRF,
    and a model without the loss factor does not."""
    from test_free_pivot import _freed

    free, _ = _freed()
    set_rayleigh(free, Rayleigh(0.0, 0.0, 0.05))
    data = simulate(free, freq_hz=np.geomspace(5.0, 500.0, 80))
    names = ["x_guide_ry_pivot_u.multiplier", "x_guide_ry_pivot_v.multiplier"]
    problem = FrfProblem(free, [data])
    pm = ParameterMap(free, problem.blocks[0].affine, names)
    assert np.max(np.abs(problem.residual(pm, pm.p0))) <= EXACT_TOL
    lossless, _ = _freed()
    problem = FrfProblem(lossless, [data])
    pm = ParameterMap(lossless, problem.blocks[0].affine, names)
    assert np.max(np.abs(problem.residual(pm, pm.p0))) > 1e3 * EXACT_TOL


def test_resonances_and_anti_resonances_are_damped_by_half_the_loss_factor():
    """The features the diagnosis pairs with the data: every resonance of the bonder and
    every anti-resonance of its ``x.x`` channel (the system clamped at ``x``) at ζ = η/2."""
    from bondid.modes.bands import model_features

    doc = UrdfDocument.load("urdf/bonder.urdf")
    for j in doc.movable_joint_names:
        doc.set_damping(j, 0.0)
    set_rayleigh(doc, Rayleigh(0.0, 0.0, ETA))
    feats = model_features(build_affine_model(doc), channels=["x.x"])
    kinds = {f.kind for f in feats}
    assert kinds == {"resonance", "anti-resonance"}
    assert all(f.zeta == pytest.approx(ETA / 2, rel=1e-6) for f in feats), feats


def test_the_summary_line_states_the_loss_factor_and_its_damping_ratio():
    from bondid.setup.damping import damping_line

    line = damping_line({"kind": "structural", "start": "as given", "alpha": 0.0, "beta": 0.0,
                         "eta": 0.012})  # fmt: skip
    assert line is not None
    assert "K·(1 + jη), η = 0.012 (ζ = 0.600% at every mode" in line
    assert line.endswith("η started from as given")
    line = damping_line({"kind": "rayleigh", "start": None, "alpha": 1.0, "beta": 2e-6,
                         "eta": 0.01})  # fmt: skip
    assert line is not None and "loss factor η = 0.01" in line
