"""A fleet of machines of one design: ``python -m bondid.fleet`` (fit every machine on Dask,
the fleet's statistics and outliers). Modules: :mod:`.machines` (discover ``DIR``),
:mod:`.worker` (one machine, in a Dask worker), :mod:`.cluster` (the Dask client),
:mod:`.runner` (submit, collect, progress), :mod:`.state` (result folders, resumption),
:mod:`.aggregate` (statistics, outliers), :mod:`.outputs` / :mod:`.plot` (fleet.json, fleet.csv,
strip plot), :mod:`.cli`. Nothing heavy is imported here.
"""

from __future__ import annotations

from ..lazy import lazy_getattr

_LAZY = {
    "discover": "machines",
    "run_machine": "worker",
    "MachineJob": "worker",
}

__all__ = sorted(_LAZY)

__getattr__ = lazy_getattr(__name__, _LAZY)
