"""Replay the diagnosis's verdict rule on kept ``diagnosis.json`` outputs.

A change of the verdict rule (``bondid.diagnose.scoring``) that only re-reads figures every
refit already reports (held-out scores, the noise reference, parameters and their std) can be
judged on the outputs of earlier benchmark runs without running them again. For every search
step of every ``diagnosis.json`` under the given folders this script takes the step's refitted
candidates and applies the current rule twice: on the best-scoring refit (the rule before
stop 25) and on the best refit whose effect strength the data determine
(``scoring.determined``, stop 25). It prints each step where the two differ, with the case's
withheld effects when the folder layout is ``<design>/<tag>/<regime>/diag/diagnosis.json`` of
``tools/blind_benchmark.py --keep``. Steps after the first change are not replayed (their base
would differ).

Usage: ``python tools/replay_verdict.py KEEP_DIR [KEEP_DIR ...]``
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

import numpy as np  # noqa: E402
from benchmark.cases import all_cases  # noqa: E402

from bondid.diagnose import scoring  # noqa: E402
from bondid.diagnose.effects import get_effects  # noqa: E402
from bondid.diagnose.effects.base import Candidate, NewParameter  # noqa: E402


def _strength_names() -> dict[str, set[str]]:
    """Per effect, the names of its strength parameters (from the registered plugins)."""
    from bondid.model.document import UrdfDocument

    doc = UrdfDocument.load(ROOT / "urdf" / "bonder.urdf")
    out: dict[str, set[str]] = {}
    for effect in get_effects():
        for cand in effect.candidates(doc):
            out.setdefault(effect.name, set()).update(p.name for p in cand.parameters if p.strength)
    return out


def strength_z(entry: dict[str, Any], strength: dict[str, set[str]]) -> float:
    """``scoring.strength_z`` of a ``candidates`` entry of ``diagnosis.json``."""
    from types import SimpleNamespace

    names = strength.get(entry["effect"], set())
    vals, std = entry.get("parameters") or {}, entry.get("parameters_std") or {}
    params = tuple(NewParameter(n, 1.0, 1.0, 1.0, "", strength=n in names) for n in vals)
    result = SimpleNamespace(
        candidate=Candidate(entry["effect"], entry["location"], params), n_own=len(params),
        values=np.array(list(vals.values()), float),
        std=np.array([np.nan if std.get(n) is None else std[n] for n in vals], float),
    )  # fmt: skip
    return scoring.strength_z(result)


def replay(path: Path, strength: dict[str, set[str]]) -> list[str]:
    """The lines of one output: per step, the claim before and after the strength rule."""
    d = json.loads(path.read_text())
    lines = []
    for st in d["scoring"]["steps"]:
        k = st["step"]
        cs = [c for c in d["candidates"] if c["step"] == k and c.get("refitted")
              and c.get("score") is not None and math.isfinite(c["score"])]  # fmt: skip
        if not cs or st.get("rule") != "noise":
            break
        cs.sort(key=lambda c: c["score"])
        ref = scoring.NoiseReference(st["heldout_noise_level_db"], st["heldout_n_eff"])
        s0 = ref.level_db * st["base_over_noise"]

        def claim(c: dict[str, Any] | None, s0: float = s0, ref: Any = ref) -> str:
            if c is None or not scoring.tests(c["score"], s0, c["n_parameters"], ref)["accepted"]:
                return "-"
            return f"{c['effect']}@{c['location']}"

        before = claim(cs[0])
        after = claim(next((c for c in cs if strength_z(c, strength) >= scoring.Z), None))
        z = strength_z(cs[0], strength)
        mark = "  <== changed" if before != after else ""
        lines.append(f"  step {k}: before {before} (z {z:.3g}), after {after}{mark}")
        if before != after or after == "-":
            break
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", type=Path, help="folders holding diagnosis.json files")
    args = ap.parse_args(argv)
    truth = {c.name: [f"{e.effect}@{e.location}" for e in c.effects] for c in all_cases()}
    strength = _strength_names()
    n_out = n_steps = n_changed = 0
    for top in args.dirs:
        for path in sorted(top.rglob("diagnosis.json")):
            parts = path.parts
            key = "/".join(parts[-5:-2]) if len(parts) >= 5 else ""
            lines = replay(path, strength)
            n_out += 1
            n_steps += len(lines)
            n_changed += sum("changed" in x for x in lines)
            print(f"{path}  withheld: {truth.get(key, '?')}")
            print("\n".join(lines))
    print(f"{n_out} outputs, {n_steps} steps replayed, {n_changed} changed")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
