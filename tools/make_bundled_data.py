"""Regenerate the bundled measured data set in ``data/`` (see data/README.md).

A "true" bonder differs from ``urdf/bonder.urdf`` in every inertial and joint parameter by
10–30 % (random sign, seeded), staying physically consistent with each CoM inside its
collision hull; its FRFs are simulated with measurement noise at two operating points.

    python tools/make_bundled_data.py [--out data] [--seed 2026]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "src") not in sys.path:
    sys.path.insert(0, str(ROOT / "src"))

from bondid.consistency import is_consistent, link_hull, pi_from_urdf  # noqa: E402
from bondid.data.io import write_frf  # noqa: E402
from bondid.model import (  # noqa: E402
    UrdfDocument,
    get_parameter,
    link_inertial,
    parameter_infos,
    set_parameter,
)
from bondid.simulate import log_grid, simulate  # noqa: E402

OPERATING_POINTS = {"bonder_q0": {}, "bonder_q1": {"x": 0.05, "y": -0.03, "z": 0.1}}


def perturbed_truth(doc: UrdfDocument, seed: int) -> tuple[UrdfDocument, dict[str, float]]:
    """A copy of ``doc`` with every parameter changed by ±10–30 %, physically consistent."""
    rng = np.random.default_rng(seed)
    truth = doc.copy()
    factors: dict[str, float] = {}
    infos = parameter_infos(doc)
    links = sorted({p.owner for p in infos if p.is_inertial})
    for link in links:
        hull = link_hull(doc.link(link))
        for _attempt in range(200):
            trial = truth.copy()
            f_link = {}
            for p in infos:
                if p.owner != link:
                    continue
                f = 1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.10, 0.30)
                f_link[p.name] = f
                set_parameter(trial, p.name, get_parameter(doc, p.name) * f)
            m, c, Ic = link_inertial(trial, link)
            if is_consistent(pi_from_urdf(m, c, Ic)) and (hull is None or hull.contains(c)):
                truth, factors = trial, {**factors, **f_link}
                break
        else:
            raise RuntimeError(f"no consistent perturbation found for {link}")
    for p in infos:
        if p.is_inertial:
            continue
        value = get_parameter(doc, p.name)
        if value == 0.0:
            continue
        f = 1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.10, 0.30)
        factors[p.name] = f
        set_parameter(truth, p.name, value * f)
    return truth, factors


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--model", type=Path, default=ROOT / "urdf" / "bonder.urdf")
    ap.add_argument("--out", type=Path, default=ROOT / "data")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--floor-db", type=float, default=-70.0)
    args = ap.parse_args(argv)
    doc = UrdfDocument.load(args.model)
    truth, factors = perturbed_truth(doc, args.seed)
    truth.source = None
    truth.write(args.out / "truth" / "bonder_truth.urdf")
    f = log_grid(1.0, 4000.0, 2000)
    for k, (stem, op) in enumerate(OPERATING_POINTS.items()):
        data = simulate(truth, op, f, noise=args.noise, floor_db=args.floor_db, seed=args.seed + k)
        write_frf(data, args.out / f"{stem}.csv")
        print(f"wrote {args.out / (stem + '.csv')} at {op or 'neutral'}")
    spread = np.abs(np.array(list(factors.values())) - 1.0)
    print(
        f"truth: {len(factors)} parameters changed by {100 * spread.min():.1f}–"
        f"{100 * spread.max():.1f} % (median {100 * np.median(spread):.1f} %)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
