"""The optimisation core: one fit problem, one IPOPT interface, search schedules.

* :class:`FitProblem` (:mod:`.problem`) — built once from (model, data sets, free names, bounds,
  cost options): linearisations, decision vector, residual with exact Jacobian, constraints
  with labels; :meth:`FitProblem.restrict` to names, bands or a residual kind without
  linearising again.
* :func:`solve` (:mod:`.ipopt`, the only module that talks to CasADi/IPOPT) → :class:`Solution`.
* :func:`run_search` (:mod:`.search`) over a schedule of :class:`Step` (:mod:`.schedules`:
  ``direct``, ``staged``, ``continuation``) → :class:`SearchResult`;
  :func:`run_to_noise` (:mod:`.fallback`): the same, plus the band continuation when the
  search ends above the predicted noise level.

Names are imported lazily (CasADi and Pinocchio load when a problem is built).
"""

from __future__ import annotations

from ..lazy import lazy_getattr

_LAZY = {
    "Constraints": "problem",
    "FitProblem": "problem",
    "Solution": "ipopt",
    "solve": "ipopt",
    "SearchResult": "search",
    "Step": "search",
    "StepResult": "search",
    "run_search": "search",
    "run_to_noise": "fallback",
    "fit_result": "outcome",
    "TiedParameters": "tied",
}

__all__ = sorted(_LAZY)

__getattr__ = lazy_getattr(__name__, _LAZY)
