"""The FRF problem's residual Jacobian, on both of its paths, against central differences."""

from __future__ import annotations

import numpy as np
import pytest

from bondid.cost import CostOptions, FrfProblem
from bondid.cost.residuals import RESIDUAL_KINDS
from bondid.data.measurement import FrfData
from bondid.linear.affine import build_affine_model
from bondid.linear.parameter_map import ParameterMap
from bondid.model import UrdfDocument, get_parameters, set_parameter

OPS = [{}, {"x": 0.05, "y": -0.03, "z": 0.1}]
NAMES = [
    "x_stage.mass",
    "y_stage.com.x",
    "z_stage.inertia.ixy",
    "x_guide_ry.stiffness",
    "y_guide_tx.damping",
    "z_bearing_rz.stiffness",
]
TOL_FD = 1e-6  # relative to each column's largest entry


@pytest.fixture(scope="module")
def bonder() -> UrdfDocument:
    return UrdfDocument.load("urdf/bonder.urdf")


def _data(doc: UrdfDocument, gaps: bool) -> list[FrfData]:
    """Data of a model 10 % off on NAMES at two poses; with ``gaps`` one channel is missing
    and some entries are NaN (so the problem selects points instead of whole grids)."""
    truth = doc.copy()
    for n, v in zip(NAMES, get_parameters(doc, NAMES), strict=True):
        set_parameter(truth, n, 1.1 * v if v != 0 else 1e-3)
    f = np.logspace(0, np.log10(4000.0), 70)
    rng = np.random.default_rng(0)
    out = []
    for op in OPS:
        am = build_affine_model(truth, op)
        H = am.linear_model().frf(f)
        coh = rng.uniform(0.2, 1.0, H.shape)
        if gaps:
            H[0, 2] = np.nan  # channel x.z absent
            H[1, 1, rng.choice(f.size, 5, replace=False)] = np.nan
        out.append(FrfData(f, am.outputs, am.inputs, H, operating_point=op, coherence=coh))
    return out


@pytest.mark.parametrize("gaps", [False, True], ids=["whole-grid", "selected-points"])
@pytest.mark.parametrize("norm", ["l2", "l1"])
@pytest.mark.parametrize("kind", RESIDUAL_KINDS)
def test_residual_jacobian_matches_central_differences(
    bonder: UrdfDocument, kind: str, norm: str, gaps: bool
) -> None:
    options = CostOptions(kind=kind, norm=norm, l1_delta=0.5, bands=[(2.0, 3000.0)])
    problem = FrfProblem(bonder, _data(bonder, gaps), options)
    assert all((b.flat is not None) == gaps for b in problem.blocks)
    pmap = ParameterMap(bonder, problem.affines[0], NAMES)
    p0 = pmap.p0
    r, J = problem.residual_and_jacobian(pmap, p0)
    np.testing.assert_array_equal(r, problem.residual(pmap, p0))
    assert J.shape == (r.size, len(NAMES))
    for k in range(len(NAMES)):
        h = 1e-5 * abs(p0[k])  # every parameter in NAMES is non-zero
        up, dn = p0.copy(), p0.copy()
        up[k] += h
        dn[k] -= h
        fd = (problem.residual(pmap, up) - problem.residual(pmap, dn)) / (2 * h)
        err = np.abs(fd - J[:, k]).max() / np.abs(J[:, k]).max()
        assert err < TOL_FD, f"{NAMES[k]}: {err:.2e}"
