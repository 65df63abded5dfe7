"""The fit's Jacobian along the movable entries of its decision vector (:mod:`bondid.optim.
free_columns`): the same numbers as the whole Jacobian there, and zeros on the fixed ones."""

from __future__ import annotations

import numpy as np
import pytest

from bondid.model.document import UrdfDocument
from bondid.model.parameters import get_parameters, set_parameter
from bondid.optim.evaluator import Evaluator
from bondid.optim.free_columns import FreeColumns, movable
from bondid.optim.problem import FitProblem
from bondid.simulate import simulate

BONDER_URDF = "urdf/bonder.urdf"
#: the movable columns are the same products as the whole Jacobian's: equal to round-off
SAME_RTOL = 1e-12

NAMES = ["x_stage.mass", "z_stage.inertia.ixx", "x_guide_ry.stiffness", "y_guide_rz.damping"]


@pytest.fixture(scope="module")
def problem() -> FitProblem:
    bonder = UrdfDocument.load(BONDER_URDF)
    truth = bonder.copy()
    k = get_parameters(bonder, ["x_guide_ry.stiffness"])[0]
    set_parameter(truth, "x_guide_ry.stiffness", 1.3 * k)  # data the start does not fit
    data = simulate(truth, freq_hz=np.geomspace(5.0, 2000.0, 80))
    return FitProblem(bonder, [data], NAMES)


def test_movable_is_every_entry_whose_bounds_differ() -> None:
    lo, hi = np.array([0.0, 1.0, -np.inf, 2.0]), np.array([1.0, 1.0, np.inf, 2.0])
    np.testing.assert_array_equal(movable(lo, hi), [0, 2])
    assert movable(lo[:1], hi[:1]) is None


def test_fixed_entries_are_left_out_and_the_rest_agrees(problem: FitProblem) -> None:
    fixed = problem.lbz == problem.ubz
    assert fixed.any() and not fixed.all()  # held CoM / inertia entries of the fitted bodies
    z = problem.z0 + 0.03
    whole = Evaluator(problem.frf, problem.model, prior=problem.rows)
    r0, J0 = whole.residual_and_jacobian(z)
    ev = problem.evaluator
    np.testing.assert_array_equal(ev.cols, np.flatnonzero(~fixed))
    r1, J1 = ev.residual_and_jacobian(z)
    np.testing.assert_allclose(r1, r0, rtol=SAME_RTOL, atol=0)
    scale = np.abs(J0).max()
    np.testing.assert_allclose(J1[:, ~fixed], J0[:, ~fixed], rtol=0, atol=SAME_RTOL * scale)
    assert np.all(J1[:, fixed] == 0.0)
    f, g = ev.cost_and_gradient(z)
    assert f == pytest.approx(float(r0 @ r0), rel=SAME_RTOL)
    np.testing.assert_allclose(g[~fixed], 2 * J0[:, ~fixed].T @ r0, rtol=1e-10)
    assert np.all(g[fixed] == 0.0)
    H = ev.gauss_newton(z)
    assert np.all(H[fixed] == 0.0) and np.all(H[:, fixed] == 0.0)


def test_the_view_reduces_every_jacobian_and_keeps_the_values(problem: FitProblem) -> None:
    free = problem.evaluator.cols
    view = FreeColumns(problem.model, free)
    z = problem.z0
    assert view.size == free.size
    for a, b in zip(view.values(z), problem.model.values(z), strict=True):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(view.jacobian(z), problem.model.jacobian(z), strict=True):
        np.testing.assert_array_equal(a, b[..., free])
    with pytest.raises(AttributeError):
        view.no_such_part  # noqa: B018 - the model has no such part: neither has the view
