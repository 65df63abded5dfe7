"""Measurement points (frame-Jacobian B and C) and transducer gains: known answers."""

from __future__ import annotations

import numpy as np
import pytest
from models import central_jacobian, robot_path, two_mass_chain

from bondid.cost.problem import CostOptions, FrfProblem
from bondid.exceptions import ConfigError, ModelError
from bondid.linear.affine import build_affine_model
from bondid.linear.parameter_map import ParameterMap
from bondid.model import UrdfDocument
from bondid.model.parameters import get_parameter, select_parameters
from bondid.model.points import Point, points_from_table
from bondid.simulate import simulate

#: Central differences of Pinocchio placements (step 1e-6) agree with the Jacobian to this.
FD_TOL = 1e-7
#: Two exact computations of the same FRF (round-off only; pointwise relative, the deepest
#: anti-resonance of the chain loses a few digits).
EXACT_TOL = 1e-9
#: Residual Jacobian against central differences (relative to its largest entry).
JAC_FD_TOL = 1e-6


def _free_chain(n: int, hammer: bool = True) -> UrdfDocument:
    """A free-free chain of ``n`` masses along x (the first slides freely: a rigid-body mode),
    springs and dampers between neighbours, a point on each body (a link on a fixed joint,
    offset so its frame differs from the body's) and no transmission."""
    parts = ['<robot name="chain"><link name="ground"/>']
    for i in range(n):
        m = 1.0 + 0.3 * i
        parts.append(
            f'<link name="m{i}"><inertial><mass value="{m!r}"/><inertia ixx="1e-3" ixy="0"'
            ' ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial></link>'
            f'<link name="p{i}"/><joint name="fix{i}" type="fixed"><parent link="m{i}"/>'
            f'<child link="p{i}"/><origin xyz="0.01 0.02 0.03" rpy="0.1 0.2 0.3"/></joint>'
        )
        parent = "ground" if i == 0 else f"m{i - 1}"
        parts.append(
            f'<joint name="j{i}" type="prismatic"><parent link="{parent}"/><child link="m{i}"/>'
            '<axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
            f'<dynamics damping="{0.0 if i == 0 else 2.0 + i!r}"/></joint>'
        )
        if i > 0:
            parts.append(
                f'<gazebo reference="j{i}"><springStiffness>{1e4 * (1 + i)!r}</springStiffness>'
                "<springReference>0</springReference></gazebo>"
            )
    parts.append("</robot>")
    doc = UrdfDocument.from_string("".join(parts), source="<chain>")
    for i in range(n):
        if hammer:
            doc.set_point(Point(f"h{i}", f"p{i}", "translation", (1.0, 0.0, 0.0)))
    doc.set_point(Point("acc", f"p{n - 1}", "translation", (1.0, 0.0, 0.0)))
    return doc


