"""``python -m bondid.fleet``: fit (and diagnose) every machine of a fleet on Dask.

``--model NOMINAL.urdf --machines DIR --out OUT [--diagnose] [--scheduler ADDRESS]
[--workers N] [fit options]``. Each machine runs as ``python -m bondid.fit`` would (and
``bondid.diagnose`` with ``--diagnose``) into ``OUT/machines/<id>/``; the fleet's statistics
and outliers go to ``OUT/fleet.json``, ``OUT/fleet.csv`` and ``OUT/fleet_strip.png``.
Exit codes: 0 every machine succeeded, 1 any failed, 2 bad input.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .. import interrupt
from ..cli import (
    EXIT_FAILED,
    EXIT_OK,
    add_channels_arg,
    make_parser,
    parse_and_run,
    parse_band,
    split_names,
)
from ..exceptions import ComputationError, ConfigError
from ..fit.defaults import add_prior_arg, check_prior
from .machines import Machine

#: the lock file of earlier versions inside OUT (removed when found)
LOCK_NAME = ".fleet.lock"
_BOUND = re.compile(r"^[^=\s]+=([0-9.eE+-]+|[0-9.eE+-]+:[0-9.eE+-]+)$")
#: fit options passed through unchanged: (option, takes a list, help)
_FIT_VALUE_OPTIONS = (
    ("--cost", "residual kind of the fit (default complex_log)"),
    ("--norm", "norm of the fit (default l2)"),
)
_FIT_INT_OPTIONS = (
    ("--max-iter", "IPOPT iterations per fit (default 200)", 0),
    ("--presolve", "presolve iterations of a log-cost fit (default 60)", 0),
    ("--continuation", "band-continuation steps (default 0 = off)", 0),
    ("--multistart", "starts per machine (default 1)", 1),
    ("--seed", "Latin-hypercube seed of --multistart", 0),
)


def build_parser() -> argparse.ArgumentParser:
    p = make_parser("fleet", "Fit (and diagnose) every machine of a fleet on Dask.")
    p.add_argument("--model", required=True, type=Path, help="the nominal URDF of the design")
    p.add_argument(
        "--machines", required=True, type=Path,
        help="folder with one sub-folder per machine (its data files; optional model.urdf)",
    )  # fmt: skip
    p.add_argument("--out", required=True, type=Path, help="folder for the fleet's results")
    p.add_argument("--diagnose", action="store_true", help="also run bondid.diagnose per machine")
    p.add_argument(
        "--scheduler", metavar="ADDRESS",
        help="tcp://HOST:PORT of a running Dask scheduler (default: $DASK_SCHEDULER_ADDRESS,"
        " else a local cluster)",
    )  # fmt: skip
    p.add_argument("--workers", type=int, help="local worker processes (default 2)")
    p.add_argument(
        "--retries", type=int, default=2, help="Dask retries of a machine's task (default 2)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress display")
    g = p.add_argument_group("fit options (passed to bondid.fit for every machine)")
    g.add_argument("--free", nargs="+", action="extend", help="parameters to fit")
    g.add_argument("--fixed", nargs="+", action="extend", help="parameters to hold")
    add_prior_arg(g)
    g.add_argument("--bound", action="append", metavar="KEY=REL|KEY=LO:HI", help="bounds")
    g.add_argument("--band", action="append", metavar="F_LO:F_HI", help="band, Hz")
    g.add_argument("--weight", action="append", metavar="OUT.IN=W", help="channel weight")
    add_channels_arg(g, "channels to fit")
    for opt, text in _FIT_VALUE_OPTIONS:
        g.add_argument(opt, help=text)
    for opt, text, _ in _FIT_INT_OPTIONS:
        g.add_argument(opt, type=int, metavar="N", help=text)
    d = p.add_argument_group("diagnosis options (with --diagnose)")
    d.add_argument("--effects", help="candidate effects, comma-separated (default all)")
    d.add_argument("--points", type=int, help="frequencies per data set for the refits")
    d.add_argument(
        "--diagnose-free", nargs="+", action="extend", metavar="NAME",
        help="parameters of the diagnosis's refit (bondid.diagnose --free; default its own)",
    )  # fmt: skip
    return p


def fit_argv(args: argparse.Namespace) -> list[str]:
    """The bondid.fit options of every machine (without --model/--data/--out)."""
    argv: list[str] = []
    if args.free:
        argv += ["--free", *split_names(args.free)]
    if args.fixed:
        argv += ["--fixed", *split_names(args.fixed)]
    if args.prior is not None:
        argv += ["--prior", repr(args.prior)]
    for b in args.bound or ():
        argv += ["--bound", b]
    for b in args.band or ():
        argv += ["--band", b]
    for w in args.weight or ():
        argv += ["--weight", w]
    if args.channels:
        argv += ["--channels", args.channels]
    for opt, _ in _FIT_VALUE_OPTIONS:
        value = getattr(args, opt[2:].replace("-", "_"))
        if value is not None:
            argv += [opt, value]
    for opt, _, _ in _FIT_INT_OPTIONS:
        value = getattr(args, opt[2:].replace("-", "_"))
        if value is not None:
            argv += [opt, str(value)]
    return [*argv, "--workers", "1"]


def diagnose_argv(args: argparse.Namespace) -> list[str] | None:
    """The bondid.diagnose options of every machine, or None without --diagnose."""
    if not args.diagnose:
        return None
    argv: list[str] = []
    for b in args.band or ():
        argv += ["--band", b]
    if args.channels:
        argv += ["--channels", args.channels]
    if args.effects:
        argv += ["--effects", args.effects]
    if args.points is not None:
        argv += ["--points", str(args.points)]
    if args.diagnose_free:
        argv += ["--free", *split_names(args.diagnose_free)]
    return argv


def check_options(args: argparse.Namespace) -> None:
    """Option checks that need no machine (one ConfigError naming the item)."""
    from ..cluster.client import scheduler_address
    from ..model.document import UrdfDocument
    from ..model.parameters import select_parameters

    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers {args.workers}: give an integer >= 1")
    if args.workers is not None and scheduler_address(args.scheduler):
        raise ConfigError(
            f"--workers {args.workers}: not with a scheduler address (--scheduler or"
            " $DASK_SCHEDULER_ADDRESS): the cluster's own workers are used"
        )
    if args.retries < 0:
        raise ConfigError(f"--retries {args.retries}: give an integer >= 0")
    for opt, _, minimum in _FIT_INT_OPTIONS:
        value = getattr(args, opt[2:].replace("-", "_"))
        if value is not None and value < minimum:
            raise ConfigError(f"{opt} {value}: give an integer >= {minimum}")
    if args.prior is not None:
        check_prior(args.prior, "--prior")
    for text in args.band or ():
        try:
            parse_band(text)
        except argparse.ArgumentTypeError as exc:
            raise ConfigError(f"--band: {exc}") from None
    for text in args.bound or ():
        if not _BOUND.match(text):
            raise ConfigError(f"--bound {text!r}: not KEY=REL or KEY=LO:HI")
    for opt in ("points", "effects", "diagnose_free"):
        if getattr(args, opt) is not None and not args.diagnose:
            raise ConfigError(f"--{opt.replace('_', '-')}: only with --diagnose")
    doc = UrdfDocument.load(args.model)
    interrupt.check()  # a Ctrl-C that a library swallowed in its import (trimesh does)
    free = [n for n in split_names(args.free) if n != "auto"]
    if free:
        select_parameters(doc, free, split_names(args.fixed))
    if args.diagnose_free:
        select_parameters(doc, split_names(args.diagnose_free), [])
    if args.machines.resolve() in (args.out.resolve(), *args.out.resolve().parents):
        raise ConfigError(f"--out {args.out}: must not be inside --machines {args.machines}")
    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"--out {args.out}: exists and is not a folder")


def _settings_hash(fit: Sequence[str], diag: Sequence[str] | None) -> str:
    text = json.dumps({"fit": list(fit), "diagnose": None if diag is None else list(diag)})
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def plan(
    machines: Sequence[Machine], machines_dir: Path, fit: list[str], diag: list[str] | None
) -> tuple[list[Any], list[dict[str, Any]]]:
    """(jobs to run, status records of machines already done with the same inputs/settings)."""
    from .state import read_status, skip_reason
    from .worker import MachineJob

    settings = _settings_hash(fit, diag)
    jobs, done = [], []
    for m in machines:
        fp = f"{m.fingerprint()}-{settings}"
        status = read_status(machines_dir / m.id)
        if status is not None and skip_reason(status, fp):
            done.append(status)
            continue
        jobs.append(
            MachineJob(
                machine_id=m.id, model=str(m.model.resolve()),
                data=tuple(str(p.resolve()) for p in m.data),
                machines_dir=str(machines_dir.resolve()), fit_args=tuple(fit),
                diagnose_args=None if diag is None else tuple(diag), fingerprint=fp,
            )
        )  # fmt: skip
    return jobs, done


def _summary(statuses: Sequence[dict[str, Any]], stats: Any, n_skipped: int) -> str:
    from .aggregate import ok_count

    n_ok = ok_count(statuses)
    lines = [
        f"bondid.fleet: {len(statuses)} machines, {n_ok} ok, {len(statuses) - n_ok} failed"
        f" ({n_skipped} skipped: already done)"
    ]
    for st in statuses:
        if st.get("status") != "ok":
            lines.append(f"failed: {st.get('machine')}: {st.get('reason')}")
    for p in stats.parameters:
        spread = p["robust_rel_spread"]
        rel = "—" if spread is None else f"{100 * spread:.1f} %"
        lines.append(f"{p['name']}: median {p['median']:.6g}, robust spread {rel} (n={p['n']})")
    lines += [f"outlier: {o['machine']}: {o['reason']}" for o in stats.outliers]
    if not stats.outliers:
        lines.append("outliers: none")
    if stats.effects is not None:
        counts = ", ".join(f"{k} {v}" for k, v in stats.effects["counts"].items())
        lines.append(f"effects found: {counts or 'none'}")
    return "\n".join(lines)


def _body(args: argparse.Namespace) -> int:
    from ..cluster.client import open_client, scheduler_address
    from ..manifest import RESULT_PATTERNS
    from ..results import open_results
    from .aggregate import aggregate
    from .machines import discover
    from .outputs import FLEET_JSON, write_fleet_outputs
    from .runner import run_jobs
    from .state import clean_stale

    check_options(args)
    interrupt.check()  # a Ctrl-C that a library swallowed in its import (trimesh does)
    machines = discover(args.machines, args.model)
    fit, diag = fit_argv(args), diagnose_argv(args)
    machines_dir = args.out / "machines"
    # the lock of --out (one bondid run into it at a time) and the staging of the fleet's
    # own files; the machines' results go straight to OUT/machines/<id> (each complete or
    # absent), so that an interrupted fleet resumes where it stopped
    res = open_results(args.out, "fleet", [args.model], patterns=RESULT_PATTERNS["fleet"])
    (args.out / LOCK_NAME).unlink(missing_ok=True)  # left by earlier versions
    clean_stale(machines_dir)
    jobs, done = plan(machines, machines_dir, fit, diag)
    if done:
        print(f"skipping {len(done)} of {len(machines)} machines already done", flush=True)
    results = {str(st.get("machine")): st for st in done}
    if jobs:
        address = scheduler_address(args.scheduler)
        try:
            with open_client(address, args.workers or 2) as client:
                for st in run_jobs(client, jobs, retries=args.retries, quiet=args.quiet):
                    results[str(st.get("machine"))] = st
        except (OSError, TimeoutError) as exc:  # the scheduler went away mid-run
            raise ComputationError(
                f"Dask scheduler {address or '(local cluster)'}: lost ({exc}); the machines"
                " finished so far are saved: re-run the same command to resume"
            ) from None
        clean_stale(machines_dir)  # what killed workers left (every task has ended)
    statuses = [results[m.id] for m in machines if m.id in results]
    stats = aggregate(statuses, diagnose=args.diagnose)
    header = {
        "command": "bondid.fleet",
        "model": str(args.model),
        "machines_dir": str(args.machines),
        "fit_args": fit,
        "diagnose_args": diag,
        "skipped": sorted(str(st.get("machine")) for st in done),
    }
    write_fleet_outputs(res.tmp, statuses, stats, header)
    written = res.commit(main=FLEET_JSON)
    print(_summary(statuses, stats, len(done)))
    print(f"results: {args.out} ({', '.join(p.name for p in written)}, machines/)")
    return EXIT_OK if all(st.get("status") == "ok" for st in statuses) else EXIT_FAILED


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; returns the exit code (0 all ok, 1 a machine failed, 2 bad input)."""
    return parse_and_run(build_parser(), argv, _body)


if __name__ == "__main__":
    sys.exit(main())
