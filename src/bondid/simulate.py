"""Synthetic measurements: ``python -m bondid.simulate``.

FRFs of a "true" machine with realistic measurement error (relative complex noise, a sensor
noise floor so anti-resonances and weak cross-terms are noisy, and the coherence that goes
with it), reproducible by seed, written as a spec CSV or UFF58 file.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .data.io import CSV_SUFFIXES, UFF_SUFFIXES
from .data.measurement import FrfData
from .model.document import UrdfDocument

DEFAULT_FREQ = (1.0, 4000.0, 2000)


def log_grid(f_lo: float, f_hi: float, n: int) -> np.ndarray:
    """``n`` log-spaced frequencies from ``f_lo`` to ``f_hi`` (Hz), shape ``(n,)``."""
    return np.logspace(np.log10(f_lo), np.log10(f_hi), n)


def simulate(
    doc: UrdfDocument,
    operating_point: Mapping[str, float] | None = None,
    freq_hz: np.ndarray | None = None,
    *,
    noise: float = 0.0,
    floor_db: float | None = -70.0,
    seed: int | None = 0,
    quantity: str = "receptance",
    outputs: Sequence[str] | None = None,
    floor_ref: str = "response",
    floor_quantity: str | None = None,
    coherence: bool = True,
) -> FrfData:
    """Measured-like FRFs of ``doc`` at ``operating_point``.

    Args:
        doc: the "true" machine.
        operating_point: joint positions (m, rad) by name.
        freq_hz: ``(n_freq,)`` Hz; default 2000 log-spaced points, 1 Hz–4 kHz.
        noise: relative complex error (0 = exact data, no floor either).
        floor_db: sensor noise floor, dB below the sensor's response level (smoothed over
            ±½ octave), so weak cross-terms and anti-resonance dips are noisy.
        seed: random seed (same seed, same data).
        quantity: receptance, mobility or accelerance.
        outputs: sensed joints (default: the transmitted joints).
        floor_ref: what ``floor_db`` refers to (see
            :func:`bondid.data.noise.add_measurement_noise`): ``"response"`` (default),
            ``"median"`` (a flat floor below each channel's median ``|H|``), ``"channel"``,
            ``"output"``.
        floor_quantity: the quantity in which the floor is flat (None = ``quantity``;
            ``"accelerance"``: an accelerometer's flat floor).
        coherence: False leaves the coherence out (``coherence=None``, as many files come).

    Returns:
        :class:`FrfData` with ``H`` ``(n_out, n_in, n_freq)`` and coherence.
    """
    from .data.noise import add_measurement_noise
    from .linear.affine import build_affine_model

    f = log_grid(*DEFAULT_FREQ) if freq_hz is None else np.asarray(freq_hz, dtype=float)
    am = build_affine_model(
        doc, operating_point, outputs=None if outputs is None else tuple(outputs)
    )
    H = am.linear_model().frf(f, quantity)
    if noise > 0:
        H, coh = add_measurement_noise(
            H, f, rel=noise, rng=np.random.default_rng(seed), quantity=quantity,
            floor_db=floor_db, floor_ref=floor_ref, floor_quantity=floor_quantity,
        )  # fmt: skip
    else:
        coh = np.ones(H.shape)
    return FrfData(
        f, am.outputs, am.inputs, H, quantity, dict(am.operating_point), coh if coherence else None
    )


#: file types ``--out`` and ``--plot`` accept
DATA_SUFFIXES = (*CSV_SUFFIXES, *UFF_SUFFIXES)
PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def _check_options(args: argparse.Namespace) -> None:
    """Refuse impossible option values before any work."""
    import math

    from .exceptions import ConfigError

    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise ConfigError(f"--noise {args.noise}: give a finite relative error >= 0 (0 = exact)")
    if not args.floor_db < 0:
        raise ConfigError(
            f"--floor-db {args.floor_db}: the sensor floor is given in dB below the response;"
            " valid: a negative number such as -70 (-inf for no floor); a floor at or above"
            " the signal would leave nothing but noise"
        )
    if args.seed is not None and not 0 <= args.seed < 2**63:
        raise ConfigError(f"--seed {args.seed}: give an integer >= 0")
    if args.out.suffix.lower() not in DATA_SUFFIXES:
        raise ConfigError(f"--out {args.out}: valid file types: {', '.join(DATA_SUFFIXES)}")
    if args.plot is not None and args.plot.suffix.lower() not in PLOT_SUFFIXES:
        raise ConfigError(f"--plot {args.plot}: valid image types: {', '.join(PLOT_SUFFIXES)}")
    if args.plot is not None and args.plot.absolute() == args.out.absolute():
        raise ConfigError(f"--plot {args.plot}: is the --out file; give another name")


def main(argv: Sequence[str] | None = None) -> int:
    from . import cli

    args = _parser().parse_args(argv)
    return cli.run(lambda: _run(args), args)


def _parser() -> argparse.ArgumentParser:
    from . import cli

    p = cli.make_parser("simulate", "Synthesise measured FRFs of a (true) machine model.")
    p.add_argument("--model", required=True, type=Path, help="the true machine's URDF")
    p.add_argument("--out", required=True, type=Path, help="output file (.csv or .uff)")
    p.add_argument("--q", nargs="*", default=[], help="operating point, e.g. x=0.01 y=-0.02")
    p.add_argument("--freq", type=cli.parse_freq, default=DEFAULT_FREQ, help="F_LO:F_HI:N (Hz)")
    p.add_argument("--noise", type=float, default=0.02, help="relative error (0 = exact)")
    p.add_argument(
        "--floor-db", type=float, default=-70.0, help="sensor noise floor below the response (dB)"
    )
    p.add_argument(
        "--floor-ref", default="response", choices=["response", "median", "channel", "output"],
        help="what --floor-db is below: the sensor's response envelope (default), each "
        "channel's median |H| (flat floor), its peak, or its output row's peak",
    )  # fmt: skip
    p.add_argument(
        "--floor-quantity", default=None, choices=["receptance", "mobility", "accelerance"],
        help="quantity in which the floor is flat (default: --quantity; accelerance = an "
        "accelerometer's flat floor, ∝ 1/ω² in receptance)",
    )  # fmt: skip
    p.add_argument("--no-coherence", action="store_true", help="write no coherence columns")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--quantity", default="receptance", choices=["receptance", "mobility", "accelerance"]
    )
    p.add_argument("--plot", type=Path, default=None, help="also draw a Bode plot (PNG)")
    p.add_argument("--quiet", action="store_true")
    p.add_argument(
        "--outputs", nargs="+", default=None, metavar="NAME",
        help="sensed joints or points (default: the inputs: transmitted joints, then points)",
    )  # fmt: skip
    cli.add_points_arg(p)
    cli.add_package_path_arg(p)
    cli.add_floating_base_arg(p)
    return p


def _run(args: argparse.Namespace) -> int:
    """Simulate the model's measurement, write it (and ``--plot``) and print what was written."""
    from . import cli
    from .data.io import write_frf
    from .linear.operating_point import parse_operating_point
    from .results import open_results
    from .validation import check_inputs, load_model
    from .validation.datasets import model_channel_map

    _check_options(args)
    op = parse_operating_point(" ".join(args.q), "--q")
    res = open_results(args.out, "simulate", [args.model], file=True)
    plot_path = None
    if args.plot is not None:
        from .results import check_out

        check_out(args.plot, [args.model, args.out], file=True, option="--plot")
        plot_path = res.stage_extra(args.plot)
    doc, warnings = load_model(args.model, lambda d: cli.apply_model_options(d, args))
    warnings += check_inputs(doc, operating_points={"--q": op})
    data = simulate(
        doc, op, log_grid(*args.freq), noise=args.noise, floor_db=args.floor_db,
        seed=args.seed, quantity=args.quantity, floor_ref=args.floor_ref,
        floor_quantity=args.floor_quantity, coherence=not args.no_coherence,
        outputs=args.outputs,
    )  # fmt: skip
    data.source = str(args.out)
    is_uff = args.out.suffix.lower() in (".uff", ".unv", ".uff58")
    staged = res.path(args.out.name)
    write_frf(data, staged, channel_map=model_channel_map(doc) if is_uff else None)
    if plot_path is not None:
        _plot(doc, op, data, args, plot_path)
    res.commit(warnings=warnings)
    print(
        f"wrote {args.out}: {len(data.channels)} channels × {data.freq_hz.size} frequencies"
        f" ({data.freq_hz[0]:g}–{data.freq_hz[-1]:g} Hz), {args.quantity},"
        f" noise {args.noise:g}, seed {args.seed}, operating point {op or 'neutral'}"
    )
    if args.plot is not None:
        print(f"wrote {args.plot}")
    for line in cli.warn_lines(warnings):
        print(line)
    return 0


def _plot(
    doc: UrdfDocument,
    op: dict[str, float],
    data: FrfData,
    args: argparse.Namespace,
    path: Path,
) -> None:
    """The Bode plot of ``--plot``: the simulated measurement over the exact model and the
    noise level estimated from the measurement."""
    from .data.weights import noise_estimate
    from .plots import Curve, noise_curve, plot_bode

    exact = simulate(doc, op, data.freq_hz, noise=0.0, quantity=args.quantity, outputs=args.outputs)
    plot_bode(
        data.freq_hz,
        [
            Curve("simulated measurement", data.H, kind="measured"),
            Curve("model (exact)", exact.H, kind="model"),
            noise_curve(noise_estimate(data).sigma),
        ],
        outputs=data.outputs,
        inputs=data.inputs,
        path=path,
        title=f"{doc.name}: simulated FRF at {op or 'neutral'}",
        quantity=args.quantity,
    )


if __name__ == "__main__":
    from .interrupt import exit_process

    exit_process(main())
