"""One case end to end: truth machine, data files, ``python -m bondid.diagnose`` and
``python -m bondid.fit`` (its defaults) on the same files (subprocesses: they see the nominal URDF
and the data files only), and the case's scores."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bondid.model import UrdfDocument

from .cases import Case
from .designs import ROOT, design
from .regimes import measure
from .truth import signal_factor, truth_model
from .visibility import frequencies, visible_case


@dataclass(frozen=True)
class Settings:
    """How a case is run: frequencies per file, diagnose ``--points`` and ``--workers``,
    optional ``--effects`` subset, whether to time the fit too."""

    freq: int = 2000
    points: int = 500
    workers: int = 2
    effects: str | None = None
    fit: bool = True
    #: a folder to copy each case's data files and outputs into (``<keep>/<design>/<effect>/
    #: <regime>/``), for a look at a case afterwards; None: nothing kept
    keep: Path | None = None
    #: strengthen a single effect the oracle parameter refit does not see (:mod:`.visibility`)
    visibility: bool = True


#: the subprocesses running now (:func:`terminate_children` stops them with the benchmark)
_LIVE: set[subprocess.Popen] = set()
_LIVE_LOCK = threading.Lock()
#: set by :func:`terminate_children`: no subprocess starts after it
STOPPING = threading.Event()


def _run(cmd: list[str]) -> tuple[subprocess.CompletedProcess, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(v, "1")
    t0 = time.perf_counter()
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          env=env) as p:  # fmt: skip
        with _LIVE_LOCK:
            _LIVE.add(p)
            if STOPPING.is_set():  # started while the benchmark was being stopped
                p.terminate()
        try:
            out, err = p.communicate()
        finally:
            with _LIVE_LOCK:
                _LIVE.discard(p)
    return subprocess.CompletedProcess(cmd, p.returncode, out, err), time.perf_counter() - t0


def terminate_children(grace_s: float = 30.0) -> None:
    """Stop the running diagnoses and fits (SIGTERM, which they handle; SIGKILL after
    ``grace_s``), so that a stopped benchmark leaves no orphan working on."""
    with _LIVE_LOCK:
        STOPPING.set()
        live = list(_LIVE)
    for p in live:
        p.terminate()
    for p in live:
        try:
            p.wait(grace_s)
        except subprocess.TimeoutExpired:
            p.kill()


def stop_on_sigterm() -> None:
    """Install the benchmarks' SIGTERM handler: stop the running subprocesses
    (:func:`terminate_children`) and exit at once; the rows written so far stay on disk, and
    a case cut short is not a result (its runner sees :data:`STOPPING` set)."""

    def stop(signum: int, _frame: Any) -> None:
        terminate_children()
        os._exit(128 + signum)

    signal.signal(signal.SIGTERM, stop)


def _error(proc: subprocess.CompletedProcess) -> str:
    lines = (proc.stderr or proc.stdout or "").strip().splitlines()
    return lines[-1] if lines else f"exit {proc.returncode}"


def diagnose_cmd(model: Path, paths: list[Path], out: Path, s: Settings) -> list[str]:
    cmd = [sys.executable, "-m", "bondid.diagnose", "--model", str(model), "--data",
           *map(str, paths), "--out", str(out), "--quiet", "--no-plots",
           "--points", str(s.points), "--workers", str(s.workers)]  # fmt: skip
    return cmd + (["--effects", s.effects] if s.effects else [])


def fit_cmd(model: Path, paths: list[Path], out: Path) -> list[str]:
    return [sys.executable, "-m", "bondid.fit", "--model", str(model), "--data",
            *map(str, paths), "--out", str(out), "--quiet"]  # fmt: skip


def run_case(case: Case, s: Settings) -> dict[str, Any]:
    """Build (strengthened until its effect shows, :mod:`.visibility`), measure, diagnose (and
    fit); the row of the case (``error`` when a step failed)."""
    vis: dict[str, Any] = {}
    if s.visibility:
        case, vis = visible_case(case, s.freq, s.points)
    dz = design(case.design)
    nominal = UrdfDocument.load(dz.path)
    truth = truth_model(nominal, case.effects, case.seed)
    f = frequencies(s.freq)

    def factor(ff, outs, ins):
        return signal_factor(case.effects, ff, outs, ins)

    row: dict[str, Any] = {"case": case.name, "design": case.design, "regime": case.regime,
                           "truth": [[e.effect, e.location] for e in case.effects],
                           "spec": [dict(e.spec) for e in case.effects], **vis}  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="bondid_blind_") as tmp:
        folder = Path(tmp)
        paths, exact = measure(
            truth, dz.operating_points, f, case.regime, factor, folder, case.seed, case.effects
        )
        proc, row["diagnosis_s"] = _run(diagnose_cmd(dz.path, paths, folder / "diag", s))
        if proc.returncode != 0:
            return {**row, "error": f"diagnose: {_error(proc)}"}
        diag = json.loads((folder / "diag" / "diagnosis.json").read_text())
        if s.fit:
            fproc, row["fit_s"] = _run(fit_cmd(dz.path, paths, folder / "fit"))
            row["fit_status"] = _fit_status(fproc, folder / "fit" / "fit.json")
        row["db_truth"] = truth_db(paths, exact, diag)
        if s.keep is not None:
            dest = s.keep / case.name
            shutil.rmtree(dest, ignore_errors=True)
            shutil.copytree(folder, dest)
    return {**row, **score(case, diag, row["db_truth"]),
            **open_score(case, diag, s.effects, truth)}  # fmt: skip


def case_truth(case: Case) -> UrdfDocument:
    """The truth machine of ``case`` (the design's model perturbed and given its effects,
    as its data were made from)."""
    from .designs import design
    from .truth import truth_model

    return truth_model(UrdfDocument.load(design(case.design).path), case.effects, case.seed)


def open_score(
    case: Case, diag: dict[str, Any], effects: str | None, truth: UrdfDocument | None = None
) -> dict[str, Any]:
    """The open-world figures of a case (:mod:`.open_scoring`): the answer, whether a case
    whose cause no candidate can name stayed honest, whether the remainder's description
    points where its cause lives (``truth``: the case's truth machine, built when needed)."""
    from .open_scoring import honest, remainder_ok
    from .truth import expected_remainder

    offered = set(effects.split(",")) if effects else None
    left_out = any(
        e.library is None or (offered is not None and e.library not in offered)
        for e in case.effects
    )
    if truth is None and any(e.effect == "flexible_link" for e in case.effects):
        truth = case_truth(case)
    expected = [r for e in case.effects for r in expected_remainder(e, truth)]
    return {
        "outcome": (diag.get("verdict") or {}).get("outcome"),
        "left_out": left_out,
        "honest": honest(diag, left_out),
        "remainder_ok": remainder_ok(diag, expected) if left_out else None,
    }


def _fit_status(proc: subprocess.CompletedProcess, path: Path) -> str:
    """IPOPT's status from ``fit.json`` (written also when the fit ends unconverged, exit 1),
    else ``failed: <last line>``."""
    if not path.exists():
        return f"failed: {_error(proc)}"
    return str(json.loads(path.read_text()).get("status"))


def truth_db(paths: list[Path], exact: list[np.ndarray], diag: dict[str, Any]) -> float | None:
    """The truth model's own gap on the diagnosis's channels and points (the package's
    ``gap_report`` on the files, converted and incoherent points masked as the diagnosis does;
    with the weighting ``diagnosis.json`` names under ``weighting`` or ``scoring.weighting``,
    if any)."""
    from bondid.data.io import read_frf
    from bondid.data.quantity import convert_quantity
    from bondid.diagnose.gap import gap_report
    from bondid.diagnose.split import limit_bands, mask_incoherent

    info = diag.get("weighting")
    rule = info.get("weighting") if isinstance(info, dict) else info
    try:
        raw = [read_frf(p) for p in paths]
        data = [limit_bands(r, None) for r in raw]  # may convert the quantity
        exact = [convert_quantity(H, r.freq_hz, r.quantity, d.quantity)
                 for H, r, d in zip(exact, raw, data, strict=True)]  # fmt: skip
        if isinstance(rule, str):  # weighted as diagnosis.json's gap.db_rms is
            from bondid.data.weights import with_weights_as_coherence

            weighted = [with_weights_as_coherence(d, rule) for d in data]
            return float(gap_report(weighted, exact, channels=diag.get("channels"),
                                    weighting="coherence").db_rms)  # fmt: skip
        masked = [mask_incoherent(d) for d in data]
        return float(gap_report(masked, exact, channels=diag.get("channels")).db_rms)
    except Exception as exc:  # the package's API moved: say so, do not guess
        print(f"truth gap not computed: {exc}", file=sys.stderr)
        return None


def claimed_effects(diag: dict[str, Any]) -> list[dict[str, Any]]:
    """The accepted effects: ``effects`` (issue 14's ordered list) when present, else the
    verdict alone; ``none`` entries dropped."""
    items = diag.get("effects")
    if not isinstance(items, list):
        items = [diag.get("verdict") or {}]
    return [e for e in items if isinstance(e, dict) and e.get("effect") not in (None, "none")]


def screening(case: Case, diag: dict[str, Any]) -> bool | None:
    """Did every true effect's candidate survive the screening (``refitted``, else
    ``screened``)? None when the candidates carry neither field."""
    cands = [c for c in diag.get("candidates") or [] if isinstance(c, dict)]
    key = next((k for k in ("refitted", "screened") if any(k in c for c in cands)), None)
    if key is None or not case.effects:
        return None
    return all(
        any(c.get("effect") == e.effect and c.get("location") == e.location and bool(c.get(key))
            for c in cands)
        for e in case.effects
    )  # fmt: skip


def named_or_tied(case: Case, claimed: list[dict[str, Any]]) -> bool | None:
    """Is every true effect (class and location) claimed, or listed by a claimed step as
    one the data cannot tell from its effect (``indistinguishable_from``)? None on a "none"
    case."""
    if not case.effects:
        return None
    names = {(c.get("effect"), c.get("location")) for c in claimed}
    for c in claimed:
        ties = [t for t in c.get("indistinguishable_from") or [] if isinstance(t, dict)]
        names |= {(t.get("effect"), t.get("location")) for t in ties}
    return all((e.effect, e.location) in names for e in case.effects)


def _gap_closed_final(diag: dict[str, Any], claimed: list[dict[str, Any]]) -> float:
    """gap_closed of the whole accepted list (its last step's, when it says), else the
    verdict's."""
    if claimed and isinstance(claimed[-1].get("gap_closed"), int | float):
        return float(claimed[-1]["gap_closed"])
    return float((diag.get("verdict") or {}).get("gap_closed") or 0.0)


#: a model is "at the noise level" when its weighted gap is within this factor of the truth's
AT_NOISE = 1.10


def _at_noise(db: float | None, db_truth: float | None) -> bool | None:
    """Is a weighted gap [dB] within :data:`AT_NOISE` of the truth's (None if either is
    missing)?"""
    return None if db is None or db_truth is None else float(db) <= AT_NOISE * db_truth


def shows(gap_refit: float | None, db_truth: float | None, n_truth: int) -> bool | None:
    """Does the case's withheld effect show above the noise: is the parameter refit's weighted
    gap [dB] above :data:`AT_NOISE` × the truth model's? (None for "none" cases or a missing
    figure.) Where it does not, the verdict rule's first condition (the base above the noise
    level) refuses every candidate, the true one included: no diagnosis can name it."""
    at = _at_noise(gap_refit, db_truth)
    return None if not n_truth or at is None else not at


def final_db(diag: dict[str, Any], claimed: list[dict[str, Any]]) -> float | None:
    """The weighted gap of the diagnosis's final model: after its last accepted effect, else
    the parameter refit's."""
    if claimed and isinstance(claimed[-1].get("db_rms_after"), int | float):
        return float(claimed[-1]["db_rms_after"])
    before = (diag.get("gap") or {}).get("db_rms")
    return float(before) if isinstance(before, int | float) else None


def score(case: Case, diag: dict[str, Any], db_truth: float | None) -> dict[str, Any]:
    """Class, location, extra claims, gap figures, the ratio to the truth's gap_closed and
    whether the final model is at the noise level (within :data:`AT_NOISE` of the truth's
    own weighted gap)."""
    v = diag.get("verdict") or {}
    claimed = claimed_effects(diag)
    got = [(c.get("effect"), c.get("location")) for c in claimed]
    truth = [(e.effect, e.location) for e in case.effects]
    before = (diag.get("gap") or {}).get("db_rms")
    truth_closed = None
    if db_truth is not None and before:
        truth_closed = 1.0 - db_truth / before
    if len(truth) <= 1:
        class_ok = (v.get("effect") or "none") == (truth[0][0] if truth else "none")
        loc_ok = None if not truth else class_ok and v.get("location") == truth[0][1]
        closed = float(v.get("gap_closed") or 0.0)
    else:
        class_ok = all(t[0] in [g[0] for g in got] for t in truth)
        loc_ok = all(t in got for t in truth)
        closed = _gap_closed_final(diag, claimed)
    ratio = None
    if truth and truth_closed is not None and truth_closed > 0.02:
        ratio = closed / truth_closed
    stages = diag.get("stages") or {}
    final = final_db(diag, claimed)
    at_noise = _at_noise(final, db_truth)
    # the final model refitted on all data
    ff = (diag.get("final_fit") or {}).get("db_rms")
    ff_at = _at_noise(ff, db_truth)
    return {
        "claimed": [list(g) for g in got], "verdict": v.get("effect"),
        "location": v.get("location"), "class_ok": class_ok, "location_ok": loc_ok,
        "extra_claims": max(0, len(got) - len(truth)),
        "gap_nominal": (stages.get("nominal") or {}).get("db_rms"), "gap_refit": before,
        "gap_closed": closed, "truth_gap_closed": truth_closed, "ratio": ratio,
        "screen_ok": screening(case, diag), "final_db": final, "at_noise": at_noise,
        "final_fit_db": ff, "final_fit_at_noise": ff_at,
        "named_or_tied": named_or_tied(case, claimed),
        "shows": shows(before, db_truth, len(truth)),
    }  # fmt: skip
