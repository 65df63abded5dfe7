"""Accuracy of the modal identification against sdypy-EMA's LSCF and LSFD, on data with known modes.

    python tools/modal_id_accuracy.py [--cases NAME,...] [--data DIR] [--freq 2000]
        [--motor motor_bench_B.npz] [--methods NAME,...]

Data sets:

- the bundled bonder files (``data/bonder_q0.csv``, ``data/bonder_q1.csv``); truth: the modes
  of ``data/truth/bonder_truth.urdf`` at each file's operating point;
- benchmark cases (``tools/benchmark``: a design, a data regime, withheld effects); truth: the
  case's truth machine (:func:`benchmark.truth.truth_model` with the case's seed and effects)
  at each file's operating point. A case's files are read from ``--data DIR/<case with / as
  __>/`` when there (its ``case.json`` may hold the effects' specs as the blind benchmark
  strengthened them), else simulated into a temporary folder as :mod:`benchmark.regimes`
  does (also with ``--noise-seed N`` > 0: the same truths, other noise, for the spread of
  the figures);
- a real two-inertia motor bench (``--motor``, 1 input, 2 outputs, 13–249 Hz on 4 Hz lines):
  one resonance; reference: a least-squares fit of the two-inertia rig's own transfer functions
  (motor and load angle per current, a delay) to the data.

Every method reads the same input: the data set with its information weights in place of
the coherence, as the diagnosis hands it to :func:`bondid.modal.identify.identify_modes`.
Methods:

- ``ours``: :func:`~bondid.modal.identify.identify_modes` as it is;
- ``ours-norefine``: the same without the nonlinear refinement of the poles;
- ``sdypy-lscf``: the same pipeline with sdypy-EMA's LSCF as the pole estimator in each band
  (the band's FRF, channels balanced, interpolated onto the uniform grid from 0 Hz that
  sdypy's FFT-based estimator needs; ``lower`` = the band's first frequency);
- ``sdypy-lsfd``: ours without refinement, with sdypy-EMA's LSFD for the residues;
- ``sdypy``: sdypy-EMA's LSCF and sdypy-EMA's LSFD (residues, on the input grid), no
  refinement: the maintained library in every numerical step it offers. Pole selection
  (the stabilisation rule), the band plan, the per-row / per-channel passes and the
  prominence filter stay ours: sdypy-EMA picks poles only by hand (a chart) or next to given
  frequencies;
- ``union``: ``ours`` with the stable poles of both estimators in each band (sdypy's where
  ours has none within 2·``tol_f``).

Metrics per data set (truth modes: prominence ≥ 0.1 inside the data's band): ``found`` =
truth modes paired one-to-one with an identified mode within 3 % in frequency; ``dζ`` =
median relative damping error of those pairs [%]; ``MAC`` = mean MAC of their residues
against the truth's (:func:`bondid.modal.pairing.mac_matrix`); ``spur`` = identified modes
farther than 3 % from every mode of the truth (of any prominence); ``cpu`` = process CPU time
of the identification [s]. Then the same summed per group (design and regime).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from unittest import mock

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

import numpy as np  # noqa: E402

from bondid.data import FrfData  # noqa: E402
from bondid.data.io import read_frf  # noqa: E402
from bondid.data.weights import with_weights_as_coherence  # noqa: E402
from bondid.modal import lscf as _lscf  # noqa: E402
from bondid.modal.identify import IdentifiedMode, identify_modes, model_modes  # noqa: E402

#: the benchmark cases measured by default: the four designs, every regime
CASES = (
    "bonder/jct/coh", "bonder/sd/coh", "bonder/sm/acc", "bonder/none_a/coh", "bonder/jcr+al/coh",
    "bonder_b/jcr/harsh", "bonder_b/fb/nocoh", "bonder_b/sm/coh",
    "gantry/fb/coh", "gantry/al/nocoh", "gantry/jct/harsh", "gantry/none_b/acc",
    "polar/sm/mob", "polar/jct2/acc", "polar/al/harsh",
)  # fmt: skip
F_TOL = 0.03
MIN_PROMINENCE = 0.1


@dataclass
class DataSet:
    """One identification problem: the input, the truth's modes (residues in the data's
    channel order, NaN where unknown), a label and the group it is summed in."""

    label: str
    group: str
    data: FrfData
    truth: list[IdentifiedMode]


# -- sdypy-EMA as the estimator ------------------------------------------------------------
def uniform_from_zero(f: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(g, Hg, f_lo)``: ``H`` ``(..., n_f)`` on ``f`` [Hz] interpolated (log magnitude and
    unwrapped phase, linear in f) onto the uniform grid ``g`` from 0 Hz to one step past
    ``f[-1]`` with the finest step of ``f``; 0 below ``f[0]``. sdypy's LSCF needs this grid
    (its sums are FFTs), and cuts one line below its ``upper``."""
    step = float(np.min(np.diff(f)))
    n = int(np.ceil(f[-1] / step))
    g = np.linspace(0.0, f[-1], n + 1)
    g = np.append(g, g[-1] + g[1])
    inside = (g >= f[0]) & (g <= f[-1])
    flat = H.reshape(-1, f.size)
    out = np.zeros((flat.shape[0], g.size), complex)
    for k, h in enumerate(flat):
        mag, ph = np.log(np.abs(h)), np.unwrap(np.angle(h))
        out[k, inside] = np.exp(np.interp(g[inside], f, mag) + 1j * np.interp(g[inside], f, ph))
    return g, out.reshape(*H.shape[:-1], g.size), float(f[0])


