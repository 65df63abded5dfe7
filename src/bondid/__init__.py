"""bondid: fit a machine's multibody model to its measured frequency response.

The package is layered; each layer only imports the ones before it::

    model (URDF, parameters) → linear (Pinocchio linearisation) → frf (engine)
    → data (measured files) → cost → fit → sensitivity / diagnose → plots / report

Nothing heavy is imported here: ``import bondid`` is cheap and has no side effects.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
