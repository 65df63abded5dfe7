"""Parameter ties declared in the model (bondid.model.ties): one value for a glob of joint
springs or dampers, link masses, CoM or inertia components, kept in the URDF, fitted as one
parameter with exact derivatives."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_points import _free_chain

from bondid.exceptions import ModelError, ParameterError
from bondid.fit import fit
from bondid.linear.affine import build_affine_model
from bondid.linear.parameter_map import ParameterMap
from bondid.model import UrdfDocument
from bondid.model.parameters import (
    get_parameter,
    get_parameters,
    select_parameters,
    set_parameter,
)
from bondid.model.points import Point
from bondid.model.tie_declaration import declare_tie
from bondid.model.ties import leader_ties, model_ties
from bondid.optim.problem import FitProblem
from bondid.optim.tied import TiedParameters
from bondid.simulate import simulate

#: residual Jacobian against central differences (relative to its largest entry) with a
#: relative step FD_STEP: the residual's round-off (deep anti-resonances of the chain) keeps
#: the differences from agreeing better
JAC_FD_TOL = 1e-5
FD_STEP = 1e-4
#: a noise-free fit recovers the truth's values to this (relative)
RECOVER_RTOL = 1e-6
#: tied inertial members agree to this (relative) at a fit's end: IPOPT's constraint tolerance
TIE_ATOL = 1e-7

N = 4  # masses of the free-free chain (joints j1..j3 carry springs and dampers)
DAMPERS = [f"j{i}.damping" for i in range(1, N)]
SPRINGS = [f"j{i}.stiffness" for i in range(1, N)]


def test_declare_tie_equalises_stores_and_survives_write_and_read(tmp_path):
    doc = _free_chain(N)
    first = get_parameter(doc, "j1.damping")
    tie = declare_tie(doc, "damping", ["j[1-9].damping"], "--tie")
    assert tie.members == tuple(DAMPERS)
    assert all(get_parameter(doc, n) == first for n in DAMPERS)
    doc.write(tmp_path / "m.urdf")
    back = UrdfDocument.load(tmp_path / "m.urdf")
    assert model_ties(back) == [tie]
    # other URDF readers ignore the element
    import pinocchio as pin

    pin.buildModelFromUrdf(str(tmp_path / "m.urdf"))


def test_select_parameters_keeps_one_member_of_a_tie():
    doc = _free_chain(N)
    declare_tie(doc, "damping", ["*.damping"], "--tie")
    # j0.damping (0 in the model) is in the glob too: the tie's first chosen member leads
    names = select_parameters(doc, ["joints"])
    assert [n for n in names if n.endswith(".damping")] == ["j0.damping"]
    names = select_parameters(doc, ["joints"], ["j0.damping"])
    assert [n for n in names if n.endswith(".damping")] == ["j1.damping"]
    assert leader_ties(model_ties(doc), names)["j1.damping"] == [
        ("j0.damping", 1.0), ("j2.damping", 1.0), ("j3.damping", 1.0),
    ]  # fmt: skip
    with pytest.raises(ModelError, match="all free"):
        leader_ties(model_ties(doc), ["j1.damping", "j2.damping"])


@pytest.mark.parametrize(
    ("items", "needle"),
    [
        (["*.nothing"], "matches no parameter"),
        (["j1.damping"], "two or more"),
        (["j1.damping", "j2.stiffness"], "of one kind"),
        (["m1.mass", "j1.damping"], "of one kind"),
        (["m1.com.x", "m2.com.y"], "one component"),
        (["m1.inertia.*"], "one component"),
    ],
)
def test_bad_ties_are_refused_naming_the_origin(items, needle):
    with pytest.raises(ParameterError, match=needle) as err:
        declare_tie(_free_chain(N), "t", items, "study.toml")
    assert str(err.value).startswith("study.toml: tie 't'")


def test_a_parameter_in_two_ties_is_refused():
    doc = _free_chain(N)
    declare_tie(doc, "a", ["j1.damping", "j2.damping"], "--tie")
    with pytest.raises(ParameterError, match="already in tie 'a'"):
        declare_tie(doc, "b", ["j2.damping", "j3.damping"], "--tie")


def test_tied_residual_jacobian_matches_finite_differences():
    """The fit's residual Jacobian in the named parameters (the tied damping as one) against
    central differences of the residual with every member moved together."""
    doc = _free_chain(N)
    declare_tie(doc, "damping", DAMPERS, "--tie")
    declare_tie(doc, "springs", ["j2.stiffness", "j3.stiffness"], "--tie")
    names = select_parameters(doc, ["j1.damping", "j2.stiffness", "m1.mass"])
    truth = _free_chain(N)
    data = simulate(truth, freq_hz=np.geomspace(5.0, 300.0, 60), outputs=("acc",))
    problem = FitProblem(doc, [data], names)
    am = build_affine_model(doc, outputs=data.outputs)
    pmap = TiedParameters(doc, am, names, problem.ties)
    x0 = get_parameters(doc, names)
    _, J = problem.frf.residual_and_jacobian(pmap, x0)
    for k in range(len(names)):
        h = FD_STEP * abs(x0[k])
        e = np.zeros_like(x0)
        e[k] = h
        fd = (problem.frf.residual(pmap, x0 + e) - problem.frf.residual(pmap, x0 - e)) / (2 * h)
        assert np.max(np.abs(J[:, k] - fd)) <= JAC_FD_TOL * np.max(np.abs(J[:, k]))
    # the members move with their leader: the tie's column is the sum of the members' own
    untied = ParameterMap(doc, am, DAMPERS)
    _, Ju = problem.frf.residual_and_jacobian(untied, get_parameters(doc, DAMPERS))
    k = names.index("j1.damping")
    assert np.allclose(J[:, k], Ju.sum(axis=1), rtol=1e-9, atol=1e-12 * np.abs(Ju).max())


def test_fit_of_a_tie_recovers_the_shared_value_and_writes_it_to_every_member():
    truth = _free_chain(N)
    for n in DAMPERS:
        set_parameter(truth, n, 3.7)
    set_parameter(truth, "j2.stiffness", 1.15 * get_parameter(truth, "j2.stiffness"))
    f = np.geomspace(3.0, 300.0, 150)
    data = simulate(truth, freq_hz=f, outputs=("acc",), noise=0.0)
    model = _free_chain(N)
    declare_tie(model, "damping", DAMPERS, "--tie")
    names = select_parameters(model, [*DAMPERS, "j2.stiffness"])
    assert names == ["j1.damping", "j2.stiffness"]
    res = fit(model, [data], names, max_iter=200, presolve_iter=0)
    assert res.success
    assert res.parameter("j1.damping") == pytest.approx(3.7, rel=RECOVER_RTOL)
    for n in DAMPERS:
        assert get_parameter(res.document, n) == pytest.approx(3.7, rel=RECOVER_RTOL)
    assert model_ties(res.document) == model_ties(model)


def test_fit_cli_tie_option_and_study_table(tmp_path):
    from bondid.fit.cli import main

    truth = _free_chain(N)
    for n in DAMPERS:
        set_parameter(truth, n, 3.7)
    data = simulate(truth, freq_hz=np.geomspace(3.0, 120.0, 120), outputs=("acc",),
                    quantity="accelerance")  # fmt: skip
    keep = [i for i, n in enumerate(data.inputs) if n.startswith("h")]
    data = type(data)(data.freq_hz, data.outputs, tuple(data.inputs[i] for i in keep),
                      data.H[:, keep], data.quantity)  # fmt: skip
    from bondid.data.io import write_frf

    write_frf(data, tmp_path / "d.csv")
    _free_chain(N).write(tmp_path / "m.urdf")
    base = ["--model", str(tmp_path / "m.urdf"), "--data", str(tmp_path / "d.csv"), "--quiet",
            "--presolve", "0", "--free", "*.damping", "j2.stiffness",
            "--fixed", "j0.damping"]  # fmt: skip
    out = tmp_path / "out"
    assert main([*base, "--tie", "j[1-9].damping", "--out", str(out)]) == 0
    fitted = {p["name"]: p["fitted"] for p in json.loads((out / "fit.json").read_text())[
        "parameters"]}  # fmt: skip
    assert set(fitted) == {"j1.damping", "j2.stiffness"}
    assert fitted["j1.damping"] == pytest.approx(3.7, rel=RECOVER_RTOL)
    doc = UrdfDocument.load(out / "fitted.urdf")
    assert [get_parameter(doc, n) for n in DAMPERS] == [fitted["j1.damping"]] * len(DAMPERS)
    study = tmp_path / "s.toml"
    study.write_text('[ties]\ndamping = ["j1.damping", "j2.damping", "j3.damping"]\n')
    out2 = tmp_path / "out2"
    assert main([*base, "--study", str(study), "--out", str(out2)]) == 0
    again = json.loads((out2 / "fit.json").read_text())
    assert again["settings"]["ties"] == {"damping": DAMPERS}
    assert main([*base, "--tie", "*.nothing"]) == 2
    bad = tmp_path / "bad.toml"
    bad.write_text('[ties]\nmixed = ["j1.damping", "j1.stiffness"]\n')
    assert main([*base, "--study", str(bad)]) == 2


def _rotor_chain(izz: tuple[float, ...]) -> UrdfDocument:
    """Rotors on a common z axis: the first sprung to the ground, each next one sprung to the
    one before; a torque input and an angle output on every rotor."""
    parts = ['<robot name="rotors"><link name="ground"/>']
    for i, v in enumerate(izz):
        parent = "ground" if i == 0 else f"r{i - 1}"
        parts.append(
            f'<link name="r{i}"><inertial><mass value="0.5"/><inertia ixx="2e-3" ixy="0"'
            f' ixz="0" iyy="2e-3" iyz="0" izz="{v!r}"/></inertial></link>'
            f'<joint name="k{i}" type="revolute"><parent link="{parent}"/><child link="r{i}"/>'
            '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
            '<dynamics damping="0.02"/></joint>'
            f'<gazebo reference="k{i}"><springStiffness>{50.0 * (i + 1)!r}</springStiffness>'
            "<springReference>0</springReference></gazebo>"
        )
    parts.append("</robot>")
    doc = UrdfDocument.from_string("".join(parts), source="<rotors>")
    for i in range(len(izz)):
        doc.set_point(Point(f"t{i}", f"r{i}", "rotation", (0.0, 0.0, 1.0)))
    return doc


def test_fit_of_inertial_ties_recovers_the_shared_mass_and_inertia():
    """Identical parts: one mass for the chain's sliders, one inertia about the axis for the
    rotors. The model starts from unequal parts (the tie equalises them to its first member's
    value); a noise-free fit recovers the shared values and writes them to every member."""
    truth = _free_chain(N)
    for i in range(1, N):
        set_parameter(truth, f"m{i}.mass", 1.6)
    data = simulate(truth, freq_hz=np.geomspace(3.0, 300.0, 150), outputs=("acc",), noise=0.0)
    model = _free_chain(N)
    masses = [f"m{i}.mass" for i in range(1, N)]
    declare_tie(model, "mass", masses, "--tie")
    names = select_parameters(model, masses)
    assert names == ["m1.mass"]
    res = fit(model, [data], names, max_iter=200, presolve_iter=0)
    assert res.success
    for n in masses:
        assert get_parameter(res.document, n) == pytest.approx(1.6, rel=RECOVER_RTOL)

    truth = _rotor_chain((1.5e-3, 1.5e-3, 1.5e-3))
    f = np.geomspace(1.0, 200.0, 150)
    data = simulate(truth, freq_hz=f, outputs=("t0", "t2"), noise=0.0)
    model = _rotor_chain((1.0e-3, 1.2e-3, 1.4e-3))
    inertias = [f"r{i}.inertia.izz" for i in range(3)]
    declare_tie(model, "izz", ["r*.inertia.izz"], "study.toml")
    names = select_parameters(model, inertias)
    assert names == ["r0.inertia.izz"]
    res = fit(model, [data], names, max_iter=200, presolve_iter=0)
    assert res.success
    for n in inertias:
        assert get_parameter(res.document, n) == pytest.approx(1.5e-3, rel=RECOVER_RTOL)
    # the members' other components stay as they were
    assert get_parameter(res.document, "r2.inertia.ixx") == pytest.approx(2e-3, rel=1e-12)
    # rotors that differ: the tie still holds them to one value, between the true ones
    truth = _rotor_chain((1.3e-3, 1.5e-3, 1.7e-3))
    data = simulate(truth, freq_hz=f, outputs=("t0", "t2"), noise=0.0)
    res = fit(model, [data], names, max_iter=200, presolve_iter=0)
    values = [get_parameter(res.document, n) for n in inertias]
    assert max(values) - min(values) <= TIE_ATOL * values[0]
    assert 1.3e-3 < values[0] < 1.7e-3


def test_inertial_tie_residual_jacobian_matches_finite_differences():
    """The named Jacobian (parameter statistics, the diagnosis's refits) of a mass tie: the
    tie's column is the derivative with every member moved together."""
    doc = _free_chain(N)
    declare_tie(doc, "mass", ["m1.mass", "m2.mass", "m3.mass"], "--tie")
    names = select_parameters(doc, ["m*.mass", "j1.damping"])
    assert names == ["m0.mass", "m1.mass", "j1.damping"]
    data = simulate(_free_chain(N), freq_hz=np.geomspace(5.0, 300.0, 60), outputs=("acc",))
    problem = FitProblem(doc, [data], names)
    am = build_affine_model(doc, outputs=data.outputs)
    pmap = TiedParameters(doc, am, names, problem.ties)
    x0 = get_parameters(doc, names)
    _, J = problem.frf.residual_and_jacobian(pmap, x0)
    k = names.index("m1.mass")
    h = FD_STEP * x0[k]
    e = np.zeros_like(x0)
    e[k] = h
    fd = (problem.frf.residual(pmap, x0 + e) - problem.frf.residual(pmap, x0 - e)) / (2 * h)
    assert np.max(np.abs(J[:, k] - fd)) <= JAC_FD_TOL * np.max(np.abs(J[:, k]))
    # the fit's constraint rows hold the members to the leader at the start
    cons = problem.constraints()
    rows = [i for i, lab in enumerate(cons.labels) if "tied to m1.mass" in lab]
    assert len(rows) == 2
    import casadi

    g = np.array(casadi.Function("g", [cons.zsym], [cons.expr])(problem.z0)).ravel()
    assert np.allclose(g[rows], 0.0, atol=1e-12)


def test_a_tie_across_components_is_refused_by_the_fit():
    """``x`` of one body tied to ``y`` of another: refused by the fit's own check too (a
    caller can give ties without declaring them in the model)."""
    from bondid.exceptions import ConfigError

    doc = _free_chain(N)
    data = simulate(_free_chain(N), freq_hz=np.geomspace(5.0, 300.0, 20), outputs=("acc",))
    with pytest.raises(ConfigError, match="of the leader's kind"):
        FitProblem(doc, [data], ["m1.com.x"], ties={"m1.com.x": [("m2.com.y", 1.0)]})
    # the same component is accepted
    FitProblem(doc, [data], ["m1.com.x"], ties={"m1.com.x": [("m2.com.x", 1.0)]})
