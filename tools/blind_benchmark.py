"""Blind benchmark of ``python -m bondid.diagnose``: can it name an effect withheld from the model?

Each case builds a *truth* machine from the reference bonder (``urdf/bonder.urdf``): random
parameter errors of 10–30 % (every mass, CoM coordinate, inertia tensor (scaled as a whole,
so it stays physical), non-zero spring and damper, each with a random sign), plus at most one
effect, then simulates measured FRFs with noise (2 % relative, sensor floor −70 dB) at two
operating points and writes them as CSV files to a temporary folder. The diagnosis is then
run as a subprocess with ONLY the nominal URDF and those files — nothing about the truth is
passed in. Truth effects are built here, deliberately not identical to the candidates the
diagnosis tries: compliant joints pivot elsewhere than the candidate's pivot, the flexible
base has 5 unequal lumps, heavier at the bottom (the candidate: 4, uniform-rod lumping), the
soft mounts have six different stiffnesses.

Scores per case: top-1 effect class, location (where it applies), and the verdict's
``gap_closed`` against what the truth model itself achieves on the same data
(``1 − db_rms(truth)/gap.db_rms``). Prints a table (Markdown) and a summary against the goals:
class ≥ 90 %, location ≥ 80 %, no effect claimed on "none" cases, median gap_closed ratio ≥ 0.8.

Usage: ``python tools/blind_benchmark.py [--quick] [--cases N] [--out results.json]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from bondid.data.io import write_frf  # noqa: E402
from bondid.data.noise import add_measurement_noise  # noqa: E402
from bondid.model import UrdfDocument, insert_parasitic_joint, set_parameter  # noqa: E402
from bondid.model.parameters import (  # noqa: E402
    get_parameter,
    link_inertial,
    parameter_infos,
    set_link_inertial,
)
from bondid.simulate import log_grid, simulate  # noqa: E402

MODEL = ROOT / "urdf" / "bonder.urdf"
OPS = ({}, {"x": 0.05, "y": -0.03, "z": 0.1})


@dataclass
class Case:
    name: str
    effect: str  # "none" or an effect name
    location: str | None
    spec: dict[str, Any] = field(default_factory=dict)
    seed: int = 0


CASES = [
    Case(
        "jc_x_rx", "joint_compliance", "base->x_stage:rx", {"f": 450.0, "pivot": (0, 0, -0.02)}, 1
    ),
    Case("jc_y_tz", "joint_compliance", "x_stage->y_stage:tz", {"f": 900.0}, 2),
    Case("jc_z_ty", "joint_compliance", "y_stage->z_stage:ty", {"f": 1500.0}, 3),
    Case("jc_y_ry", "joint_compliance", "x_stage->y_stage:ry", {"f": 300.0, "pivot": (0, 0, 0)}, 4),
    Case("fb_800", "flexible_base", "base", {"f": 800.0}, 5),
    Case("fb_1800", "flexible_base", "base", {"f": 1800.0}, 6),
    Case("sm_15", "soft_mounts", "base", {"f": 15.0}, 7),
    Case("sm_40", "soft_mounts", "base", {"f": 40.0}, 8),
    Case("sd_x_40us", "sensor_delay", "x", {"tau": 40e-6}, 9),
    Case("sd_all_15us", "sensor_delay", "all", {"tau": 15e-6}, 10),
    Case("sd_z_80us", "sensor_delay", "z", {"tau": 80e-6}, 11),
    Case("al_y_80us", "actuator_lag", "y", {"T": 80e-6}, 12),
    Case("al_all_40us", "actuator_lag", "all", {"T": 40e-6}, 13),
    Case("al_z_150us", "actuator_lag", "z", {"T": 150e-6}, 14),
    Case("none_a", "none", None, {}, 15),
    Case("none_b", "none", None, {}, 16),
    Case("none_c", "none", None, {}, 17),
]
QUICK = [CASES[1], CASES[14]]


# -- truth machines ------------------------------------------------------------------------
def perturb(doc: UrdfDocument, rng: np.random.Generator) -> UrdfDocument:
    """Random 10–30 % errors (random sign) on every physical parameter (see module doc)."""
    out = doc.copy()

    def fac() -> float:
        return 1.0 + float(rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 0.3))

    links = sorted({p.owner for p in parameter_infos(out) if p.is_inertial})
    for link in links:
        m, c, inertia = link_inertial(out, link)
        set_link_inertial(
            out, link, m * fac(), c * np.array([fac(), fac(), fac()]), inertia * fac()
        )
    for p in parameter_infos(out):
        if p.kind in ("stiffness", "damping"):
            v = get_parameter(out, p.name)
            if v > 0:
                set_parameter(out, p.name, v * fac())
    return out


def _eff_inertia(doc: UrdfDocument, joint: str) -> float:
    from bondid.linear.affine import build_affine_model

    am = build_affine_model(doc)
    return float(1.0 / np.linalg.inv(am.mass_matrix())[am.dofs.index(joint), am.dofs.index(joint)])


def add_compliance(doc: UrdfDocument, location: str, f: float, pivot=None) -> UrdfDocument:
    from bondid.diagnose.effects.topology import axis_vector, interfaces

    pair, axis = location.split(":")
    parent, child = pair.split("->")
    itf = next(i for i in interfaces(doc) if i.parent == parent and i.child == child)
    kind, vec = axis_vector(axis)
    out = doc.copy()
    name = f"truth_{child}_{axis}"
    piv = (0.0, 0.0, 0.0) if pivot is None or kind == "prismatic" else pivot
    insert_parasitic_joint(out, name, after=itf.joints[-1], kind=kind, axis=vec, pivot=piv,
                           stiffness=1.0, damping=0.0)  # fmt: skip
    m = _eff_inertia(out, name)
    k = m * (2 * np.pi * f) ** 2
    out.set_stiffness(name, k)
    out.set_damping(name, 2 * 0.02 * np.sqrt(k * m))
    return out


def add_flexible_base(doc: UrdfDocument, f: float) -> UrdfDocument:
    """5-lump free-free chain, heavier at the bottom (masses M·(0.3, 0.25, 0.2, 0.15) below
    the root's 0.1), x/y shear 1 : 1.3, compression 3×, segments 4 cm high, ζ ≈ 2.5 %; the
    shear stiffness sets the first x mode near ``f``."""
    from bondid.diagnose.effects._chain import TRANSLATIONS, add_link, dof_chain

    out = doc.copy()
    root = out.root_link()
    M, c, inertia = link_inertial(out, root)
    split = np.array([0.3, 0.25, 0.2, 0.15, 0.1])
    set_link_inertial(out, root, M * split[-1], c, inertia)
    add_link(out, "tb_ground")
    nodes = [f"tb_{i}" for i in range(4)] + [root]
    for i in range(4):
        add_link(out, nodes[i], M * split[i])
    dof_chain(out, "tb_free", "tb_ground", nodes[0], TRANSLATIONS, xyz=(0, 0, -0.16),
              stiffness=[0.0] * 3)  # fmt: skip
    # first elastic mode of the chain with unit stiffness, then scale k to put it at f
    masses = M * split
    K1 = np.zeros((5, 5))
    for i in range(4):
        K1[i : i + 2, i : i + 2] += [[1.0, -1.0], [-1.0, 1.0]]
    w2 = np.sort(np.linalg.eigvals(np.linalg.solve(np.diag(masses), K1)).real)[1]
    k = (2 * np.pi * f) ** 2 / w2
    m_l = float(np.mean(masses))
    for i in range(4):
        ks = [k, 1.3 * k, 3.0 * k]
        ds = [2 * 0.025 * np.sqrt(kk * m_l) for kk in ks]
        dof_chain(out, f"tb_seg{i}", nodes[i], nodes[i + 1], TRANSLATIONS, xyz=(0, 0, 0.04),
                  stiffness=ks, damping=ds)  # fmt: skip
    return out


def add_soft_mounts(doc: UrdfDocument, f: float) -> UrdfDocument:
    """Six different mount stiffnesses around ``f`` (horizontal 0.6 f, vertical f, rocking
    from 4 feet at the base corners), 4 % damping."""
    from bondid.diagnose.effects._chain import ROTATIONS, TRANSLATIONS, add_link, dof_chain

    out = doc.copy()
    root = out.root_link()
    _, c, inertia = link_inertial(out, root)
    m = sum(float(lk.inertial.mass) for lk in out.robot.links if lk.inertial is not None)
    w = 2 * np.pi * f
    kv = m * w**2 / 4  # per foot
    kh = m * (0.6 * w) ** 2 / 4
    a, b = 0.22, 0.17  # foot positions ±a (x), ±b (y)
    ks = [4 * kh, 4 * kh * 1.2, 4 * kv, 4 * kv * b**2, 4 * kv * a**2, 4 * kh * (a**2 + b**2)]
    inert = [m, m, m, inertia[0, 0], inertia[1, 1], inertia[2, 2]]
    ds = [2 * 0.04 * np.sqrt(k * mi) for k, mi in zip(ks, inert, strict=True)]
    add_link(out, "tm_ground")
    dof_chain(out, "tm", "tm_ground", root, TRANSLATIONS + ROTATIONS, xyz=c, back=-c,
              stiffness=ks, damping=ds)  # fmt: skip
    return out


def modifier(case: Case, f: np.ndarray, outputs, inputs) -> np.ndarray:
    G = np.ones((len(outputs), len(inputs), f.size), complex)
    w = 2 * np.pi * f
    if case.effect == "sensor_delay":
        rows = [i for i, o in enumerate(outputs) if case.location in ("all", o)]
        G[rows] = np.exp(-1j * w * case.spec["tau"])
    elif case.effect == "actuator_lag":
        cols = [i for i, o in enumerate(inputs) if case.location in ("all", o)]
        G[:, cols] = 1.0 / (1.0 + 1j * w * case.spec["T"])
    return G


def truth_model(case: Case, nominal: UrdfDocument) -> UrdfDocument:
    rng = np.random.default_rng(1000 + case.seed)
    doc = perturb(nominal, rng)
    if case.effect == "joint_compliance":
        return add_compliance(doc, case.location or "", case.spec["f"], case.spec.get("pivot"))
    if case.effect == "flexible_base":
        return add_flexible_base(doc, case.spec["f"])
    if case.effect == "soft_mounts":
        return add_soft_mounts(doc, case.spec["f"])
    return doc


def measure(case: Case, truth: UrdfDocument, folder: Path, n_freq: int) -> tuple[list[Path], list]:
    f = log_grid(1.0, 4000.0, n_freq)
    paths, exact = [], []
    for k, op in enumerate(OPS):
        d = simulate(truth, op, f, noise=0.0)
        d.H = d.H * modifier(case, f, d.outputs, d.inputs)
        exact.append(d.H.copy())
        d.H, d.coherence = add_measurement_noise(
            d.H, f, rel=0.02, floor_db=-70.0, rng=case.seed * 10 + k, floor_ref="response"
        )
        p = folder / f"op{k}.csv"
        d.source = str(p)
        write_frf(d, p)
        paths.append(p)
    return paths, exact


# -- running and scoring -------------------------------------------------------------------
def run_case(case: Case, args: argparse.Namespace) -> dict[str, Any]:
    from bondid.data.io import read_frf
    from bondid.diagnose.gap import gap_report
    from bondid.diagnose.split import limit_bands, mask_incoherent

    nominal = UrdfDocument.load(MODEL)
    truth = truth_model(case, nominal)
    with tempfile.TemporaryDirectory(prefix="bondid_blind_") as tmp:
        folder = Path(tmp)
        paths, exact = measure(case, truth, folder, args.freq)
        out = folder / "out"
        cmd = [sys.executable, "-m", "bondid.diagnose", "--model", str(MODEL), "--data",
               *map(str, paths), "--out", str(out), "--quiet", "--no-plots",
               "--points", str(args.points), "--workers", str(args.workers)]  # fmt: skip
        if args.effects:
            cmd += ["--effects", args.effects]
        env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            return {
                "case": case.name,
                "error": proc.stderr.strip().splitlines()[-1:],
                "wall_s": wall,
            }
        diag = json.loads((out / "diagnosis.json").read_text())
        data = [mask_incoherent(limit_bands(read_frf(p), None)) for p in paths]
    # the truth model's own gap on the same points and channels
    db_truth = gap_report(data, exact, channels=diag["channels"]).db_rms
    before = diag["gap"]["db_rms"]
    truth_closed = 1.0 - db_truth / before if before else float("nan")
    v = diag["verdict"]
    class_ok = v["effect"] == case.effect
    loc_ok = None if case.effect == "none" else (class_ok and v["location"] == case.location)
    ratio = None
    if case.effect != "none" and truth_closed > 0.02:
        ratio = (v["gap_closed"] or 0.0) / truth_closed
    top = diag["candidates"][0] if diag["candidates"] else {}
    return {
        "case": case.name, "truth": case.effect, "truth_location": case.location,
        "verdict": v["effect"], "location": v["location"], "class_ok": class_ok,
        "location_ok": loc_ok, "gap_nominal": diag["stages"]["nominal"]["db_rms"],
        "gap_refit": before, "gap_effect": (diag["stages"].get("effect") or {}).get("db_rms"),
        "db_truth": db_truth, "gap_closed": v["gap_closed"], "truth_gap_closed": truth_closed,
        "ratio": ratio, "top": f"{top.get('effect')}@{top.get('location')}",
        "score_refit": diag["refit"]["score"], "score_top": top.get("score"),
        "wall_s": wall, "diagnosis_s": diag.get("wall_s"),
    }  # fmt: skip


def _f(v: Any, fmt: str = ".2f") -> str:
    return "–" if v is None else format(v, fmt)


def table(rows: list[dict[str, Any]]) -> str:
    head = (
        "| case | truth | truth location | verdict | location | class | loc | gap nominal"
        " | gap refit | gap effect | truth db | gap_closed | truth gap_closed | ratio | s |"
    )
    lines = [head, "|" + "---|" * 15]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['case']} | error: {r['error']} |" + " |" * 13)
            continue
        lines.append(
            f"| {r['case']} | {r['truth']} | {r['truth_location'] or '–'} | {r['verdict']} |"
            f" {r['location'] or '–'} | {'✓' if r['class_ok'] else '✗'} |"
            f" {'–' if r['location_ok'] is None else ('✓' if r['location_ok'] else '✗')} |"
            f" {_f(r['gap_nominal'])} | {_f(r['gap_refit'])} | {_f(r['gap_effect'])} |"
            f" {_f(r['db_truth'])} | {_f(r['gap_closed'])} | {_f(r['truth_gap_closed'])} |"
            f" {_f(r['ratio'])} | {_f(r['wall_s'], '.0f')} |"
        )
    return "\n".join(lines)


def summarise(rows: list[dict[str, Any]]) -> str:
    ok = [r for r in rows if "error" not in r]
    eff = [r for r in ok if r["truth"] != "none"]
    none = [r for r in ok if r["truth"] == "none"]
    cls = sum(r["class_ok"] for r in ok) / max(len(ok), 1)
    loc = sum(bool(r["location_ok"]) for r in eff) / max(len(eff), 1)
    claimed = sum(r["verdict"] != "none" for r in none)
    ratios = [r["ratio"] for r in eff if r["ratio"] is not None]
    med = float(np.median(ratios)) if ratios else float("nan")
    return (
        f"cases {len(rows)} ({len(rows) - len(ok)} failed); effect class right {cls:.0%}"
        f" (goal ≥ 90 %); location right {loc:.0%} of {len(eff)} effect cases (goal ≥ 80 %);"
        f" effect claimed on {claimed}/{len(none)} 'none' cases (goal 0); median gap_closed /"
        f" truth's {med:.2f} over {len(ratios)} cases (goal ≥ 0.8)"
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="2 cases, few frequencies (a test)")
    p.add_argument("--cases", default=None, help="comma-separated case names")
    p.add_argument("--freq", type=int, default=None, help="frequencies per data file")
    p.add_argument("--points", type=int, default=None, help="refit frequencies per data set")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--effects", default=None, help="restrict the candidates (quick test only)")
    p.add_argument("--out", type=Path, default=None, help="write the rows as JSON")
    args = p.parse_args(argv)
    cases = QUICK if args.quick else CASES
    if args.cases:
        wanted = set(args.cases.split(","))
        cases = [c for c in CASES if c.name in wanted]
    args.freq = args.freq or (300 if args.quick else 2000)
    args.points = args.points or (120 if args.quick else 500)
    rows = []
    for c in cases:
        r = run_case(c, args)
        rows.append(r)
        got = f"{r.get('verdict', 'error')} @ {r.get('location')}"
        print(f"{c.name}: {got} (truth {c.effect} @ {c.location}) {r.get('wall_s', 0):.0f} s",
              flush=True)  # fmt: skip
    print()
    print(table(rows))
    print()
    print(summarise(rows))
    if args.out:
        args.out.write_text(json.dumps(rows, indent=2, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
