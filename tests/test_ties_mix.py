"""A point with a second component (a patch driving bending and torsion) and its fittable mix:
the model's rows, exact FRF derivatives, declaration and a known-answer fit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bondid.cost.problem import FrfProblem
from bondid.exceptions import ConfigError
from bondid.linear.affine import build_affine_model
from bondid.linear.parameter_map import ParameterMap
from bondid.model import UrdfDocument
from bondid.model.parameters import get_parameter, parameter_names, set_parameter
from bondid.model.points import Point, points_from_table
from bondid.simulate import simulate

#: two exact computations of one FRF (round-off only, relative to the largest entry)
EXACT_TOL = 1e-10
#: residual Jacobian against central differences (relative to its largest entry)
JAC_FD_TOL = 1e-6
#: a noise-free fit recovers the truth's mix to this (relative)
RECOVER_RTOL = 1e-6

#: a cantilever strip: a bending joint then a torsion joint, twice; springs and dampers
_STRIP = """<robot name="strip"><link name="clamp"/>
<link name="b0l"/><link name="s0"><inertial><origin xyz="0.05 0 0"/><mass value="0.08"/>
<inertia ixx="7e-5" ixy="0" ixz="0" iyy="7e-5" iyz="0" izz="1.4e-4"/></inertial></link>
<link name="b1l"/><link name="s1"><inertial><origin xyz="0.05 0 0"/><mass value="0.08"/>
<inertia ixx="7e-5" ixy="0" ixz="0" iyy="7e-5" iyz="0" izz="1.4e-4"/></inertial></link>
<link name="tip"/>
<joint name="b0" type="revolute"><parent link="clamp"/><child link="b0l"/><axis xyz="0 1 0"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/><dynamics damping="0.002"/></joint>
<joint name="t0" type="revolute"><parent link="b0l"/><child link="s0"/><axis xyz="1 0 0"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/><dynamics damping="0.001"/></joint>
<joint name="b1" type="revolute"><parent link="s0"/><child link="b1l"/><origin xyz="0.1 0 0"/>
<axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
<dynamics damping="0.002"/></joint>
<joint name="t1" type="revolute"><parent link="b1l"/><child link="s1"/><axis xyz="1 0 0"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/><dynamics damping="0.001"/></joint>
<joint name="ft" type="fixed"><parent link="s1"/><child link="tip"/>
<origin xyz="0.1 0.03 0"/></joint>
<gazebo reference="b0"><springStiffness>60.0</springStiffness></gazebo>
<gazebo reference="t0"><springStiffness>25.0</springStiffness></gazebo>
<gazebo reference="b1"><springStiffness>50.0</springStiffness></gazebo>
<gazebo reference="t1"><springStiffness>20.0</springStiffness></gazebo>
</robot>"""


def _strip(mix: float = 0.3) -> UrdfDocument:
    doc = UrdfDocument.from_string(_STRIP, source="<strip>")
    doc.set_point(Point("acc", "tip", "translation", (0.0, 0.0, 1.0)))
    doc.set_point(
        Point("patch", "s0", "rotation", (0.0, 1.0, 0.0), relative_to="clamp",
              second_kind="rotation", second_direction=(1.0, 0.0, 0.0), mix=mix)
    )  # fmt: skip
    return doc


FREQ = np.geomspace(2.0, 200.0, 90)


def test_a_mixed_point_is_the_sum_of_its_components():
    """The patch's column = bending torque + mix × torsion torque: the FRF of the mixed point
    is that of two separate points, the second scaled by the mix (linearity), both as an
    input and as an output."""
    mix = 0.3
    doc = _strip(mix)
    parts = _strip(mix)
    parts.set_point(Point("bend", "s0", "rotation", (0.0, 1.0, 0.0), relative_to="clamp"))
    parts.set_point(Point("twist", "s0", "rotation", (1.0, 0.0, 0.0), relative_to="clamp"))
    H = build_affine_model(doc, outputs=("acc", "patch")).linear_model().frf(FREQ)
    P = build_affine_model(parts, outputs=("acc", "bend", "twist")).linear_model().frf(FREQ)
    i_p = build_affine_model(doc, outputs=("acc",)).inputs.index("patch")
    ins = build_affine_model(parts, outputs=("acc",)).inputs
    i_b, i_t = ins.index("bend"), ins.index("twist")
    expected_col = P[0, i_b] + mix * P[0, i_t]
    assert np.max(np.abs(H[0, i_p] - expected_col)) <= EXACT_TOL * np.max(np.abs(expected_col))
    # as an output too: the patch senses bend + mix · twist of the same excitation
    expected_row = P[1, i_b] + mix * P[2, i_b] + mix * (P[1, i_t] + mix * P[2, i_t])
    assert np.max(np.abs(H[1, i_p] - expected_row)) <= EXACT_TOL * np.max(np.abs(expected_row))


def test_mix_is_a_parameter_of_the_model_and_survives_write_and_read(tmp_path):
    doc = _strip(0.3)
    assert "mix.patch" in parameter_names(doc)
    assert get_parameter(doc, "mix.patch") == 0.3
    set_parameter(doc, "mix.patch", -0.7)
    doc.write(tmp_path / "s.urdf")
    back = UrdfDocument.load(tmp_path / "s.urdf")
    assert get_parameter(back, "mix.patch") == -0.7
    assert back.points == doc.points


@pytest.mark.parametrize("gain", [1.0, 2.5])
def test_residual_jacobian_in_the_mix_matches_finite_differences(gain):
    doc = _strip(0.3)
    if gain != 1.0:
        doc.set_gain("gain.in.patch", gain)
    truth = _strip(0.55)
    data = simulate(truth, freq_hz=FREQ, outputs=("acc", "patch"))
    names = ["mix.patch", "b0.stiffness", "t0.stiffness", "s0.mass"]
    problem = FrfProblem(doc, [data])
    pmap = ParameterMap(doc, problem.affines[0], names)
    x0 = pmap.p0
    r0, J = problem.residual_and_jacobian(pmap, x0)
    assert np.allclose(r0, problem.residual(pmap, x0), rtol=0, atol=1e-12)
    for k in range(len(names)):
        h = 1e-6 * max(abs(x0[k]), 1.0)
        e = np.zeros_like(x0)
        e[k] = h
        fd = (problem.residual(pmap, x0 + e) - problem.residual(pmap, x0 - e)) / (2 * h)
        assert np.max(np.abs(J[:, k] - fd)) <= JAC_FD_TOL * np.max(np.abs(J[:, k])), names[k]


def test_fit_recovers_the_mix_of_a_patch(tmp_path):
    """Noise-free accelerance of the strip with the patch's torsion share 0.55; the model
    starts with 0 (a pure bending patch) and fits the mix and the torsion springs."""
    from bondid.data.io import write_frf
    from bondid.fit.cli import main

    truth = _strip(0.55)
    data = simulate(truth, freq_hz=FREQ, outputs=("acc",), quantity="accelerance")
    keep = [data.inputs.index("patch")]
    data = type(data)(FREQ, data.outputs, ("patch",), data.H[:, keep], "accelerance")
    write_frf(data, tmp_path / "d.csv")
    start = UrdfDocument.from_string(_STRIP, source="<strip>")
    start.write(tmp_path / "strip.urdf")
    (tmp_path / "points.toml").write_text(
        '[points.acc]\nlink = "tip"\ndirection = [0, 0, 1]\n'
        '[points.patch]\nlink = "s0"\nkind = "rotation"\ndirection = [0, 1, 0]\n'
        'relative_to = "clamp"\nsecond = {kind = "rotation", direction = [1, 0, 0]}\nmix = 0.0\n'
    )
    out = tmp_path / "out"
    args = ["--model", str(tmp_path / "strip.urdf"), "--data", str(tmp_path / "d.csv"),
            "--points", str(tmp_path / "points.toml"), "--free", "mix.patch", "t0.stiffness",
            "--presolve", "0", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    fit = json.loads((out / "fit.json").read_text())
    fitted = {p["name"]: p["fitted"] for p in fit["parameters"]}
    assert fitted["mix.patch"] == pytest.approx(0.55, rel=RECOVER_RTOL)
    assert get_parameter(UrdfDocument.load(out / "fitted.urdf"), "mix.patch") == pytest.approx(
        0.55, rel=RECOVER_RTOL
    )


@pytest.mark.parametrize(
    ("table", "needle"),
    [
        ({"link": "s0", "mix": 0.2}, "a mix needs a second component"),
        ({"link": "s0", "second": {"kind": "rotation"}}, "second.direction: missing"),
        ({"link": "s0", "second": {"direction": [0, 0, 0]}}, "not a direction"),
        ({"link": "s0", "second": {"direction": [1, 0, 0], "axes": "x"}}, "unknown key"),
        ({"link": "s0", "second": {"direction": [1, 0, 0]}, "mix": "a"}, "not a finite"),
    ],
)
def test_bad_second_components_name_the_key(table, needle):
    with pytest.raises(ConfigError, match=needle) as err:
        points_from_table({"p": table}, "pts.toml")
    assert str(err.value).startswith("pts.toml: points.p")
