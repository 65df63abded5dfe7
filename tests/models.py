"""Small models and example robots for the tests (built with bondid's authoring API)."""

from __future__ import annotations

import os

import numpy as np

from bondid.model import UrdfDocument

_BOX_INERTIA = 'ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"'


def _body(name: str, mass: float) -> str:
    return (
        f'<link name="{name}"><inertial><origin xyz="0 0 0"/><mass value="{mass!r}"/>'
        f"<inertia {_BOX_INERTIA}/></inertial>"
        f'<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>'
    )


def _slider(name: str, parent: str, child: str, damping: float) -> str:
    return (
        f'<joint name="{name}" type="prismatic"><parent link="{parent}"/><child link="{child}"/>'
        f'<axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="100" velocity="1"/>'
        f'<dynamics damping="{damping!r}"/></joint>'
    )


def _trans(joint: str) -> str:
    return (
        f'<transmission name="{joint}_trans"><type>transmission_interface/SimpleTransmission'
        f'</type><joint name="{joint}"><hardwareInterface>hardware_interface/'
        f"EffortJointInterface</hardwareInterface></joint></transmission>"
    )


def _spring(joint: str, k: float) -> str:
    return (
        f'<gazebo reference="{joint}"><springStiffness>{k!r}</springStiffness>'
        f"<springReference>0</springReference></gazebo>"
    )


def one_mass(m: float, k: float, d: float) -> UrdfDocument:
    """Seed eq. (4.1): one mass on a spring and damper to ground, force and sensor on it."""
    xml = (
        '<robot name="one_mass"><link name="ground"/>'
        + _body("mass1", m)
        + _slider("x1", "ground", "mass1", d)
        + _trans("x1")
        + _spring("x1", k)
        + "</robot>"
    )
    return UrdfDocument.from_string(xml, source="<one_mass>")


def two_mass_chain(m_a: float, m_b: float, k_a: float, d_a: float, k_b: float, d_b: float):
    """ground --(k_a, d_a, joint `a`)--> body_a --(k_b, d_b, joint `b`, relative)--> body_b."""
    xml = (
        '<robot name="two_mass"><link name="ground"/>'
        + _body("body_a", m_a)
        + _body("body_b", m_b)
        + _slider("a", "ground", "body_a", d_a)
        + _slider("b", "body_a", "body_b", d_b)
        + _trans("a")
        + _trans("b")
        + _spring("a", k_a)
        + _spring("b", k_b)
        + "</robot>"
    )
    return UrdfDocument.from_string(xml, source="<two_mass>")


def robot_path(name: str) -> str:
    import example_robot_data as erd

    sub = {
        "ur5": "ur_description/urdf/ur5_robot.urdf",
        "panda": "panda_description/urdf/panda.urdf",
    }[name]
    return os.path.join(erd.getModelPath(sub), sub)


def sprung_robot(name: str, seed: int = 0) -> UrdfDocument:
    """An example-robot-data robot with a spring and damper on every joint and an actuator
    on every joint that has none (all through the authoring API)."""
    doc = UrdfDocument.load(robot_path(name))
    for j in doc.mimic_joints():  # panda's second finger: an independent DOF here
        doc.drop_mimic(j)
    rng = np.random.default_rng(seed)
    driven = {t.joint for t in doc.transmissions}
    for j in doc.movable_joint_names:
        doc.set_stiffness(j, float(2e3 * (1 + rng.random())))
        doc.set_damping(j, float(2.0 * (1 + rng.random())))
        if j not in driven:
            doc.add_transmission(j)
    return doc


def random_pose(doc: UrdfDocument, seed: int = 1) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    return {
        j: float(0.02 * rng.standard_normal())
        if doc.joint(j).type == "prismatic"
        else float(0.5 * rng.standard_normal())
        for j in doc.movable_joint_names
    }


#: the two operating points of the diagnosis tests' synthetic data (joint name → position)
BONDER_OPS: tuple[dict[str, float], ...] = ({}, {"x": 0.05, "y": -0.03})


def noisy_bonder_data(truth: UrdfDocument, n: int = 120, noise: float = 0.005) -> list:
    """Receptance data of ``truth`` at :data:`BONDER_OPS` on ``n`` log-spaced frequencies from
    1 Hz to 4 kHz, with ``noise`` relative noise and a floor 70 dB below the response
    (seeded per operating point; coherence from the same noise)."""
    from bondid.data.noise import add_measurement_noise
    from bondid.simulate import log_grid, simulate

    f = log_grid(1.0, 4000.0, n)
    out = []
    for k, op in enumerate(BONDER_OPS):
        d = simulate(truth, op, f)
        d.H, d.coherence = add_measurement_noise(
            d.H, f, rel=noise, floor_db=-70, rng=k, floor_ref="response"
        )
        out.append(d)
    return out


def central_columns(fn, x: np.ndarray, floor: float):
    """``(k, ∂fn/∂x_k)`` by central differences at ``x`` for every ``k``, each parameter
    stepped by ``1e-6 · max(|x_k|, floor)`` (``fn``: ``(size,)`` → any array)."""
    for k in range(x.size):
        h = 1e-6 * max(abs(x[k]), floor)
        up, dn = x.copy(), x.copy()
        up[k] += h
        dn[k] -= h
        yield k, (fn(up) - fn(dn)) / (2 * h)


def central_jacobian(problem, pmodel, x: np.ndarray, floor: float) -> np.ndarray:
    """Central differences ``(n_residuals, size)`` of ``problem.residual(pmodel, ·)`` at ``x``,
    each parameter stepped by ``1e-6 · max(|x|, floor)``."""
    out = np.empty((problem.n_residuals, x.size))
    for k, col in central_columns(lambda p: problem.residual(pmodel, p), x, floor):
        out[:, k] = col
    return out


def frf_jacobian_errors(doc, names, freq_hz: np.ndarray, outputs, floor: float = 0.0):
    """The engine's FRF and Jacobian (:func:`bondid.frf.jacobian.frf_and_jacobian`, with the
    proportional-damping rows) against the plain engine: ``(relative FRF error, {name:
    Jacobian column's largest error relative to the central difference's largest entry})``."""
    from bondid.frf.jacobian import frf_and_jacobian
    from bondid.linear.affine import build_affine_model
    from bondid.linear.parameter_map import ParameterMap

    am = build_affine_model(doc, outputs=outputs)
    pmap = ParameterMap(doc, am, names)
    p0 = pmap.p0
    H, J = frf_and_jacobian(am, freq_hz, *pmap.jacobian(p0), drayleigh=pmap.rayleigh_jacobian(p0))
    frf_error = float(np.max(np.abs(H - am.linear_model().frf(freq_hz))) / np.abs(H).max())

    def frf_at(p):
        coefficients = pmap.rayleigh_values(p)
        assert coefficients is not None
        model = am.with_values(*pmap.values(p)).with_rayleigh(*coefficients)
        return model.linear_model().frf(freq_hz)

    errors = {
        names[k]: float(np.max(np.abs(J[..., k] - fd)) / np.abs(fd).max())
        for k, fd in central_columns(frf_at, p0, floor)
    }
    return frf_error, errors