def sdypy_plscf(
    freq_hz: np.ndarray, H: np.ndarray, weight: np.ndarray, n_max: int
) -> list[_lscf.PoleSet]:
    """:func:`bondid.modal.lscf.plscf`'s job by sdypy-EMA's LSCF: the poles of each of
    its ``n_max`` orders (denominator degrees 2, 4, … 2·n_max; fewer where the band has too
    few lines). ``weight`` is not used: sdypy's estimator weighs every line alike."""
    from sdypy import EMA

    g, Hg, lo = uniform_from_zero(np.asarray(freq_hz, float), H)
    # its highest order is bounded by the number of lines (sums over ±2·order lags)
    n = min(int(n_max), (g.size - 3) // 2)
    if n < 1:
        return []
    model = EMA.Model(frf=Hg.reshape(-1, g.size), freq=g, lower=lo, upper=g[-1],
                      pol_order_high=n, frf_form="receptance")  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.get_poles(show_progress=False)
    out = []
    for k, p in enumerate(model.all_poles):
        p = np.asarray(p, complex)
        out.append(_lscf.PoleSet(k + 1, np.where(p.imag < 0, p.conj(), p)))
    return out


def sdypy_lsfd(
    freq_hz: np.ndarray,
    H: np.ndarray,
    lam: np.ndarray,
    weight: np.ndarray | None = None,
    *,
    lower: bool = True,
    upper: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`bondid.modal.lscf.lsfd`'s job by sdypy-EMA's LSFD (one unweighted least
    squares over the channels with no gap; lower residual ``1/s²``, upper a constant);
    ``weight`` is not used."""
    from sdypy.EMA.EMA import LSFD

    n_out, n_in, n_f = H.shape
    flat = H.reshape(n_out * n_in, n_f)
    ok = np.all(np.isfinite(flat), axis=1)
    R = np.full((len(lam), n_out * n_in), np.nan, complex)
    model = np.full(flat.shape, np.nan, complex)
    if np.any(ok) and len(lam):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            A, rec, _, _ = LSFD(np.asarray(lam, complex), flat[ok], np.asarray(freq_hz, float),
                                lower, upper > 0, 0, n_f, "receptance")  # fmt: skip
        R[:, ok] = A.T
        model[ok] = rec
    return R.reshape(len(lam), n_out, n_in), model.reshape(H.shape)


@contextmanager
def patched(lscf: bool, lsfd: bool) -> Iterator[None]:
    """Our pipeline with sdypy-EMA's estimators in place of ours."""
    with (
        mock.patch.object(_lscf, "plscf", sdypy_plscf if lscf else _lscf.plscf),
        mock.patch.object(_lscf, "lsfd", sdypy_lsfd if lsfd else _lscf.lsfd),
    ):
        yield


def _ours(d: FrfData) -> list[IdentifiedMode]:
    return identify_modes(d)


def _ours_norefine(d: FrfData) -> list[IdentifiedMode]:
    return identify_modes(d, refine=False)


def _sdypy_lscf(d: FrfData) -> list[IdentifiedMode]:
    with patched(lscf=True, lsfd=False):
        return identify_modes(d)


def _sdypy_lsfd(d: FrfData) -> list[IdentifiedMode]:
    with patched(lscf=False, lsfd=True):
        return identify_modes(d, refine=False)


def _sdypy(d: FrfData) -> list[IdentifiedMode]:
    with patched(lscf=True, lsfd=True):
        return identify_modes(d, refine=False)


def _union(d: FrfData) -> list[IdentifiedMode]:
    from bondid.modal import identify as modal_id

    own = modal_id._band_poles

    def both(*args: Any, **kw: Any) -> list[tuple[complex, int]]:
        ours = own(*args, **kw)
        with patched(lscf=True, lsfd=False):
            theirs = own(*args, **kw)
        return modal_id._with_new(ours, theirs, kw["tol_f"])

    with mock.patch.object(modal_id, "_band_poles", both):
        return identify_modes(d)


METHODS: dict[str, Callable[[FrfData], list[IdentifiedMode]]] = {
    "ours": _ours,
    "ours-norefine": _ours_norefine,
    "sdypy-lscf": _sdypy_lscf,
    "sdypy-lsfd": _sdypy_lsfd,
    "sdypy": _sdypy,
    "union": _union,
}


# -- the data sets --------------------------------------------------------------------------
def truth_modes(doc, d: FrfData) -> list[IdentifiedMode]:  # type: ignore[no-untyped-def]
    """The vibration modes of ``doc`` at ``d``'s operating point (prominence against the
    model's receptance on ``d``'s frequencies, residues in ``d``'s channel order)."""
    from bondid.linear import build_affine_model

    am = build_affine_model(doc, d.operating_point, outputs=d.outputs)
    cols = [am.inputs.index(i) for i in d.inputs]
    modes = model_modes(am.linear_model(), freq_hz=d.freq_hz)
    for m in modes:
        m.residues = m.residues[:, cols]
    return modes


def bundled(noise_seed: int) -> list[DataSet]:
    """The bundled files; with ``noise_seed`` > 0 their truth measured afresh with the same
    noise (2 %, floor −70 dB below the response) and other seeds."""
    from bondid.model import UrdfDocument
    from bondid.simulate import simulate

    doc = UrdfDocument.load(ROOT / "data" / "truth" / "bonder_truth.urdf")
    out = []
    for k in (0, 1):
        d = read_frf(ROOT / "data" / f"bonder_q{k}.csv")
        if noise_seed:
            d = simulate(doc, d.operating_point, d.freq_hz, noise=0.02, floor_db=-70.0,
                         seed=10_000 * noise_seed + k)  # fmt: skip
        out.append(DataSet(f"bundled q{k}", "bundled", with_weights_as_coherence(d),
                           truth_modes(doc, d)))  # fmt: skip
    return out


def case_sets(name: str, data_dir: Path | None, freq: int, noise_seed: int = 0) -> list[DataSet]:
    """The data sets of benchmark case ``name`` (module docstring); with ``noise_seed`` > 0
    its truth measured afresh in its regime with other noise seeds."""
    from benchmark.cases import all_cases
    from benchmark.designs import design
    from benchmark.regimes import measure
    from benchmark.truth import TruthEffect, signal_factor, truth_model
    from benchmark.visibility import frequencies

    from bondid.model import UrdfDocument

    case = {c.name: c for c in all_cases()}[name]
    folder = None if data_dir is None else data_dir / name.replace("/", "__")
    effects = list(case.effects)
    if folder is not None and (folder / "case.json").exists():
        meta = json.loads((folder / "case.json").read_text())
        given = meta.get("truth") or []
        if all(isinstance(t, list) and len(t) == 3 for t in given):  # the specs as measured
            effects = [TruthEffect(e, loc, dict(spec)) for e, loc, spec in given]
        paths = [folder / p for p in meta["files"]]
    truth = truth_model(UrdfDocument.load(design(case.design).path), effects, case.seed)
    if noise_seed or folder is None or not (folder / "case.json").exists():
        tmp = Path(tempfile.mkdtemp(prefix="modal_id_accuracy_"))
        dz = design(case.design)

        def factor(ff, outs, ins):  # type: ignore[no-untyped-def]
            return signal_factor(effects, ff, outs, ins)

        paths, _ = measure(truth, dz.operating_points, frequencies(freq), case.regime, factor,
                           tmp, case.seed + 1000 * noise_seed)  # fmt: skip
    out = []
    for k, p in enumerate(paths):
        d = read_frf(p)
        out.append(DataSet(f"{name} op{k}", f"regime {case.regime}",
                           with_weights_as_coherence(d), truth_modes(truth, d)))  # fmt: skip
    return out


def two_inertia_reference(f: np.ndarray, H: np.ndarray) -> tuple[float, float]:
    """``(f_hz, zeta)`` of the resonance of a two-inertia rig fitted to its FRF ``H``
    ``(2, 1, n_f)`` (motor angle, load angle per current): ``H_m = g (s² + 2ζₐωₐ s + ωₐ²) / D``,
    ``H_l = g (2ζₐωₐ s + ωₐ²) / D``, ``D = s (s + p₀) (s² + 2ζᵣωᵣ s + ωᵣ²) e^{sτ}`` (a
    coupling between two inertias, viscous friction ``p₀``, a delay ``τ``), by least squares
    on the complex logarithm."""
    from scipy.optimize import least_squares

    s = 2j * np.pi * f
    fa, fr = f[np.argmin(np.abs(H[0, 0]))], f[np.argmax(np.abs(H[0, 0]) * f**2)]

    def residual(x: np.ndarray) -> np.ndarray:
        g, wa, za, wr, zr, p0 = np.exp(x[:6])
        den = s * (s + p0) * (s**2 + 2 * zr * wr * s + wr**2) * np.exp(s * x[6])
        model = np.stack([g * (s**2 + 2 * za * wa * s + wa**2), g * (2 * za * wa * s + wa**2)])
        e = np.log(model / den / H[:, 0])
        e = e.real + 1j * np.angle(np.exp(1j * e.imag))
        return np.concatenate([e.real.ravel(), e.imag.ravel()])

    g0 = np.median(np.abs(H[0, 0] * s**2))
    x0 = np.array([np.log(g0), np.log(2 * np.pi * fa), np.log(0.02), np.log(2 * np.pi * fr),
                   np.log(0.02), np.log(2 * np.pi), 0.0])  # fmt: skip
    x = least_squares(residual, x0, method="lm").x
    return float(np.exp(x[3]) / (2 * np.pi)), float(np.exp(x[4]))


def motor_bench(path: Path) -> list[DataSet]:
    z = np.load(path, allow_pickle=True)
    f, H, coh = z["f"], z["H"], z["coh"]
    outs = tuple(str(o) for o in z["outputs"])
    d = FrfData(f, outs, tuple(str(i) for i in z["inputs"]), H, "receptance", {}, coh, str(path))
    fr, zr = two_inertia_reference(f, H)
    ref = IdentifiedMode(fr, zr, np.full(H.shape[:2], np.nan + 0j), prominence=1.0)
    return [DataSet("motor bench", "motor bench", with_weights_as_coherence(d), [ref])]


# -- the metric -----------------------------------------------------------------------------
@dataclass
class Score:
    """One method on one data set (module docstring); ``mac``: residue MAC of each found
    pair where the truth's residues are known (channels balanced over all those pairs)."""

    n_truth: int
    found: int
    dzeta: list[float]
    mac: list[float]
    spurious: int
    cpu_s: float
    error: str | None = None


def matched(ident: list[IdentifiedMode], truth: list[IdentifiedMode]) -> list[tuple[int, int]]:
    """One-to-one pairs ``(identified, truth)`` within :data:`F_TOL` in frequency, the
    assignment of least total relative frequency error."""
    from scipy.optimize import linear_sum_assignment

    if not ident or not truth:
        return []
    df = np.array([[abs(m.f_hz - t.f_hz) / t.f_hz for t in truth] for m in ident])
    rows, cols = linear_sum_assignment(np.where(df <= F_TOL, df, 1e6))
    return [(int(i), int(j)) for i, j in zip(rows, cols, strict=True) if df[i, j] <= F_TOL]


def score(ds: DataSet, method: Callable[[FrfData], list[IdentifiedMode]]) -> Score:
    from bondid.modal.pairing import mac_matrix

    f_lo, f_hi = float(ds.data.freq_hz[0]), float(ds.data.freq_hz[-1])
    shown = [t for t in ds.truth if t.prominence >= MIN_PROMINENCE and f_lo <= t.f_hz <= f_hi]
    t0 = time.process_time()
    try:
        ident = method(ds.data)
    except Exception as exc:  # a failed method scores nothing found
        return Score(len(shown), 0, [], [], 0, time.process_time() - t0, str(exc))
    cpu = time.process_time() - t0
    pairs = matched(ident, shown)
    dz = [abs(ident[i].zeta - shown[j].zeta) / shown[j].zeta for i, j in pairs]
    known = [(i, j) for i, j in pairs if np.all(np.isfinite(shown[j].residues))]
    # balanced over all found pairs at once, as the pairing balances over all modes
    mm = mac_matrix([ident[i] for i, _ in known], [shown[j] for _, j in known])
    mac = [float(x) for x in np.diag(mm)]
    spur = sum(all(abs(m.f_hz - t.f_hz) > F_TOL * t.f_hz for t in ds.truth) for m in ident)
    return Score(len(shown), len(pairs), dz, mac, spur, cpu)


def _median(x: list[float], scale: float = 1.0) -> str:
    return f"{scale * float(np.median(x)):.1f}" if x else "–"


def _cell(sc: list[Score]) -> str:
    dz = [x for s in sc for x in s.dzeta]
    mac = [x for s in sc for x in s.mac]
    err = " (failed)" if any(s.error for s in sc) else ""
    mean_mac = f"{np.mean(mac):.3f}" if mac else "–"
    return (
        f"{sum(s.found for s in sc)}/{sum(s.n_truth for s in sc)}, {_median(dz, 100)}, "
        f"{mean_mac}, {sum(s.spurious for s in sc)}, {sum(s.cpu_s for s in sc):.1f}{err}"
    )


def tables(sets: list[DataSet], names: list[str]) -> tuple[str, str]:
    """(per data set, per group) tables; each row is printed as it is measured."""
    head = "| {} | " + " | ".join(f"{n}: found, dζ %, MAC, spur, cpu s" for n in names) + " |"
    rule = "|---|" + "---|" * len(names)
    lines = [head.format("data set"), rule]
    print(lines[0] + "\n" + rule, flush=True)
    by_group: dict[str, dict[str, list[Score]]] = {}
    for ds in sets:
        scores = {n: score(ds, METHODS[n]) for n in names}
        for n, sc in scores.items():
            by_group.setdefault(ds.group, {m: [] for m in names})[n].append(sc)
        lines.append(f"| {ds.label} | " + " | ".join(_cell([scores[n]]) for n in names) + " |")
        print(lines[-1], flush=True)
    groups = [head.format("group"), rule]
    for g, sc in by_group.items():
        groups.append(f"| {g} | " + " | ".join(_cell(sc[n]) for n in names) + " |")
    every = {n: [s for sc in by_group.values() for s in sc[n]] for n in names}
    groups.append("| **all** | " + " | ".join(_cell(every[n]) for n in names) + " |")
    return "\n".join(lines), "\n".join(groups)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES), help="benchmark cases, comma-separated")
    ap.add_argument("--data", type=Path, default=None, help="folder of benchmark case folders")
    ap.add_argument("--freq", type=int, default=2000, help="lines per simulated case file")
    ap.add_argument("--motor", type=Path, default=None, help="the motor bench's .npz")
    ap.add_argument("--methods", default=",".join(METHODS), help="methods, comma-separated")
    ap.add_argument("--no-bundled", action="store_true", help="leave the bundled files out")
    ap.add_argument("--noise-seed", type=int, default=0,
                    help="0: the files as they are; N > 0: the truths measured afresh with "
                         "other noise (the spread of the figures)")  # fmt: skip
    a = ap.parse_args(argv)
    names = [n for n in a.methods.split(",") if n]
    bad = [n for n in names if n not in METHODS]
    if bad:
        ap.error(f"--methods: unknown {', '.join(bad)}; valid: {', '.join(METHODS)}")
    sets = [] if a.no_bundled else bundled(a.noise_seed)
    for name in [c for c in a.cases.split(",") if c]:
        sets += case_sets(name, a.data, a.freq, a.noise_seed)
    if a.motor is not None:
        sets += motor_bench(a.motor)
    print(
        f"truth modes: prominence ≥ {MIN_PROMINENCE} in band; found (one-to-one) / spurious "
        f"within {100 * F_TOL:.0f} % in frequency; dζ = median |ζ − ζ_truth| / ζ_truth; "
        "MAC = mean residue MAC of the found pairs against the truth's\n"
    )
    _, groups = tables(sets, names)
    print("\n" + groups)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
