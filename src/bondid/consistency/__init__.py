"""Physical consistency of rigid-body dynamic parameters, for the constrained fit.

* :mod:`.pseudo_inertia` — ``pi`` (10,) in Pinocchio's order ↔ URDF form ↔ pseudo-inertia ``J``;
  consistency test and report.
* :mod:`.log_cholesky` — θ (10,) ↦ ``pi`` in numpy and CasADi, its Jacobian, and the inverse.
* :mod:`.hull` — convex hull ``A x ≤ b`` of a link's geometry (link frame).
* :mod:`.projection` — nearest feasible ``pi`` (consistent, CoM inside the shrunk hull).

CasADi, trimesh and scipy are imported lazily inside the functions that need them.
"""

from bondid.consistency.hull import (
    Hull,
    hull_from_halfspaces,
    hull_from_points,
    link_hull,
    make_resolver,
)
from bondid.consistency.log_cholesky import (
    THETA_NAMES,
    jacobian_pi_theta,
    pi_from_theta,
    pi_from_theta_casadi,
    theta_from_pi,
)
from bondid.consistency.projection import feasibility_margins, is_feasible, project_feasible
from bondid.consistency.pseudo_inertia import (
    consistency_report,
    is_consistent,
    pi_from_pseudo_inertia,
    pi_from_urdf,
    pseudo_inertia,
    second_moment_com,
    urdf_from_pi,
)

__all__ = [
    "THETA_NAMES",
    "Hull",
    "consistency_report",
    "feasibility_margins",
    "hull_from_halfspaces",
    "hull_from_points",
    "is_consistent",
    "is_feasible",
    "jacobian_pi_theta",
    "link_hull",
    "make_resolver",
    "pi_from_pseudo_inertia",
    "pi_from_theta",
    "pi_from_theta_casadi",
    "pi_from_urdf",
    "project_feasible",
    "pseudo_inertia",
    "second_moment_com",
    "theta_from_pi",
    "urdf_from_pi",
]