def _chain_matrices(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M, K, D of the chain written by hand in absolute coordinates x_i."""
    m = np.array([1.0 + 0.3 * i for i in range(n)])
    M, K, D = np.diag(m), np.zeros((n, n)), np.zeros((n, n))
    for i in range(1, n):
        k, d = 1e4 * (1 + i), 2.0 + i
        e = np.zeros(n)
        e[i], e[i - 1] = 1.0, -1.0
        K += k * np.outer(e, e)
        D += d * np.outer(e, e)
    return M, K, D


def test_roving_hammer_free_free_chain_accelerance_known_answer():
    n = 4
    doc = _free_chain(n)
    am = build_affine_model(doc, outputs=("acc",))
    assert am.inputs == (*(f"h{i}" for i in range(n)), "acc")
    f = np.linspace(5.0, 200.0, 60)
    H = am.linear_model().frf(f, "accelerance")[:, :n]  # 1 accelerometer × n hammer points
    M, K, D = _chain_matrices(n)
    w = 2 * np.pi * f
    ref = np.empty((1, n, f.size), complex)
    for k, wk in enumerate(w):
        G = np.linalg.inv(K - wk**2 * M + 1j * wk * D)
        ref[0, :, k] = -(wk**2) * G[n - 1, :]  # x_i = sum of joint coordinates up to i
    assert np.max(np.abs(H - ref) / np.abs(ref)) < EXACT_TOL
    # the rigid-body mode: accelerance tends to 1/(total mass) at low frequency
    low = am.linear_model().frf(np.array([1e-3]), "accelerance")[0, 0, 0]
    assert abs(low.real * M.trace() - 1.0) < 1e-6


def test_point_rows_match_finite_differences_of_frame_placements():
    import pinocchio as pin

    doc = UrdfDocument.load(robot_path("ur5"))
    doc.set_point(Point("t", "wrist_3_link", "translation", (0.3, -0.5, 0.8), axes="local"))
    doc.set_point(Point("r", "forearm_link", "rotation", (1.0, 2.0, 0.5)))
    doc.set_point(
        Point("rel", "wrist_2_link", "translation", (0, 1, 0), relative_to="upper_arm_link")
    )
    q = {"shoulder_lift_joint": -0.7, "elbow_joint": 1.1, "wrist_1_joint": 0.4}
    am = build_affine_model(doc, q, outputs=("t", "r", "rel"))
    model = doc.build_pinocchio_model()
    data = model.createData()

    def place(qv: np.ndarray, frame: str) -> pin.SE3:
        pin.framesForwardKinematics(model, data, qv)
        return data.oMf[model.getFrameId(frame, pin.FrameType.BODY)].copy()

    h = 1e-6
    P0 = place(am.q0, "wrist_3_link")
    d_t = P0.rotation @ (np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]))
    d_r = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    for j in range(model.nv):
        e = np.zeros(model.nv)
        e[j] = h
        qp, qm = pin.integrate(model, am.q0, e), pin.integrate(model, am.q0, -e)
        dp = (place(qp, "wrist_3_link").translation - place(qm, "wrist_3_link").translation) / (
            2 * h
        )
        Rp, Rm = place(qp, "forearm_link").rotation, place(qm, "forearm_link").rotation
        dth = pin.log3(Rp @ Rm.T) / (2 * h)
        rel = [
            place(qq, "wrist_2_link").translation - place(qq, "upper_arm_link").translation
            for qq in (qp, qm)
        ]
        drel = (rel[0] - rel[1]) / (2 * h)
        assert abs(am.C[0, j] - d_t @ dp) < FD_TOL
        assert abs(am.C[1, j] - d_r @ dth) < FD_TOL
        assert abs(am.C[2, j] - drel[1]) < FD_TOL
    # a point as an input is the transpose of the same point as an output (reciprocity)
    k = am.inputs.index("t")
    assert np.allclose(am.B[:, k], am.C[0], rtol=0, atol=1e-15)


def test_relative_sensor_is_the_joint_twist_and_matches_python_control():
    import control

    doc = two_mass_chain(1.0, 0.5, 1000.0, 1.0, 2000.0, 2.0)
    doc.set_point(Point("abs_b", "body_b", "translation", (1.0, 0.0, 0.0)))
    doc.set_point(Point("twist", "body_b", "translation", (1.0, 0.0, 0.0), relative_to="body_a"))
    am = build_affine_model(doc, outputs=("abs_b", "twist", "b"))
    f = np.geomspace(1.0, 300.0, 50)
    H = am.linear_model().frf(f)
    assert np.max(np.abs(H[1] - H[2])) <= EXACT_TOL * np.max(np.abs(H[2]))
    A, B, C, D = am.linear_model().state_space()
    ref = control.ss(A, B, C, D).frequency_response(2 * np.pi * f).frdata
    assert np.max(np.abs(H - ref) / np.abs(ref)) < 1e-9


def _gain_problem(free: str):
    doc = two_mass_chain(1.0, 0.5, 1000.0, 1.0, 2000.0, 2.0)
    doc.set_point(Point("pb", "body_b", "translation", (1.0, 0.0, 0.0)))
    truth = doc.copy()
    truth.set_gain("gain.in.a", 0.37)
    truth.set_gain("gain.out.pb", -2.5)
    data = simulate(truth, freq_hz=np.geomspace(2.0, 100.0, 40), outputs=("a", "pb"))
    data = type(data)(data.freq_hz, data.outputs, data.inputs[:1], data.H[:, :1], data.quantity)
    doc.set_gain("gain.in.a", 1.0)
    doc.set_gain("gain.out.pb", -1.0)
    names = select_parameters(doc, [free])
    return doc, truth, data, names


@pytest.mark.parametrize("kind", ["complex_log", "normalised_complex", "log_magnitude"])
def test_gain_jacobian_matches_finite_differences(kind):
    doc, _, data, names = _gain_problem("gains, b.stiffness, body_a.mass")
    assert set(names) == {"gain.in.a", "gain.out.pb", "b.stiffness", "body_a.mass"}
    prob = FrfProblem(doc, [data], CostOptions(kind=kind))
    pm = ParameterMap(doc, prob.affines[0], names)
    x = pm.p0 * np.array([1.2 if n.startswith("gain") else 1.05 for n in names])
    r, J = prob.residual_and_jacobian(pm, x)
    assert np.allclose(r, prob.residual(pm, x), rtol=0, atol=1e-14)
    Jfd = central_jacobian(prob, pm, x, floor=1e-3)
    assert np.max(np.abs(J - Jfd)) < JAC_FD_TOL * np.max(np.abs(J))


def test_fitted_gain_known_answer():
    from bondid.fit import fit

    doc, truth, data, names = _gain_problem("gains")
    res = fit(doc, [data], names, max_iter=100, presolve_iter=0)
    assert res.success
    for n in names:
        k = res.names.index(n)
        assert abs(res.fitted[k] / get_parameter(truth, n) - 1.0) < 1e-6
        assert get_parameter(res.document, n) == res.fitted[k]  # fitted.urdf carries it


def test_points_table_errors_name_the_key():
    with pytest.raises(ConfigError, match=r"points\.acc\.kind"):
        points_from_table({"acc": {"link": "tip", "kind": "force"}}, "s.toml")
    with pytest.raises(ConfigError, match=r"points\.acc\.direction"):
        points_from_table({"acc": {"link": "tip", "direction": [0, 0, 0]}}, "s.toml")
    doc = two_mass_chain(1.0, 0.5, 1000.0, 1.0, 2000.0, 2.0)
    doc.set_point(Point("q", "nowhere", "translation"))
    with pytest.raises(ModelError, match="nowhere"):
        build_affine_model(doc)


def test_points_and_gains_survive_write_and_read():
    doc = two_mass_chain(1.0, 0.5, 1000.0, 1.0, 2000.0, 2.0)
    doc.set_point(Point("pb", "body_b", "rotation", (0.0, 0.6, 0.8), "local", "body_a"))
    doc.set_gain("gain.out.pb", 9.81)
    back = UrdfDocument.from_string(doc.to_string())
    assert back.points == doc.points
    assert back.gains == {"gain.out.pb": 9.81}
    import io

    import pinocchio as pin
    import yourdfpy

    text = doc.to_string()  # other URDF readers ignore the two extension elements
    assert pin.buildModelFromXML(text).nv == 2
    raw = yourdfpy.URDF.load(io.BytesIO(text.encode()), load_meshes=False, build_scene_graph=False)
    assert len(raw.robot.joints) == 2
    from bondid.model.points import plot_units

    assert plot_units(back, ["a", "pb"]) == {"a": "m", "pb": ("u(pb)", "N·m")}


@pytest.mark.parametrize("quantity", ["receptance", "mobility", "accelerance"])
def test_export_to_control_matches_bondid_frf(quantity):
    from bondid.export import to_control

    doc = two_mass_chain(1.0, 0.5, 1000.0, 1.0, 2000.0, 2.0)
    doc.set_point(Point("pb", "body_b", "translation", (1.0, 0.0, 0.0)))
    doc.set_gain("gain.in.a", 0.5)
    f = np.geomspace(1.0, 300.0, 40)
    sys, frd = to_control(doc, None, f, outputs=("a", "pb"), quantity=quantity)
    ref = build_affine_model(doc, outputs=("a", "pb")).linear_model().frf(f, quantity)
    H_ss = sys.frequency_response(2 * np.pi * f).frdata
    assert np.max(np.abs(H_ss - ref) / np.abs(ref)) < 1e-9
    assert np.array_equal(frd.frdata, ref)
    assert list(sys.input_labels) == ["a", "b", "pb"]


def _free_body() -> UrdfDocument:
    """One rigid body with an off-diagonal inertia and an offset CoM, free-flying."""
    from bondid.model.authoring import add_floating_base

    xml = (
        '<robot name="body"><link name="base"><inertial><origin xyz="0.1 -0.05 0.02"/>'
        '<mass value="2.5"/><inertia ixx="0.03" ixy="0.004" ixz="-0.002" iyy="0.05" iyz="0.001"'
        ' izz="0.04"/></inertial></link>'
        '<link name="p1"/><joint name="f1" type="fixed"><parent link="base"/><child link="p1"/>'
        '<origin xyz="0.3 0.1 -0.1"/></joint>'
        '<link name="p2"/><joint name="f2" type="fixed"><parent link="base"/><child link="p2"/>'
        '<origin xyz="-0.2 0.25 0.05"/></joint></robot>'
    )
    doc = UrdfDocument.from_string(xml, source="<body>")
    add_floating_base(doc)
    doc.set_point(Point("hit", "p1", "translation", (0.0, 0.6, 0.8)))
    doc.set_point(Point("acc", "p2", "translation", (1.0, 0.0, 0.0)))
    return doc


def test_free_flyer_rigid_body_accelerance_known_answer():
    from bondid.modes.analysis import modal_analysis

    doc = _free_body()
    am = build_affine_model(doc, outputs=("acc",))
    assert am.bodies == ("base",)  # the floating base is a fitted body, not grounded
    f = np.array([0.5, 10.0, 300.0])
    A = am.linear_model().frf(f, "accelerance")[0, am.inputs.index("hit")]
    c = np.array([0.1, -0.05, 0.02])
    r_i, r_o = np.array([0.3, 0.1, -0.1]) - c, np.array([-0.2, 0.25, 0.05]) - c
    I_c = np.array([[0.03, 0.004, -0.002], [0.004, 0.05, 0.001], [-0.002, 0.001, 0.04]])

    def cross(v: np.ndarray) -> np.ndarray:
        return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])

    d_i, d_o = np.array([0.0, 0.6, 0.8]), np.array([1.0, 0.0, 0.0])
    ref = d_o @ (np.eye(3) / 2.5 - cross(r_o) @ np.linalg.solve(I_c, cross(r_i))) @ d_i
    assert np.max(np.abs(A - ref)) < EXACT_TOL * abs(ref)
    modes = modal_analysis(am.linear_model())
    # the mode table lists the state matrix's eigenvalues: an undamped rigid DOF is a double
    # zero, so 6 rigid-body DOF give 12 entries at 0 Hz (and nothing else: no spring)
    assert [m.kind for m in modes.modes] == ["rigid"] * 12
    assert all(m.f_hz == 0 for m in modes.modes)


def test_roving_hammer_fit_of_a_free_free_chain_recovers_the_springs():
    from bondid.fit import fit
    from bondid.model.parameters import set_parameter

    n = 4
    truth = _free_chain(n)
    names = [f"j{i}.stiffness" for i in range(1, n)] + ["j2.damping"]
    for k, name in enumerate(names):
        set_parameter(truth, name, get_parameter(truth, name) * (1.25 - 0.15 * k))
    f = np.geomspace(3.0, 300.0, 150)
    data = simulate(truth, freq_hz=f, outputs=("acc",), quantity="accelerance")
    hammer = [i for i, name in enumerate(data.inputs) if name.startswith("h")]
    data = type(data)(f, data.outputs, tuple(data.inputs[i] for i in hammer),
                      data.H[:, hammer], "accelerance").to_quantity("receptance")  # fmt: skip
    res = fit(_free_chain(n), [data], names, max_iter=100, presolve_iter=0)
    assert res.success
    for k, name in enumerate(names):
        assert abs(res.fitted[k] / get_parameter(truth, name) - 1.0) < 1e-6


def test_fit_cli_roving_hammer_uff_with_vendor_nodes_points_file_and_gain(tmp_path):
    """End to end as a test engineer brings it: a URDF without points, a points file with
    the hammer points, the accelerometer and its sensitivity, a UFF58 file with the vendor's
    own node numbers mapped on the command line."""
    import json

    from bondid.data.uff_format import write_uff58
    from bondid.fit.cli import main
    from bondid.model.parameters import set_parameter

    n = 3
    truth = _free_chain(n)
    set_parameter(truth, "j1.stiffness", 1.3 * get_parameter(truth, "j1.stiffness"))
    truth.set_gain("gain.out.acc", 0.0102)  # V per m/s² (10.2 mV/g)
    f = np.geomspace(3.0, 300.0, 120)
    data = simulate(truth, freq_hz=f, outputs=("acc",), quantity="accelerance")
    data = type(data)(f, data.outputs, data.inputs[:n], data.H[:, :n], "accelerance")
    nodes = {"acc": (901, 1), **{f"h{i}": (101 + i, 1) for i in range(n)}}
    write_uff58(data, tmp_path / "hammer.uff", channel_map=nodes)
    bare = _free_chain(n, hammer=False)
    bare.extras = [el for el in bare.extras if el.tag != "measurement_point"]
    bare.write(tmp_path / "chain.urdf")
    (tmp_path / "points.toml").write_text(
        "".join(
            f'[points.h{i}]\nlink = "p{i}"\nkind = "translation"\ndirection = [1, 0, 0]\n'
            for i in range(n)
        )
        + f'[points.acc]\nlink = "p{n - 1}"\ndirection = [1, 0, 0]\n'
        + '[gains]\n"gain.out.acc" = 0.01\n'
    )
    args = ["--model", str(tmp_path / "chain.urdf"), "--data", str(tmp_path / "hammer.uff")]
    args += ["--points", str(tmp_path / "points.toml"), "--free", "j1.stiffness", "gains"]
    args += [f"--uff-map={k}={v[0]}:{v[1]}" for k, v in nodes.items()]
    assert main([*args, "--out", str(tmp_path / "out"), "--quiet", "--presolve", "0"]) == 0
    fitted = {
        p["name"]: p["fitted"]
        for p in json.loads((tmp_path / "out/fit.json").read_text())["parameters"]
    }
    assert abs(fitted["j1.stiffness"] / get_parameter(truth, "j1.stiffness") - 1) < 1e-6
    assert abs(fitted["gain.out.acc"] / 0.0102 - 1) < 1e-6
    assert main([*args[:4], "--points", str(tmp_path / "points.toml"), "--quiet"]) == 2


@pytest.mark.parametrize("gain", [1.0, 3.0])
def test_frf_jacobian_with_points_as_inputs_and_outputs_matches_finite_differences(gain):
    """Points make C = Bᵀ (the Jacobian mirrors channels); an input gain breaks it."""
    from bondid.frf.jacobian import frf_and_jacobian

    doc = _free_chain(3)
    doc.set_gain("gain.in.h1", gain)
    am = build_affine_model(doc)
    assert np.array_equal(am.C, am.B.T) == (gain == 1.0)
    names = ["j1.stiffness", "j2.damping", "m1.mass", "m2.mass"]
    pm = ParameterMap(doc, am, names)
    f = np.geomspace(5.0, 200.0, 30)

    def H_at(p: np.ndarray) -> np.ndarray:
        return am.with_values(*pm.values(p)).linear_model().frf(f)

    p0 = pm.p0
    H, J = frf_and_jacobian(am.with_values(*pm.values(p0)), f, *pm.jacobian(p0))
    assert np.max(np.abs(H - H_at(p0))) <= 1e-12 * np.max(np.abs(H))
    for k in range(len(names)):
        h = 1e-6 * abs(p0[k])
        e = np.zeros_like(p0)
        e[k] = h
        fd = (H_at(p0 + e) - H_at(p0 - e)) / (2 * h)
        assert np.max(np.abs(J[..., k] - fd)) < JAC_FD_TOL * np.max(np.abs(J[..., k]))


def test_study_file_model_keys(tmp_path):
    from bondid.fit.study import load_study

    path = tmp_path / "s.toml"
    path.write_text(
        'package_path = "ws"\nfloating_base = true\n'
        '[points.acc]\nlink = "tip"\naxes = "local"\n'
        '[gains]\n"gain.out.acc" = 0.0102\n[uff_map]\nacc = [901, -3]\n'
    )
    s = load_study(path)
    assert s.points == [Point("acc", "tip", axes="local")]
    assert s.gains == {"gain.out.acc": 0.0102}
    assert s.uff_map == {"acc": (901, -3)}
    assert s.package_path == [tmp_path / "ws"] and s.floating_base
    path.write_text("[uff_map]\nacc = [901, 7]\n")
    with pytest.raises(ConfigError, match=r"s\.toml: uff_map\.acc"):
        load_study(path)


def test_csv_quantity_per_output_is_converted_on_reading(tmp_path):
    from bondid.data.io import read_frf
    from bondid.exceptions import DataError

    f = np.array([10.0, 20.0])
    acc = np.array([3.0 - 1.0j, -2.0 + 0.5j])  # an accelerometer's m/s² per N
    lines = [
        "# bondid-frf: 1",
        "# quantity: receptance",
        "# quantities: acc=accelerance",
        "freq_hz,x.x.re,x.x.im,acc.x.re,acc.x.im",
    ]
    lines += [f"{f[k]},1e-3,0.0,{acc[k].real},{acc[k].imag}" for k in range(2)]
    (tmp_path / "mix.csv").write_text("\n".join(lines) + "\n")
    d = read_frf(tmp_path / "mix.csv")
    assert d.quantity == "receptance"
    w = 2 * np.pi * f
    assert np.allclose(d.H[d.outputs.index("acc"), 0], acc / -(w**2), rtol=1e-15, atol=0)
    assert np.all(d.H[d.outputs.index("x"), 0] == 1e-3)
    lines[2] = "# quantities: y=accelerance"
    (tmp_path / "bad.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"bad\.csv: line 3: 'quantities' names output 'y'"):
        read_frf(tmp_path / "bad.csv")


def test_fit_of_a_free_flying_body_recovers_its_mass_and_inertia():
    from bondid.fit import fit
    from bondid.model.parameters import set_parameter

    truth = _free_body()
    f = np.geomspace(5.0, 50.0, 8)
    data = simulate(truth, freq_hz=f, outputs=("hit", "acc"))
    start = _free_body()
    names = ["base.mass", "base.inertia.izz"]
    set_parameter(start, "base.mass", 2.2)  # default bounds ±20 %: the truth 2.5 inside
    set_parameter(start, "base.inertia.izz", 0.045)
    res = fit(start, [data], names, max_iter=100, presolve_iter=0, use_hull=False)
    assert res.success
    for k, name in enumerate(names):
        assert abs(res.fitted[k] / get_parameter(truth, name) - 1.0) < 1e-6
