"""Which joints' positions change the linearised model, and data files that do not say where
they were measured.

A data file without an operating point is fitted at the neutral pose (q = 0). That is right
only when the file was measured there, or when the pose does not matter: when moving the
driven joints leaves the mass and stiffness matrices unchanged. :func:`pose_warnings` names
each file that states no operating point while the model depends on the pose.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..data.io import states_operating_point
from ..data.measurement import FrfData
from ..exceptions import BondidError
from ..model.document import UrdfDocument

#: the joint displacement of the check (m or rad)
STEP = 0.01
#: a relative change of M or K above this (of the largest entry) makes a joint pose-dependent
REL_TOL = 1e-6


def pose_dependent_joints(doc: UrdfDocument) -> list[str]:
    """The driven joints (those with a transmission) whose position changes ``M`` or ``K`` of
    the model linearised at the neutral pose (by more than :data:`REL_TOL` of the largest
    entry, for a :data:`STEP` displacement)."""
    from ..linear.affine import build_affine_model

    try:
        base = build_affine_model(doc, {}).linear_model()
    except (BondidError, np.linalg.LinAlgError, ValueError):
        return []
    scale_m = max(float(np.abs(base.M).max()), 1e-300)
    scale_k = max(float(np.abs(base.K).max()), 1e-300)
    out = []
    for name in dict.fromkeys(t.joint for t in doc.transmissions):
        try:
            lm = build_affine_model(doc, {name: STEP}).linear_model()
        except (BondidError, np.linalg.LinAlgError, ValueError):
            continue
        dm = float(np.abs(lm.M - base.M).max()) / scale_m
        dk = float(np.abs(lm.K - base.K).max()) / scale_k
        if dm > REL_TOL or dk > REL_TOL:
            out.append(name)
    return out


def pose_warnings(doc: UrdfDocument, datasets: Sequence[FrfData]) -> list[str]:
    """A warning for each data file that states no operating point (and was given none on
    the command line) while the model's M or K depend on the pose."""
    silent = [
        ds
        for ds in datasets
        if not ds.operating_point and ds.source and not states_operating_point(ds.source)
    ]
    if not silent:
        return []
    joints = pose_dependent_joints(doc)
    if not joints:
        return []
    example = ",".join(f"{j}=..." for j in joints)
    return [
        f"{ds.source}: the file states no operating point, and the model's mass or stiffness"
        f" depends on the position of joint(s) {', '.join(joints)}: it is fitted at the"
        f" neutral pose (q = 0); if it was measured elsewhere, give"
        f" --operating-point {ds.source}={example} (or [operating_points] in the study file)"
        for ds in silent
    ]
