"""The optimisation core: one fit problem, one IPOPT interface, search schedules.

* :class:`FitProblem` (:mod:`.problem`) — built once from (model, data sets, free names, bounds,
  cost options): linearisations, decision vector, residual with exact Jacobian, constraints
  with labels; :meth:`FitProblem.restrict` to names, bands or a residual kind without
  linearising again.
* :func:`solve` (:mod:`.ipopt`, the only module that runs IPOPT, on the problem's CasADi
  functions of :mod:`.nlp`) → :class:`Solution`.
* :func:`run_search` (:mod:`.search`) over a schedule of :class:`Step` (:mod:`.schedules`:
  ``direct``, ``staged``, ``continuation``) → :class:`SearchResult`;
* :func:`keep_best` (:mod:`.multistart`): the one way out of a bad basin — searches from
  ranked starts, the best kept, stopped at the noise level (:class:`NoisePolicy`,
  :mod:`.noise`), when a restart cannot improve, or when one budget is spent.

Names are imported lazily (CasADi and Pinocchio load when a problem is built).
"""

from __future__ import annotations

from ..lazy import lazy_getattr

_LAZY = {
    "Constraints": "constraints",
    "FitProblem": "problem",
    "Solution": "ipopt",
    "solve": "ipopt",
    "SearchResult": "search",
    "Step": "search",
    "StepResult": "search",
    "run_search": "search",
    "keep_best": "multistart",
    "Start": "multistart",
    "Budget": "multistart",
    "NoisePolicy": "noise",
    "fit_result": "outcome",
    "TiedParameters": "tied",
}

__all__ = sorted(_LAZY)

__getattr__ = lazy_getattr(__name__, _LAZY)
