"""The one-at-a-time sweep: one parameter at a time over 50 %..150 % of nominal.

For every parameter ``i`` and scale factor ``s`` (default 0.5, 0.6, ..., 1.5) the parameter is
set to ``p0_i + (s − 1)·scale_i`` with every other parameter at its nominal value, and the cost
is evaluated overall and per response direction (output joint of the channels: ``x``, ``y``,
``z`` on the bonder). For ``p0_i ≠ 0`` that is exactly ``s·p0_i`` (``scale_i = p0_i``). A parameter
whose nominal value is 0 is swept over the *absolute* range ``(s − 1)·ref_i`` with the reference
magnitude of :func:`bondid.sensitivity._common.reference_scales`; values that would be negative
for a non-negative quantity (stiffness, damping, mass) are skipped and reported as NaN.

The cost is the problem's ``‖r‖²`` (for the default ``complex_log`` residual the mean square
complex-log error in dB²); the per-direction cost is the mean square over that direction's
channels only, so each panel reads on the same scale as the overall cost.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from ..cost import CostOptions
from ..data.measurement import FrfData
from ..exceptions import ComputationError, ConfigError
from ..interrupt import ignore_in_worker, signals_deferred, terminate_on_interrupt
from ..model.document import UrdfDocument
from ._common import Setup, label_masks, make_setup

_NON_NEGATIVE = ("stiffness", "damping", "mass")


def default_scales(lo: float = 0.5, hi: float = 1.5, step: float = 0.1) -> np.ndarray:
    """Scale factors ``lo, lo + step, ..., hi`` (1 included when on the grid), ``(n_s,)``."""
    if not (0 <= lo < hi) or step <= 0:
        raise ConfigError(f"sweep range {lo}:{hi}:{step}: need 0 ≤ lo < hi and step > 0")
    n = int(np.floor((hi - lo) / step + 1e-9)) + 1
    return np.round(lo + step * np.arange(n), 12)


@dataclass
class SweepResult:
    """Costs of the one-at-a-time sweep.

    Attributes:
        names: parameter names ``(n_p,)``.
        scales: scale factors ``(n_s,)`` (dimensionless).
        values: the parameter value at each step ``(n_p, n_s)`` (SI units; NaN = skipped).
        costs: overall cost ``(n_p, n_s)`` (residual units², dB² for ``complex_log``).
        direction_costs: per response direction ``(n_dir, n_p, n_s)``.
        directions: output joint names ``(n_dir,)``.
        cost_nominal: overall cost at the nominal parameters; direction_nominal ``(n_dir,)``.
        zero_nominal: parameters swept over an absolute range (nominal value 0).
        wall_s: wall time of the sweep, s; workers: processes used.
    """

    names: tuple[str, ...]
    scales: np.ndarray
    values: np.ndarray
    costs: np.ndarray
    direction_costs: np.ndarray
    directions: tuple[str, ...]
    cost_nominal: float
    direction_nominal: np.ndarray
    zero_nominal: tuple[str, ...]
    wall_s: float
    workers: int

    def spread(self) -> np.ndarray:
        """Cost range ``max − min`` over the sweep per parameter, ``(n_p,)`` (NaN ignored)."""
        c = np.where(np.isfinite(self.costs), self.costs, np.nan)
        return np.nanmax(c, axis=1) - np.nanmin(c, axis=1)


# -- the per-parameter job (module level so that worker processes can run it) -------------
_STATE: dict[str, object] = {}


def _init(setup: Setup, dir_masks: np.ndarray) -> None:
    _STATE["setup"] = setup
    _STATE["masks"] = dir_masks


def _init_worker(setup: Setup, dir_masks: np.ndarray) -> None:
    ignore_in_worker()  # the parent stops the workers on Ctrl-C
    _init(setup, dir_masks)


def _costs_for(i: int, values: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Overall ``(n_s,)`` and per-direction ``(n_dir, n_s)`` costs of parameter ``i``."""
    setup = _STATE["setup"]
    masks = _STATE["masks"]
    assert isinstance(setup, Setup) and isinstance(masks, np.ndarray)
    n_s = values.size
    total = np.full(n_s, np.nan)
    per_dir = np.full((masks.shape[0], n_s), np.nan)
    for j, v in enumerate(values):
        if not np.isfinite(v):
            continue
        x = setup.pmap.p0.copy()
        x[i] = v
        r = setup.problem.residual(setup.pmap, x)
        r2 = r * r
        total[j] = r2.sum()
        for d, m in enumerate(masks):
            per_dir[d, j] = setup.mean_square(r2, m)
    return i, total, per_dir


