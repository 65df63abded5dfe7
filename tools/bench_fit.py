"""Benchmark: bondid.fit against the seed-style optimisers on the reference bonder problem.

The problem: ``urdf/bonder.urdf``, every inertial and joint parameter free
(``select_parameters(doc, ["all"])``, 52), synthetic data from a *truth* whose parameters differ
from the nominal model by 10–30 % (physically consistent: the second-moment matrix of each body
is scaled, so the truth stays a real rigid body), 1 % relative measurement noise (no additive
noise floor: one 80 dB below the peak would bury the high-frequency receptance, 140 dB below
its 1 Hz level, and the log cost would then measure noise), two operating points, 2000
log-spaced frequencies 1–4000 Hz, 9 channels (x, y, z × x, y, z). Every method starts from the
nominal model with the same bounds (±50 % of each value, inertia and CoM widened as in
:func:`bondid.optim.bounds.default_bounds`; the zero stiffness of the x and y axes gets
[0, 50] N/m) and is scored with the same cost (:class:`bondid.cost.FrfProblem`, complex-log
residual, L2, no coherence weighting, so ``cost = db_rms²``):

(a) ``bondid.fit.solver.fit`` — IPOPT, exact Jacobian, Gauss–Newton Hessian, physical constraints;
(b) scipy ``minimize(method="L-BFGS-B")`` on the scalar cost with finite-difference gradients
    (the seed's fmincon analogue);
(c) scipy ``least_squares`` (trf) with a ``'2-point'`` finite-difference Jacobian;
(d) Py-BOBYQA (derivative-free, the seed report's recommendation).

The baselines work in box-normalised variables ``u = (p − lo)/(hi − lo) ∈ [0, 1]`` (which helps
them: the raw parameters span 1e-6 … 1e8). Each has a wall-clock budget (``--budget-s``) and an
evaluation budget (``--max-evals``) and is reported "not converged" if it hits one; its best
point so far is scored.

Usage::

    PYTHONPATH=src python tools/bench_fit.py [--quick] [--budget-s 600] [--json out.json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import signal
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "src") not in sys.path:
    sys.path.insert(0, str(ROOT / "src"))

from bondid.cost import CostOptions, FrfProblem  # noqa: E402
from bondid.data import FrfData, add_measurement_noise  # noqa: E402
from bondid.linear import build_affine_model  # noqa: E402
from bondid.linear.parameter_map import ParameterMap  # noqa: E402
from bondid.model import (  # noqa: E402
    UrdfDocument,
    get_parameters,
    link_inertial,
    parameter_infos,
    select_parameters,
    set_link_inertial,
    set_parameter,
)

MODEL = ROOT / "urdf" / "bonder.urdf"
OPERATING_POINTS = ({}, {"x": 0.05, "y": -0.04, "z": 0.2})
ZERO_STIFFNESS_BOUND = (0.0, 50.0)


# -- the reference problem ----------------------------------------------------------------
def make_truth(doc: UrdfDocument, rng: np.random.Generator) -> UrdfDocument:
    """A copy of ``doc`` with every parameter changed by 10–30 % (random sign), physically.

    Per body: mass × (1 ± δ); CoM moved by ±δ·max(|c|, 0.01 m) per axis (kept inside the body);
    second moments about the CoM Σ = ½tr(I)𝟙 − I scaled as D Σ D with D = diag(√(1 ± δ)),
    which keeps Σ ≻ 0 and hence a consistent inertia I = tr(Σ)𝟙 − Σ. Joints: stiffness and
    damping × (1 ± δ) (zero stays zero).
    """
    truth = doc.copy()

    def delta(n: int = 1) -> np.ndarray:
        return rng.uniform(0.1, 0.3, n) * rng.choice([-1.0, 1.0], n)

    links = sorted({p.owner for p in parameter_infos(doc) if p.is_inertial})
    for link in links:
        m, c, I = link_inertial(doc, link)
        m2 = m * (1.0 + delta()[0])
        c2 = c + delta(3) * np.maximum(np.abs(c), 0.01)
        S = 0.5 * np.trace(I) * np.eye(3) - I
        D = np.diag(np.sqrt(1.0 + delta(3)))
        S2 = D @ S @ D
        I2 = np.trace(S2) * np.eye(3) - S2
        set_link_inertial(truth, link, m2, c2, I2)
    for p in parameter_infos(doc):
        if p.kind in ("stiffness", "damping"):
            v = get_parameters(doc, [p.name])[0]
            set_parameter(truth, p.name, v * (1.0 + delta()[0]))
    return truth


def make_datasets(
    truth: UrdfDocument, freq_hz: np.ndarray, noise: float, rng: np.random.Generator
) -> list[FrfData]:
    """Noisy receptance FRFs ``(3, 3, n_freq)`` of ``truth`` at each operating point."""
    out = []
    for op in OPERATING_POINTS:
        H = build_affine_model(truth, op).linear_model().frf(freq_hz)
        Hn, _ = add_measurement_noise(H, freq_hz, rel=noise, floor_db=None, rng=rng)
        out.append(FrfData(freq_hz, ("x", "y", "z"), ("x", "y", "z"), Hn, operating_point=op))
    return out


def bench_bounds(doc: UrdfDocument, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    from bondid.optim.bounds import default_bounds

    lo, hi = default_bounds(doc, names, rel={"mass": 0.5})
    v = get_parameters(doc, names)
    for j, n in enumerate(names):
        if n.endswith(".stiffness") and v[j] == 0.0:
            lo[j], hi[j] = ZERO_STIFFNESS_BOUND
    return lo, hi


# -- baselines ----------------------------------------------------------------------------


class _Budget(Exception):
    pass


@dataclass
class Tracker:
    """Counts evaluations, keeps the best point, enforces the budget."""

    budget_s: float
    max_evals: int
    t0: float = field(default_factory=time.perf_counter)
    evals: int = 0
    best_cost: float = math.inf
    best_u: np.ndarray | None = None
    hit: str | None = None

    def check(self, u: np.ndarray, cost: float) -> None:
        self.evals += 1
        if math.isfinite(cost) and cost < self.best_cost:
            self.best_cost, self.best_u = cost, np.array(u, dtype=float)
        if time.perf_counter() - self.t0 > self.budget_s:
            self.hit = f"wall-clock budget {self.budget_s:g} s"
            raise _Budget
        if self.evals >= self.max_evals:
            self.hit = f"evaluation budget {self.max_evals}"
            raise _Budget


@contextlib.contextmanager
def wall_clock_cap(seconds: float, tracker: Tracker) -> Iterator[None]:
    """Raise :class:`_Budget` in the main thread after ``seconds`` (SIGALRM), so a method
    spending its time outside the objective (Py-BOBYQA's model updates) is stopped too."""

    def handler(signum: int, frame: object) -> None:
        tracker.hit = f"wall-clock budget {tracker.budget_s:g} s"
        raise _Budget

    if not hasattr(signal, "setitimer"):  # pragma: no cover - not POSIX
        yield
        return
    old = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, max(seconds, 1e-3))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old)


