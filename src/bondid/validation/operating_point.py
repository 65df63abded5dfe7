"""Warnings about an operating point: outside the joint limits, or unstable there.

:func:`check_operating_point` returns readable warnings (it raises only for a value outside
any physical range): the run goes on, and every command prints them and stores them under
``warnings`` in its JSON.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..exceptions import BondidError, OperatingPointError
from ..model.document import UrdfDocument
from ..ranges import POSITION

#: an eigenvalue with Re λ > this fraction of |λ| (or > 1e-9 s⁻¹ for λ ≈ 0) counts as unstable
UNSTABLE_TOL = 1e-9
#: an unstable eigenvalue whose growth rate Re λ is below this fraction of the lowest measured
#: angular frequency changes no measured line (its phase there by about twice this, in rad):
#: a near-free motion with a negligible negative stiffness, not an unmeasurable machine
UNSEEN_GROWTH = 1e-3


def limit_warnings(doc: UrdfDocument, op: Mapping[str, float], what: str) -> list[str]:
    """Joints of ``op`` whose value lies outside their URDF ``<limit>``."""
    out = []
    for name, value in op.items():
        try:
            j = doc.joint(name)
        except BondidError:
            continue
        lim = getattr(j, "limit", None)
        if lim is None or j.type not in ("revolute", "prismatic"):
            continue
        lo, hi = lim.lower, lim.upper
        if lo is None or hi is None or lo > hi:
            continue
        if not lo <= float(value) <= hi:
            out.append(
                f"{what}: {name} = {float(value):.6g} is outside the joint's limits"
                f" [{float(lo):.6g}, {float(hi):.6g}] of {doc.source or 'the model'}"
            )
    return out


def stability_warnings(
    doc: UrdfDocument, op: Mapping[str, float], what: str, f_min_hz: float | None = None
) -> list[str]:
    """An eigenvalue of the linearised model with Re λ > 0 (e.g. gravity beats a spring).

    ``f_min_hz`` [Hz]: the lowest frequency measured there, when data were; an eigenvalue
    growing slower than :data:`UNSEEN_GROWTH` × 2π ``f_min_hz`` is not reported."""
    from ..linear.affine import build_affine_model
    from ..linear.linear_model import state_eigenvalues

    try:
        lm = build_affine_model(doc, dict(op)).linear_model().viscous()
        lam = state_eigenvalues(lm.M, lm.K, lm.D)
    except (BondidError, np.linalg.LinAlgError, ValueError):
        return []
    floor = UNSTABLE_TOL * np.maximum(np.abs(lam), 1.0)
    if f_min_hz is not None and f_min_hz > 0:
        floor = np.maximum(floor, UNSEEN_GROWTH * 2 * np.pi * f_min_hz)
    bad = lam[lam.real > floor]
    if bad.size == 0:
        return []
    worst = bad[np.argmax(bad.real)]
    return [
        f"{what}: the linearised model of {doc.source or 'the model'} is unstable there"
        f" ({bad.size} eigenvalue(s) with Re λ > 0, largest {worst.real:.4g} 1/s): a negative"
        " stiffness (gravity beyond a spring?) — an FRF of an unstable model is not measurable"
    ]


def check_range(op: Mapping[str, float], what: str) -> None:
    """Raise :class:`OperatingPointError` for a joint value outside :data:`POSITION`."""
    for name, value in op.items():
        if value not in POSITION:
            raise OperatingPointError(
                f"{what}: {name} = {value!r}; valid: {POSITION.text()} (within the joint's limits)"
            )


def check_operating_point(
    doc: UrdfDocument, op: Mapping[str, float], what: str = "operating point",
    f_min_hz: float | None = None,
) -> list[str]:  # fmt: skip
    """Limit and stability warnings for one operating point (``what`` names its origin;
    ``f_min_hz`` [Hz] the lowest frequency measured there, see :func:`stability_warnings`).

    Raises:
        OperatingPointError: a value outside any physical range (:func:`check_range`).
    """
    check_range(op, what)
    return limit_warnings(doc, op, what) + stability_warnings(doc, op, what, f_min_hz)
