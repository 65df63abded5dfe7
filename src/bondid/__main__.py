"""``python -m bondid`` and the ``bondid`` console script: the commands, one line each.

``bondid COMMAND ARGS...`` runs ``python -m bondid.COMMAND ARGS...`` (the same module, exit
codes and output); ``bondid`` alone, ``-h`` or ``--help`` lists the commands. An unknown
command exits 2 with one line naming the valid ones.
"""

from __future__ import annotations

import runpy
import sys
from collections.abc import Sequence

#: (command, what it does), in the order of a typical session
COMMANDS: tuple[tuple[str, str], ...] = (
    ("simulate", "synthetic measured FRFs of a model (CSV or UFF58), with realistic noise"),
    ("fit", "fit a URDF's parameters to measured FRFs: fit.json, fitted.urdf, Bode plots"),
    ("sensitivity", "which parameters the data determine, band by band; the recommended subset"),
    ("diagnose", "what the model is missing: the gap, candidate effects and a verdict"),
    ("modes", "the model's modes at an operating point: table, Meshcat scene / static HTML"),
    ("report", "one offline HTML page from a results folder"),
    ("fleet", "fit (and diagnose) every machine of a fleet on Dask (needs bondid[fleet])"),
)


def usage() -> str:
    """The command list printed by ``bondid`` alone."""
    width = max(len(c) for c, _ in COMMANDS)
    lines = [
        "usage: bondid COMMAND [ARGS...]   (the same as python -m bondid.COMMAND ARGS...)",
        "",
        "commands:",
        *(f"  {c:<{width}}  {text}" for c, text in COMMANDS),
        "",
        "bondid COMMAND --help shows a command's options.",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """List the commands, or run one as ``python -m bondid.COMMAND`` would."""
    if argv is None:  # a Ctrl-C while the command loads: no traceback (bondid.interrupt)
        from .interrupt import stop_quietly_until_run

        stop_quietly_until_run()
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help", "help"):
        print(usage())
        return 0
    if args[0] == "--version":
        from .cli import version_text

        print(version_text())
        return 0
    names = [c for c, _ in COMMANDS]
    if args[0] not in names:
        print(
            f"bondid: bad input: unknown command {args[0]!r}; valid: {', '.join(names)}",
            file=sys.stderr,
        )
        return 2
    sys.argv = [f"bondid {args[0]}", *args[1:]]
    module = "bondid.simulate" if args[0] == "simulate" else f"bondid.{args[0]}"
    runpy.run_module(module, run_name="__main__", alter_sys=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