def sweep_values(setup: Setup, scales: np.ndarray) -> np.ndarray:
    """Parameter values of the sweep ``(n_p, n_s)``; NaN where a value would be invalid."""
    p0, sc = setup.pmap.p0, setup.scale
    vals = p0[:, None] + (np.asarray(scales)[None, :] - 1.0) * sc[:, None]
    for i, k in enumerate(setup.kinds):
        if k in _NON_NEGATIVE:
            vals[i] = np.where(vals[i] < 0, np.nan, vals[i])
    return vals


def run_sweep(
    setup: Setup,
    scales: np.ndarray | None = None,
    *,
    workers: int = 2,
    progress: Callable[[int, str], None] | None = None,
) -> SweepResult:
    """The one-at-a-time sweep on a prepared :class:`Setup` (see :func:`sensitivity_sweep`)."""
    s = default_scales() if scales is None else np.asarray(scales, dtype=float)
    t0 = time.perf_counter()
    vals = sweep_values(setup, s)
    directions, masks = label_masks(setup.direction)
    n_p = setup.n_params
    costs = np.full((n_p, s.size), np.nan)
    dcosts = np.full((len(directions), n_p, s.size), np.nan)
    r0 = setup.problem.residual(setup.pmap, setup.pmap.p0)
    r02 = r0 * r0
    nominal = float(r02.sum())
    dnom = np.array([setup.mean_square(r02, m) for m in masks])
    at_one = np.abs(s - 1.0) < 1e-12
    todo = vals.copy()
    todo[:, at_one] = np.nan  # the nominal point is shared: evaluated once above

    def store(i: int, tot: np.ndarray, per: np.ndarray) -> None:
        costs[i] = tot
        dcosts[:, i] = per
        costs[i, at_one] = nominal
        dcosts[:, i][:, at_one] = dnom[:, None]
        if progress is not None:
            progress(1, setup.names[i])

    n_workers = max(1, min(int(workers), n_p))
    _evaluate(setup, masks, todo, n_workers, store)
    return SweepResult(
        names=setup.names,
        scales=s,
        values=vals,
        costs=costs,
        direction_costs=dcosts,
        directions=directions,
        cost_nominal=nominal,
        direction_nominal=dnom,
        zero_nominal=setup.zero_nominal,
        wall_s=time.perf_counter() - t0,
        workers=n_workers,
    )


def _evaluate(
    setup: Setup,
    masks: np.ndarray,
    todo: np.ndarray,
    n_workers: int,
    store: Callable[[int, np.ndarray, np.ndarray], None],
) -> None:
    """Evaluate the costs of every parameter's sweep values ``todo`` ``(n_p, n_scales)`` (NaN:
    skip), in this process or in ``n_workers`` processes, handing each parameter's
    ``(index, total costs, costs per direction mask)`` to ``store`` as it completes."""
    n_p = setup.n_params
    if n_workers == 1:
        _init(setup, masks)
        try:
            for i in range(n_p):
                store(*_costs_for(i, todo[i]))
        finally:
            _STATE.clear()
        return
    try:
        pool = ProcessPoolExecutor(
            max_workers=n_workers, initializer=_init_worker, initargs=(setup, masks)
        )
        with terminate_on_interrupt(pool):
            with signals_deferred():  # the workers start here: recorded before a Ctrl-C lands
                futures = [pool.submit(_costs_for, i, todo[i]) for i in range(n_p)]
            for fut in as_completed(futures):
                store(*fut.result())
    except (OSError, RuntimeError) as exc:  # BrokenProcessPool is a RuntimeError
        raise ComputationError(f"sensitivity sweep: worker processes failed ({exc})") from exc


def sensitivity_sweep(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    options: CostOptions | None = None,
    *,
    free: Sequence[str] = ("all",),
    scales: np.ndarray | None = None,
    workers: int = 2,
    progress: Callable[[int, str], None] | None = None,
) -> SweepResult:
    """The one-at-a-time sweep: each parameter alone over ``scales`` × nominal.

    Args:
        doc: the model (its values are the nominal ``θ0``).
        datasets: measured FRFs (each at its operating point).
        options: cost options (default :class:`~bondid.cost.CostOptions`).
        free: parameters to sweep (names, globs, groups; default every parameter).
        scales: scale factors ``(n_s,)``; default 0.5..1.5 in steps of 0.1.
        workers: processes (parameters are distributed over them); 1 = in this process.
        progress: called as ``progress(1, name)`` after each parameter.

    Returns:
        :class:`SweepResult` with ``costs`` ``(n_p, n_s)`` and ``direction_costs``
        ``(n_dir, n_p, n_s)``.
    """
    setup = make_setup(doc, datasets, options, free)
    return run_sweep(setup, scales, workers=workers, progress=progress)
