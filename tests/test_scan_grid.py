"""The scan grid the screening and the refits share (bondid.diagnose.scan_grid), and the starts
of a candidate (bondid.diagnose.starts): its mode placed at a measured one, the nominal origin
second in line, the figure never above the objective at its start."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")


def test_scan_grid_puts_the_compliance_mode_at_each_hint(doc):
    """Known answer: a joint compliance's stiffness scaled by a hint's factor resonates on the
    DOF's effective inertia at that hint; the grid is the candidate's own plus the hints'."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.topology import effective_inertia
    from bondid.diagnose.scan_grid import scan_grid

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "x_stage->y_stage:tz")
    hints = (123.0, 2345.0)
    grid, factors = scan_grid(c, hints)
    assert set(factors) <= set(grid) and set(c.scan_grid) <= set(grid)
    assert list(grid) == sorted(set(grid)) and len(grid) == len(set(c.scan_grid)) + 2
    probe = e.augment(doc, c)
    m = effective_inertia(probe, c.spec["joint"])
    k0 = c.parameters[0].initial
    for f, s in zip(hints, factors, strict=True):
        f_mode = math.sqrt(k0 * s ** c.parameters[0].scan / m) / (2 * math.pi)
        assert f_mode == pytest.approx(f, rel=1e-9)


def test_scan_grid_of_a_signal_candidate_has_no_hints(doc):
    """An FRF modifier has no mode: its grid is its own, no hint factors."""
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.scan_grid import scan_grid

    c = get_effect("sensor_delay").candidates(doc)[0]
    grid, factors = scan_grid(c, (100.0, 200.0))
    assert factors == [] and grid == tuple(sorted(set(c.scan_grid)))


def test_a_placed_start_puts_the_candidates_mode_at_the_measured_one(doc):
    """Known answer: the start labelled "mode at f Hz" has the compliance's stiffness that
    resonates on the DOF's effective inertia at f (a placed start stays placed), and the
    nominal origin's start comes second, with the nominal values and no figure."""
    from models import noisy_bonder_data

    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.topology import effective_inertia
    from bondid.diagnose.refit import State, nominal_space
    from bondid.diagnose.starts import Places, candidate_starts

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "x_stage->y_stage:tz")
    data = noisy_bonder_data(doc, n=60)
    names = ["x_stage.mass", "y_stage.mass"]
    space = nominal_space(doc, names, 4000.0)
    refit = build(doc.to_string(), space, data, CostOptions(), (), c).refit
    centre = np.array([0.9, 1.1]) * space.centre
    starts = candidate_starts(refit, c, Places((), (1234.0,), centre))
    assert starts[1].label.endswith("from the nominal model") and math.isnan(starts[1].figure)
    np.testing.assert_array_equal(starts[1].x[: refit.n_nominal], centre)
    placed = [s for s in starts if s.label == "mode at 1234 Hz"]
    assert len(placed) == 1
    k = refit.new_values(State(placed[0].x, placed[0].theta))[0]
    m = effective_inertia(e.augment(doc, c), c.spec["joint"])
    assert math.sqrt(k / m) / (2 * math.pi) == pytest.approx(1234.0, rel=1e-9)
    for s in starts:
        if math.isfinite(s.figure):
            assert s.figure <= refit.cost(State(s.x, s.theta)) + 1e-12


def test_a_placed_start_relaxes_the_nominal_parameters_around_its_held_spring(doc):
    """``relaxed``: the spring stays where it was placed (bit for bit), the nominal
    parameters move, and the objective does not rise (an IPOPT solve from that point)."""
    from models import noisy_bonder_data

    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.starts import relaxed

    c = next(c for c in get_effect("joint_compliance").candidates(doc)
             if c.location == "x_stage->y_stage:tz")  # fmt: skip
    data = noisy_bonder_data(doc, n=60)
    space = nominal_space(doc, ["x_stage.mass", "y_stage.mass"], 4000.0)
    refit = build(doc.to_string(), space, data, CostOptions(), (), c).refit
    placed = refit.with_new(refit.state0, refit.new_values(refit.state0) * [0.05, 1.0])
    out = relaxed(refit, placed)
    np.testing.assert_array_equal(refit.new_values(out), refit.new_values(placed))
    assert not np.array_equal(out.x[: refit.n_nominal], placed.x[: refit.n_nominal])
    assert refit.cost(out) <= refit.cost(placed) * (1 + 1e-9)


def test_a_scan_start_at_an_end_of_the_grid_is_tried_after_every_other(doc):
    """On data of the model itself a stiffer spring is always a little better, so the scan's
    lowest cost lies at the stiff end of its grid: that start is marked an edge start and
    comes after every start that is not, although its figure is the lowest; the others keep
    the figure order, the nominal origin of the best of them second."""
    from models import noisy_bonder_data

    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build
    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.starts import Places, candidate_starts

    c = next(c for c in get_effect("joint_compliance").candidates(doc)
             if c.location == "x_stage->y_stage:tz")  # fmt: skip
    data = noisy_bonder_data(doc, n=60)
    space = nominal_space(doc, ["x_stage.mass", "y_stage.mass"], 4000.0)
    refit = build(doc.to_string(), space, data, CostOptions(), (), c).refit
    starts = candidate_starts(refit, c, Places((), (1234.0,), space.centre))
    top = max(c.scan_grid)
    edge = [s for s in starts if s.edge]
    assert [s.label for s in edge] == [f"scan ×{top:.3g}"]
    inner = [s for s in starts if not s.edge]
    assert all(a is b for a, b in zip(starts, inner, strict=False))
    assert edge[0].figure < inner[0].figure
    assert inner[1].label == f"{inner[0].label} from the nominal model"
    figures = [s.figure for s in inner if math.isfinite(s.figure)]
    assert figures == sorted(figures)
