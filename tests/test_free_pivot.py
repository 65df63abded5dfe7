"""A compliance's pivot as a parameter: mimic multipliers in the model and in the fit."""

from __future__ import annotations

import numpy as np
import pytest
from models import central_jacobian, noisy_bonder_data

from bondid.cost import CostOptions, FrfProblem
from bondid.exceptions import ModelError
from bondid.linear import build_affine_model
from bondid.linear.parameter_map import ParameterMap
from bondid.model import UrdfDocument, get_parameter, set_parameter
from bondid.model.authoring import move_pivot
from bondid.model.document import rotation_and_translation
from bondid.model.parameters import group_members, parameter_infos
from bondid.model.pivot import across, free_pivot, pivot_of, settle_pivot
from bondid.model.points import Point
from bondid.simulate import log_grid

BONDER = "urdf/bonder.urdf"
JOINT = "x_guide_ry"
#: the pivot's shift across the axis placed by the two multipliers [m/rad]
SHIFT = (0.02, -0.015)
#: the coupled model against the same joint about the moved pivot: the mass matrix is the
#: same exactly; the gravity stiffness differs at second order (relative FRF difference)
TOL_SAME_MODEL = 1e-7
#: central differences against the exact Jacobian (relative to the Jacobian's largest entry)
TOL_FD = 2e-5


def _bonder() -> UrdfDocument:
    """The bonder with a point on the z stage (an input and an output that the pivot moves,
    so the derivatives through ``B`` and ``C`` are exercised too)."""
    doc = UrdfDocument.load(BONDER)
    doc.set_point(Point("tip", "z_stage", "translation", (0.6, 0.0, 0.8)))
    return doc


def _freed(shift=SHIFT) -> tuple[UrdfDocument, UrdfDocument]:
    """(the bonder with ``JOINT``'s pivot freed and shifted by ``shift``, the bonder with the
    pivot moved there)."""
    doc = _bonder()
    free = doc.copy()
    names = free_pivot(free, JOINT)
    for n, v in zip(names, shift, strict=True):
        set_parameter(free, f"{n}.multiplier", v)
    moved = doc.copy()
    move_pivot(moved, JOINT, pivot_of(free, JOINT))
    return free, moved


def test_multipliers_place_the_pivot_as_a_moved_joint_would():
    free, moved = _freed()
    doc = _bonder()
    a = np.asarray(doc.joint(JOINT).axis, float)
    p0 = rotation_and_translation(doc.joint(JOINT).origin)[1]
    e1, e2 = across(a)
    assert abs(e1 @ a) < 1e-15 and abs(e2 @ a) < 1e-15 and abs(e1 @ e2) < 1e-15
    assert np.allclose(pivot_of(free, JOINT), p0 + np.cross(a, SHIFT[0] * e1 + SHIFT[1] * e2))
    f = log_grid(5.0, 3000.0, 200)
    H_free = build_affine_model(free).linear_model().frf(f)
    H_moved = build_affine_model(moved).linear_model().frf(f)
    assert np.max(np.abs(H_free - H_moved)) < TOL_SAME_MODEL * np.max(np.abs(H_moved))
    # the multipliers are parameters of their own group, in no other
    names = [p.name for p in parameter_infos(free) if p.kind == "multiplier"]
    assert names == group_members(free, "couplings") and len(names) == 2
    assert not set(names) & set(group_members(free, "all"))
    assert get_parameter(free, names[0]) == SHIFT[0]
    # the multipliers are written with the model and read back
    again = UrdfDocument.from_string(free.to_string())
    assert [get_parameter(again, n) for n in names] == list(SHIFT)


def test_settling_the_pivot_gives_back_the_plain_joint():
    free, moved = _freed()
    settled = free.copy()
    p = settle_pivot(settled, JOINT)
    assert np.allclose(p, pivot_of(free, JOINT))
    assert [j.name for j in settled.robot.joints] == [j.name for j in moved.robot.joints]
    assert settled.to_string() == moved.to_string()


def test_a_free_pivot_needs_a_revolute_joint():
    doc = UrdfDocument.load(BONDER)
    with pytest.raises(ModelError, match="revolute"):
        free_pivot(doc, "x_guide_ty")


@pytest.mark.parametrize("channels", [None, ["x.x", "tip.x", "y.tip", "tip.tip"]])
def test_the_jacobian_through_the_multipliers_matches_central_differences(channels):
    truth, _ = _freed((0.03, 0.01))
    free, _ = _freed((0.005, -0.02))
    data = noisy_bonder_data(truth, n=60)
    opts = CostOptions() if channels is None else CostOptions(channels=channels)
    problem = FrfProblem(free, data, opts)
    names = ["x_guide_ry_pivot_u.multiplier", "x_guide_ry_pivot_v.multiplier",
             "x_guide_ry.stiffness", "y_stage.mass", "y_stage.com.x"]  # fmt: skip
    pm = ParameterMap(free, problem.blocks[0].affine, names)
    x0 = pm.p0.copy()
    r, J = problem.residual_and_jacobian(pm, x0)
    assert np.allclose(r, problem.residual(pm, x0))
    fd = central_jacobian(problem, pm, x0, floor=1e-2)
    scale = np.abs(J).max(axis=0)
    assert np.all(np.abs(fd - J).max(axis=0) < TOL_FD * scale)


#: the fitted pivot against the truth's (m), with 0.5 % noise on the data
TOL_PIVOT_M = 1e-3


def test_a_fit_finds_the_pivot_and_the_fitted_model_settles_to_a_plain_joint():
    from bondid.fit import fit

    truth, moved = _freed(SHIFT)
    data = noisy_bonder_data(moved, n=120)
    model, _ = _freed((0.0, 0.0))  # the pivot where the model has it
    names = ["x_guide_ry_pivot_u.multiplier", "x_guide_ry_pivot_v.multiplier",
             "x_guide_ry.stiffness"]  # fmt: skip
    # (the presolve on the normalised complex error crosses the phase walls between the
    # model's pivot and the truth's)
    res = fit(model, data, names, max_iter=200)
    assert np.linalg.norm(pivot_of(res.document, JOINT) - pivot_of(truth, JOINT)) < TOL_PIVOT_M
    held = fit(model, data, names[2:], max_iter=200)
    assert res.cost_final < 0.5 * held.cost_final
    settled = res.document.copy()
    settle_pivot(settled, JOINT)
    assert np.allclose(pivot_of(settled, JOINT), pivot_of(res.document, JOINT))


def test_the_diagnosis_reports_and_writes_the_pivot_it_found():
    """A rotational compliance candidate built with its pivot shifted: the effect's detail
    names the pivot, the final-fit section lists it, and the URDF the diagnosis writes has
    it as the joint's own origin (no mimic joint left)."""
    from types import SimpleNamespace

    from bondid.diagnose.augmented import with_values
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.report import _details
    from bondid.model.pivot import settled_text

    doc = UrdfDocument.load(BONDER)
    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "x_stage->y_stage:ry")
    c = with_values(c, [c.parameters[0].initial, c.parameters[1].initial, *SHIFT])
    model = e.augment(doc, c)
    p = pivot_of(model, c.spec["joint"])
    assert e.detail(model, c) == f"pivot {np.round(p * 1e3, 1).tolist()} mm"
    m = SimpleNamespace(chain=(c,), urdf=model.to_string())
    assert _details(m) == [e.detail(model, c)]  # type: ignore[arg-type]
    written = UrdfDocument.from_string(settled_text(model.to_string()))
    assert not written.mimic_joints()
    origin = rotation_and_translation(written.joint(c.spec["joint"]).origin)[1]
    assert np.allclose(origin, p)
