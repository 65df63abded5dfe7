"""Candidate effects on a free-free structure (a floating base): no candidate at the
floating joint, whose six axes already move, and none that would move no inertia of its own
(a singular mass matrix) — the screening of such a model must not fail."""

from __future__ import annotations

import numpy as np

from bondid.diagnose.effects import get_effects
from bondid.diagnose.effects.joint_compliance import JointCompliance
from bondid.diagnose.effects.topology import effective_inertia, interfaces
from bondid.linear.affine import build_affine_model
from bondid.model import UrdfDocument, insert_parasitic_joint
from bondid.model.authoring import add_floating_base

BEAM = "examples/free_free_beam/beam_chain.urdf"


def _floating() -> UrdfDocument:
    doc = UrdfDocument.load(BEAM)
    add_floating_base(doc)
    return doc


def test_the_floating_joint_is_free_along_every_axis():
    doc = _floating()
    root_joint = next(j for j in doc.robot.joints if j.type == "floating")
    (free,) = [i for i in interfaces(doc) if root_joint.name in i.joints]
    assert free.missing == []
    locations = [c.location for c in JointCompliance().candidates(doc)]
    assert locations and not [loc for loc in locations if loc.startswith(f"{free.parent}->")]


def test_a_dof_that_moves_nothing_new_weighs_nothing():
    """A prismatic DOF in series with the floating joint's own translation: the mass matrix
    is singular, the DOF weighs 0 (a candidate there is left out); a real DOF weighs what the
    mass matrix says."""
    doc = _floating()
    root_joint = next(j for j in doc.robot.joints if j.type == "floating")
    probe = doc.copy()
    insert_parasitic_joint(probe, "extra_tx", after=root_joint.name, kind="prismatic",
                           axis=(1.0, 0.0, 0.0), stiffness=1.0)  # fmt: skip
    assert effective_inertia(probe, "extra_tx") == 0.0
    am = build_affine_model(doc)
    j = am.dofs.index("j1")
    expected = 1.0 / np.linalg.inv(am.mass_matrix())[j, j]
    assert effective_inertia(doc, "j1") == expected


def test_every_effect_offers_candidates_on_a_free_free_structure():
    doc = _floating()
    for effect in get_effects(None):
        for cand in effect.candidates(doc):
            assert cand.parameters, (effect.name, cand.location)
