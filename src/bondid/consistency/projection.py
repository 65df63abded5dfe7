"""Project a body's dynamic parameters onto the feasible set of the constrained fit.

Feasible means: physically consistent (pseudo-inertia ``J ≻ 0`` with a margin) and, when a hull
is given, the CoM inside the hull shrunk by a margin. (CoM in the hull is necessary, not
sufficient, for the mass to lie inside the body.) CAD priors can violate this — the UR5's wrist
link CoMs lie ~4.7 cm outside their collision hulls — and a fit must start from a feasible point.

The metric. Write a body as ``(m, c, Σ_c)``: mass, CoM and second moment about the CoM
``Σ_c = ½ tr(I_c) 𝟙 − I_c``. Then ``J ≻ 0`` ⇔ ``m > 0`` and ``Σ_c ≻ 0``, and the CoM constraint
involves ``c`` only, so the two constraints act on separate coordinates. The projection keeps
``m``, moves ``c`` to the Euclidean-nearest point of the shrunk hull (``I_c`` about the CoM is
kept: the mass distribution is translated rigidly), and replaces ``Σ_c`` by its Frobenius-nearest
matrix with eigenvalues ``≥ floor`` (eigenvalue clipping). This is the exact nearest feasible
point for the product metric ``‖Δc‖² + w ‖ΔΣ_c‖_F²`` (any ``w > 0``) with the mass fixed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bondid.consistency.hull import Hull
from bondid.consistency.pseudo_inertia import _label, as_pi, pi_from_urdf, urdf_from_pi
from bondid.exceptions import ParameterError

FloatArray = NDArray[np.float64]

#: Relative slack on the margins when deciding that a point is already feasible, so that a
#: projected result counts as feasible (projection is idempotent despite rounding).
_ACCEPT = 1.0 - 1e-6


def feasibility_margins(
    pi: ArrayLike, hull: Hull | None = None, *, margin_rel: float = 1e-3
) -> tuple[float, float]:
    """The CoM margin (m) and second-moment floor (kg·m²) used by :func:`project_feasible`.

    ``margin = margin_rel · ℓ`` with ``ℓ`` the hull's bounding-box diagonal (0 without a hull);
    ``floor = margin_rel² · max(σ_max, m ℓ²)`` with ``σ_max`` the largest principal second moment
    about the CoM — with a hull, typically ``m · margin²``: the body is at least ``margin`` thick
    (RMS) along every principal axis.
    """
    p = as_pi(pi)
    m, _, inertia_c = urdf_from_pi(p)
    sigma = np.linalg.eigvalsh(0.5 * np.trace(inertia_c) * np.eye(3) - inertia_c)
    ell = hull.size if hull is not None else 0.0
    return margin_rel * ell, margin_rel**2 * max(float(sigma[-1]), m * ell**2)


def is_feasible(pi: ArrayLike, hull: Hull | None = None, *, margin_rel: float = 1e-3) -> bool:
    """Whether ``pi`` (10,) is already feasible, i.e. :func:`project_feasible` returns it as is."""
    p = np.asarray(pi, dtype=float)
    if p.shape != (10,) or not np.all(np.isfinite(p)) or not p[0] > 0.0:
        return False
    margin, floor = feasibility_margins(p, hull, margin_rel=margin_rel)
    _, c, inertia_c = urdf_from_pi(p)
    sigma = np.linalg.eigvalsh(0.5 * np.trace(inertia_c) * np.eye(3) - inertia_c)
    com_ok = hull is None or bool(hull.contains(c, margin * _ACCEPT))
    return com_ok and floor > 0.0 and bool(sigma[0] >= floor * _ACCEPT)


def project_feasible(
    pi: ArrayLike,
    hull: Hull | None = None,
    *,
    margin_rel: float = 1e-3,
    name: str | None = None,
) -> FloatArray:
    """Nearest feasible dynamic parameters (10,) to ``pi`` (10,), mass kept (see module doc).

    Args:
        pi: dynamic parameters (10,), Pinocchio's order, inertia about the link origin.
        hull: the link's hull (link frame, m), or None for no CoM constraint.
        margin_rel: the CoM must lie ``margin_rel · ℓ`` inside the hull (``ℓ`` its bounding-box
            diagonal) and every principal second moment about the CoM must be at least
            ``margin_rel² · max(σ_max, m ℓ²)`` kg·m² (see :func:`feasibility_margins`).
        name: body name for error messages.

    Returns:
        A copy of ``pi`` when it is already feasible (:func:`is_feasible`); otherwise the
        projected parameters (10,), which satisfy ``is_feasible``.

    Raises:
        ParameterError: non-finite ``pi``; mass ≤ 0 (it is kept, so nothing can fix it); no hull
            and no positive second moment to scale the floor from.
        ComputationError: the hull is too thin for the margin.
    """
    p = as_pi(pi, name)
    if not p[0] > 0.0:
        raise ParameterError(
            f"{_label(name)}: mass {p[0]:g} kg is not > 0; projection keeps the mass, give a "
            "positive one"
        )
    if is_feasible(p, hull, margin_rel=margin_rel):
        return p.copy()
    margin, floor = feasibility_margins(p, hull, margin_rel=margin_rel)
    if not floor > 0.0:
        raise ParameterError(
            f"{_label(name)}: no principal second moment about the CoM is > 0 and no hull gives "
            "a length scale; cannot choose an inertia floor"
        )
    m, c, inertia_c = urdf_from_pi(p)
    if hull is not None and not hull.contains(c, margin * _ACCEPT):
        c = hull.shrunk(margin).nearest_point(c)
    sigma_c = 0.5 * np.trace(inertia_c) * np.eye(3) - inertia_c
    sigma, R = np.linalg.eigh(sigma_c)
    if sigma[0] < floor * _ACCEPT:
        sigma_c = (R * np.maximum(sigma, floor)) @ R.T
        inertia_c = np.trace(sigma_c) * np.eye(3) - sigma_c
    return pi_from_urdf(m, c, inertia_c)
