"""The flexible base's chains of two lengths: the candidate (six nodes) carries a four-node
variant, a variant with other new parameters is refitted from its own scans, and a stuck
refit of one length is replaced by the other's when that reaches lower."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from models import noisy_bonder_data

from bondid.diagnose.effects import get_effect
from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
#: a truth chain's stiffness factors on the variant's start (shear x, shear y, compression):
#: modes between the start's 1 kHz and 500 Hz
TRUTH_STIFFNESS = (0.25, 0.35, 0.3)


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def _nodes(c) -> int:  # type: ignore[no-untyped-def]
    return sum(p.name.endswith("_mass") for p in c.parameters)


def test_the_chain_carries_a_shorter_variant(doc):
    """One candidate at the root, a six-node chain with a four-node variant; each builds a
    chain of its own length (three translations per node, the bottom one free)."""
    (c,) = get_effect("flexible_base").candidates(doc)
    assert _nodes(c) == 6 and [_nodes(v) for v in c.variants] == [4]
    assert c.label == c.variants[0].label and c.variants[0].variants == ()
    fb = get_effect("flexible_base")
    for cand, n in ((c, 6), (c.variants[0], 4)):
        aug = fb.augment(doc, cand)
        added = [j for j in aug.joint_names if j.startswith("flexible_base_")]
        assert len(added) == 3 * n, (n, added)


def test_a_chain_of_the_other_length_leads_when_the_data_are_its_own(doc):
    """Known answer: data from a four-node chain (stiffnesses off the start); the screening
    gives the four-node variant (other parameters: its own scans) a start of its own, which
    leads the candidate's starts, and the refit keeps that variant, no worse than what the
    six-node chain alone reaches."""
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import with_values
    from bondid.diagnose.job import Task
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.refit_job import run_refit
    from bondid.diagnose.screen import screen

    fb = get_effect("flexible_base")
    (c,) = fb.candidates(doc)
    four = c.variants[0]
    k = dict(zip(("shear_x_stiffness", "shear_y_stiffness", "compression_stiffness"),
                 TRUTH_STIFFNESS, strict=True))  # fmt: skip
    truth = np.array([p.initial * k.get(p.name, 1.0) for p in four.parameters])
    data = noisy_bonder_data(fb.augment(doc, with_values(four, truth)))
    task = Task(doc.to_string(), nominal_space(doc, FEW, 4000.0), data, data, data,
                CostOptions(), candidate=c, max_iter=60)  # fmt: skip
    s = screen(task)
    assert s.variant is not None and _nodes(s.variant) == 4
    lead = s.starts[0]
    assert lead.variant == 1
    six = min(st.figure for st in s.starts if st.variant == 0 and np.isfinite(st.figure))
    assert lead.figure < six
    r = run_refit(replace(task, starts=s.starts))
    assert not r.error and r.candidate is not None and _nodes(r.candidate) == 4
    assert r.variant == four.description
    alone = run_refit(replace(task, candidate=replace(c, variants=())))
    assert r.objective <= alone.objective


@pytest.mark.parametrize("variant_nodes", [(1,), (4, 0), (2.5,), (True,), 4, "4"])
def test_variant_lengths_that_are_no_chain_are_refused(variant_nodes):
    """A variant length below two nodes, or not an integer, or no tuple, is a ConfigError
    that names ``variant_nodes``."""
    from bondid.diagnose.effects.flexible_base import FlexibleBase
    from bondid.exceptions import ConfigError

    with pytest.raises(ConfigError, match="variant_nodes"):
        FlexibleBase(variant_nodes=variant_nodes)


def test_a_variant_of_the_main_length_is_dropped(doc):
    """A variant length equal to the main one, or repeated, gives one chain of that length."""
    from bondid.diagnose.effects.flexible_base import FlexibleBase

    (c,) = FlexibleBase(n_nodes=4, variant_nodes=(4, 3, 3)).candidates(doc)
    assert _nodes(c) == 4 and [_nodes(v) for v in c.variants] == [3]


def test_variant_lengths_from_a_generator_are_kept(doc):
    """Lengths given by a one-pass iterable (a generator) give their chains too: they are
    read once, not once to check and again to keep."""
    from bondid.diagnose.effects.flexible_base import FlexibleBase

    (c,) = FlexibleBase(n_nodes=6, variant_nodes=(n for n in (4, 3))).candidates(doc)
    assert [_nodes(v) for v in c.variants] == [4, 3]
