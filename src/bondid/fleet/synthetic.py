"""Synthetic fleets for tests and benchmarks: :func:`make_fleet`.

Each machine is the nominal model with chosen parameters scaled by a random factor (uniform in
``1 ± spread``), some machines with planted faults (a parameter scaled by a given factor); its
measured FRFs come from :func:`bondid.simulate.simulate`, one CSV per operating point, in
``DIR/<id>/``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..data.io import write_frf
from ..model.document import UrdfDocument
from ..model.parameters import get_parameter, set_parameter
from ..simulate import log_grid, simulate


def make_fleet(
    nominal: UrdfDocument,
    out_dir: str | Path,
    *,
    n_machines: int,
    parameters: Sequence[str],
    spread: float = 0.1,
    faults: Mapping[str, Mapping[str, float]] | None = None,
    operating_points: Sequence[Mapping[str, float]] = ({},),
    freq: tuple[float, float, int] = (1.0, 4000.0, 200),
    noise: float = 0.02,
    seed: int = 0,
) -> dict[str, dict[str, float]]:
    """Write a synthetic fleet and return each machine's true parameter values.

    Args:
        nominal: the design's model (not modified).
        out_dir: the fleet folder (``out_dir/m00``, ``out_dir/m01``, ...).
        n_machines: number of machines.
        parameters: parameter names drawn at random, each machine.
        spread: relative half-width of the uniform spread (0.1 = ±10 %).
        faults: ``{machine_id: {parameter: factor of the nominal value}}``, planted after the
            random draw (replacing it).
        operating_points: one data file per operating point (joint positions, m or rad).
        freq: ``(f_lo Hz, f_hi Hz, n)``, log-spaced.
        noise: relative complex measurement noise (with a −70 dB sensor floor).
        seed: random seed (the draws and the noise).

    Returns:
        ``{machine_id: {parameter: true value}}``.
    """
    rng = np.random.default_rng(seed)
    root = Path(out_dir)
    f = log_grid(*freq)
    truth: dict[str, dict[str, float]] = {}
    width = max(2, len(str(n_machines - 1)))
    for k in range(n_machines):
        mid = f"m{k:0{width}d}"
        doc = UrdfDocument.from_string(nominal.to_string(), source=f"{mid} truth")
        values = {
            p: get_parameter(nominal, p) * (1 + rng.uniform(-spread, spread)) for p in parameters
        }
        for p, factor in (faults or {}).get(mid, {}).items():
            values[p] = get_parameter(nominal, p) * factor
        for p, v in values.items():
            set_parameter(doc, p, v)
        truth[mid] = values
        (root / mid).mkdir(parents=True, exist_ok=True)
        for i, op in enumerate(operating_points):
            data = simulate(doc, op, f, noise=noise, seed=seed * 1000 + k * 10 + i)
            data.source = str(root / mid / f"q{i}.csv")
            write_frf(data, root / mid / f"q{i}.csv")
    return truth
