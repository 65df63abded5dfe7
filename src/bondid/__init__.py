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