@dataclass
class Row:
    method: str
    wall_s: float
    cost: float
    evals: str
    converged: bool
    status: str
    x: np.ndarray

    @property
    def db_rms(self) -> float:
        return math.sqrt(self.cost) if self.cost >= 0 else math.nan


def _scaled(problem: FrfProblem, pmap: ParameterMap, lo: np.ndarray, hi: np.ndarray):
    span = hi - lo

    def to_p(u: np.ndarray) -> np.ndarray:
        return lo + np.asarray(u) * span

    def resid(u: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            try:
                r = problem.residual(pmap, to_p(u))
            except (np.linalg.LinAlgError, ValueError):
                r = np.full(problem.n_residuals, 1e3)
        return np.where(np.isfinite(r), r, 1e3)

    return to_p, resid


def run_baseline(
    name: str,
    doc: UrdfDocument,
    datasets: list[FrfData],
    names: list[str],
    options: CostOptions,
    lo: np.ndarray,
    hi: np.ndarray,
    budget_s: float,
    max_evals: int,
) -> Row:
    if name == "bobyqa":
        import pybobyqa  # noqa: F401  (import outside the timed region)

    t0 = time.perf_counter()
    problem = FrfProblem(doc, datasets, options)
    pmap = ParameterMap(doc, problem.affines[0], names)
    to_p, resid = _scaled(problem, pmap, lo, hi)
    u0 = (get_parameters(doc, names) - lo) / (hi - lo)
    tr = Tracker(budget_s, max_evals, t0)

    def r_tracked(u: np.ndarray) -> np.ndarray:
        r = resid(u)
        tr.check(u, float(r @ r))
        return r

    def f_tracked(u: np.ndarray) -> float:
        return float(np.sum(r_tracked(u) ** 2))

    try:
        with wall_clock_cap(budget_s - (time.perf_counter() - t0), tr):
            status, ok = _solve(name, f_tracked, r_tracked, u0, max_evals)
    except _Budget:
        status, ok = f"stopped: {tr.hit}", False
    wall = time.perf_counter() - t0
    assert tr.best_u is not None
    x = to_p(tr.best_u)
    return Row(name, wall, problem.cost(pmap, x), str(tr.evals), ok, status, x)


def _solve(
    name: str,
    f: Callable[[np.ndarray], float],
    r: Callable[[np.ndarray], np.ndarray],
    u0: np.ndarray,
    max_evals: int,
) -> tuple[str, bool]:
    """Run baseline ``name`` on the box [0, 1]^n; returns (message, converged)."""
    import scipy.optimize as so

    if name == "lbfgsb":
        res = so.minimize(
            f, u0, method="L-BFGS-B", bounds=[(0.0, 1.0)] * u0.size,
            options={"maxiter": max_evals, "maxfun": max_evals},
        )  # fmt: skip
        return str(res.message), bool(res.success)
    if name == "least_squares":
        res = so.least_squares(
            r,
            u0,
            jac="2-point",
            bounds=(0.0, 1.0),
            method="trf",
            max_nfev=max_evals,
        )
        return str(res.message), bool(res.status > 0)
    if name == "bobyqa":
        import pybobyqa

        res = pybobyqa.solve(
            f, u0, bounds=(np.zeros_like(u0), np.ones_like(u0)), maxfun=max_evals, rhobeg=0.1,
            rhoend=1e-8,
        )  # fmt: skip
        return str(res.msg), res.flag in (res.EXIT_SUCCESS, res.EXIT_SLOW_WARNING)
    raise ValueError(f"unknown method {name!r}")


def run_bondid(
    doc: UrdfDocument,
    datasets: list[FrfData],
    names: list[str],
    options: CostOptions,
    lo: np.ndarray,
    hi: np.ndarray,
    max_iter: int,
    presolve: int | None = None,
) -> Row:
    from bondid.fit.solver import PRESOLVE_ITER, fit

    t0 = time.perf_counter()
    res = fit(doc, datasets, names, options=options, lower=lo, upper=hi, max_iter=max_iter,
              presolve_iter=PRESOLVE_ITER if presolve is None else presolve)  # fmt: skip
    wall = time.perf_counter() - t0
    problem = FrfProblem(doc, datasets, options)
    pmap = ParameterMap(doc, problem.affines[0], names)
    cost = problem.cost(pmap, res.fitted)
    return Row(
        "bondid.fit", wall, cost, f"{res.iterations} it", res.success, res.status, res.fitted
    )


# -- main ---------------------------------------------------------------------------------
BASELINES: dict[str, str] = {
    "lbfgsb": "(b) L-BFGS-B, FD gradient",
    "least_squares": "(c) least_squares, FD Jacobian",
    "bobyqa": "(d) Py-BOBYQA",
}


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: 200 frequencies, 3 s budgets")
    ap.add_argument("--n-freq", type=int, default=None, help="frequencies (default 2000)")
    ap.add_argument("--budget-s", type=float, default=None, help="wall-clock cap per baseline")
    ap.add_argument("--max-evals", type=int, default=200000, help="evaluation cap per baseline")
    ap.add_argument("--max-iter", type=int, default=200, help="IPOPT iterations for (a)")
    ap.add_argument("--noise", type=float, default=0.01, help="relative measurement noise")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--methods", default="lbfgsb,least_squares,bobyqa", help="baselines to run (comma list)"
    )
    ap.add_argument(
        "--presolve", type=int, default=None,
        help="IPOPT iterations of (a)'s presolved second fit (default: bondid.fit's; 0 = none)",
    )  # fmt: skip
    ap.add_argument("--json", type=Path, default=None, help="also write the table as JSON")
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = _parser()
    args = ap.parse_args(argv)
    n_freq = args.n_freq or (200 if args.quick else 2000)
    budget = args.budget_s if args.budget_s is not None else (3.0 if args.quick else 600.0)
    methods = [m for m in args.methods.split(",") if m]
    for m in methods:
        if m not in BASELINES:
            ap.error(f"unknown method {m!r}; valid: {', '.join(BASELINES)}")

    rng = np.random.default_rng(args.seed)
    doc = UrdfDocument.load(MODEL)
    names = select_parameters(doc, ["all"])
    truth = make_truth(doc, rng)
    freq = np.geomspace(1.0, 4000.0, n_freq)
    datasets = make_datasets(truth, freq, args.noise, rng)
    options = CostOptions(use_coherence=False)
    lo, hi = bench_bounds(doc, names)
    x_truth = get_parameters(truth, names)
    inside = bool(np.all((x_truth >= lo) & (x_truth <= hi)))
    problem = FrfProblem(doc, datasets, options)
    pmap = ParameterMap(doc, problem.affines[0], names)
    c0 = problem.cost(pmap, pmap.p0)
    ct = problem.cost(pmap, x_truth)
    print(
        f"problem: {len(names)} parameters, {n_freq} frequencies x 9 channels x "
        f"{len(datasets)} operating points = {problem.n_residuals} residuals;"
        f" truth inside bounds: {inside}"
    )
    print(f"db_rms at start {math.sqrt(c0):.3f} dB, at the truth {math.sqrt(ct):.3f} dB (noise)")
    sys.stdout.flush()

    rows = [run_bondid(doc, datasets, names, options, lo, hi, args.max_iter, args.presolve)]
    print(f"  (a) done: {rows[0].wall_s:.1f} s, db_rms {rows[0].db_rms:.4f} dB", flush=True)
    for m in methods:
        row = run_baseline(m, doc, datasets, names, options, lo, hi, budget, args.max_evals)
        row.method = BASELINES[m]
        rows.append(row)
        print(f"  {row.method} done: {row.wall_s:.1f} s, db_rms {row.db_rms:.4f} dB", flush=True)
    rows[0].method = "(a) bondid.fit"
    a = rows[0]
    print_table(rows, a)
    if args.json is not None:
        head = {"n_parameters": len(names), "n_freq": n_freq,
                "n_residuals": problem.n_residuals, "budget_s": budget,
                "db_rms_start": math.sqrt(c0), "db_rms_truth": math.sqrt(ct)}  # fmt: skip
        _write_json(args.json, head, rows, a, x_truth)
    return 0


