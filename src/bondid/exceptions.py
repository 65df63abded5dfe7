"""The one exception tree of bondid.

Every error bondid raises on purpose derives from :class:`BondidError` and from the builtin
that matches its meaning, so ``except ValueError`` in user code keeps working. Messages name
the file, the item and what would be valid.
"""

from __future__ import annotations


class BondidError(Exception):
    """Root of every error raised by bondid."""


class ModelError(BondidError, ValueError):
    """A model file (URDF) or an in-memory model is invalid or inconsistent."""


class ParameterError(BondidError, KeyError):
    """A parameter name, group or pattern is unknown, or a value is out of its valid range."""

    def __str__(self) -> str:  # KeyError would quote the message; keep it readable
        return str(self.args[0]) if self.args else ""


class DataError(BondidError, ValueError):
    """A measured-data file or array is malformed (columns, NaN, frequencies, quantity, ...)."""


class ManifestError(DataError):
    """A results folder's manifest is malformed, lists a name its command never writes, or
    disagrees with the files beside it (the folder holds no complete run)."""


class ChannelError(DataError):
    """A channel is missing, unknown or inconsistent with the model's inputs and outputs."""


class OperatingPointError(BondidError, ValueError):
    """An operating point names a joint the model lacks, or gives an invalid value."""


class ConfigError(BondidError, ValueError):
    """A command-line option or study file is invalid."""


class ComputationError(BondidError, RuntimeError):
    """A numerical computation failed (singular matrix, non-finite result, ...)."""


class SolverError(ComputationError):
    """An optimiser (IPOPT through CasADi, or another) failed.

    ``status`` keeps the solver's own return status (e.g. IPOPT's ``return_status``).
    """

    def __init__(self, message: str, status: str | None = None) -> None:
        super().__init__(message)
        self.status = status


class DependencyError(BondidError, ImportError):
    """An optional dependency (meshcat, matplotlib, chromium, ...) is not available."""
