"""bondid: fit a machine's multibody model to its measured frequency response.

The package is layered; each layer only imports the ones before it::

    model (URDF, parameters) → linear (Pinocchio linearisation) → frf (engine)
    → data (measured files) → cost → fit → sensitivity / diagnose → plots / report

Nothing heavy is imported here: ``import bondid`` is cheap and has no side effects.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("bondid")
except PackageNotFoundError:  # a source tree on sys.path without an install
    __version__ = "0.2.0"

__all__ = ["__version__"]


def _started_as_command() -> bool:
    """Whether this process is ``python [options] -m bondid[.<command>]``."""
    import sys

    argv = list(getattr(sys, "orig_argv", []))[1:]
    for k, arg in enumerate(argv[:-1]):
        if arg == "-m":
            return argv[k + 1] == "bondid" or argv[k + 1].startswith("bondid.")
        if not arg.startswith("-"):
            return False
    return False


if _started_as_command():  # a Ctrl-C while the command loads: no traceback (bondid.interrupt)
    from .interrupt import stop_quietly_until_run

    stop_quietly_until_run()