def _write_json(path: Path, head: dict, rows: list[Row], a: Row, x_truth: np.ndarray) -> None:
    """The table as JSON: ``head`` (the problem) and one entry per method."""
    scale = np.maximum(np.abs(x_truth), 1e-12)
    doc_json = {
        **head,
        "rows": [
            {
                "method": r.method, "wall_s": r.wall_s, "cost": r.cost, "db_rms": r.db_rms,
                "evals": r.evals, "converged": r.converged, "status": r.status,
                "time_ratio_to_a": r.wall_s / a.wall_s, "reached_a": reached(r, a),
                "median_rel_error_vs_truth": float(np.median(np.abs(r.x - x_truth) / scale)),
            }
            for r in rows
        ],
    }  # fmt: skip
    path.write_text(json.dumps(doc_json, indent=2) + "\n", encoding="utf-8")


def reached(r: Row, a: Row, rtol: float = 1e-3) -> bool:
    """``r``'s final db_rms is no more than 0.1 % above (a)'s."""
    return r.db_rms <= a.db_rms * (1.0 + rtol)


def print_table(rows: list[Row], a: Row, out: Callable[[str], None] = print) -> None:
    head = (
        f"{'method':<34} {'wall s':>8} {'db_rms dB':>10} {'evals':>8} {'t/t(a)':>8}"
        f" {'reached (a)':>11}  status"
    )
    out(head)
    out("-" * len(head))
    for r in rows:
        conv = r.status if r.converged else f"NOT CONVERGED: {r.status}"
        out(
            f"{r.method:<34} {r.wall_s:>8.1f} {r.db_rms:>10.4f} {r.evals:>8}"
            f" {r.wall_s / a.wall_s:>8.1f} {'yes' if reached(r, a) else 'no':>11}  {conv}"
        )


if __name__ == "__main__":
    sys.exit(main())
