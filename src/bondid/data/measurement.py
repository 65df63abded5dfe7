"""The in-memory form of a measured (or simulated) FRF set: :class:`FrfData`."""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ChannelError, DataError
from .quantity import QUANTITIES, convert_quantity


def channel_mask(
    outputs: Sequence[str], inputs: Sequence[str], names: Collection[str]
) -> np.ndarray:
    """Boolean ``(n_out, n_in)``: which channels ``OUT.IN`` of these outputs and inputs are
    among ``names``."""
    mask = [[f"{o}.{i}" in names for i in inputs] for o in outputs]
    return np.array(mask, bool).reshape(len(outputs), len(inputs))


@dataclass
class FrfData:
    """FRFs of one machine at one operating point.

    Attributes:
        freq_hz: frequencies, shape ``(n_freq,)``, Hz, strictly increasing and positive.
        outputs: names of the response joints (rows), length ``n_out``.
        inputs: names of the excited joints (columns), length ``n_in``.
        H: complex FRF, shape ``(n_out, n_in, n_freq)``, in SI units of ``quantity``
            (receptance m/N or rad/(N·m), ...). Channels absent from the file are NaN.
        quantity: ``"receptance"``, ``"mobility"`` or ``"accelerance"``.
        operating_point: joint positions (m or rad) at which the data were taken.
        coherence: ``(n_out, n_in, n_freq)`` in 0..1, or None when the file has none;
            NaN where a channel carries no coherence.
        source: the file the data came from, for error messages (None if built in memory).
        notes: what the reader changed on the way in (e.g. a 0 Hz line dropped), reported as
            warnings by the commands.
    """

    freq_hz: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    H: np.ndarray
    quantity: str = "receptance"
    operating_point: dict[str, float] = field(default_factory=dict)
    coherence: np.ndarray | None = None
    source: str | None = None
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        where = self.source or "<in-memory FRF>"
        self.freq_hz = np.asarray(self.freq_hz, dtype=float)
        self.H = np.asarray(self.H, dtype=complex)
        self.outputs = tuple(self.outputs)
        self.inputs = tuple(self.inputs)
        if self.quantity not in QUANTITIES:
            raise DataError(
                f"{where}: unknown quantity {self.quantity!r}; valid: {', '.join(QUANTITIES)}"
            )
        shape = (len(self.outputs), len(self.inputs), self.freq_hz.size)
        if self.freq_hz.ndim != 1 or self.H.shape != shape:
            raise DataError(
                f"{where}: H has shape {self.H.shape}, expected (n_out, n_in, n_freq) = {shape}"
            )
        if self.coherence is not None:
            self.coherence = np.asarray(self.coherence, dtype=float)
            if self.coherence.shape != shape:
                raise DataError(
                    f"{where}: coherence has shape {self.coherence.shape}, expected {shape}"
                )

    # -- channels -----------------------------------------------------------------------
    @property
    def present(self) -> np.ndarray:
        """Boolean ``(n_out, n_in)``: True where the channel has data at every frequency."""
        return np.all(np.isfinite(self.H), axis=2)

    @property
    def channels(self) -> list[str]:
        """Names ``OUT.IN`` of the present channels, row-major (outputs first)."""
        pres = self.present
        return [
            f"{o}.{i}"
            for a, o in enumerate(self.outputs)
            for b, i in enumerate(self.inputs)
            if pres[a, b]
        ]

    def channel(self, name: str) -> np.ndarray:
        """The FRF of channel ``OUT.IN``, shape ``(n_freq,)``."""
        out, _, inp = name.rpartition(".")
        if out not in self.outputs or inp not in self.inputs:
            raise ChannelError(
                f"{self.source or '<in-memory FRF>'}: no channel {name!r}; "
                f"valid: {', '.join(self.channels)}"
            )
        return self.H[self.outputs.index(out), self.inputs.index(inp)]

    def to_quantity(self, quantity: str) -> FrfData:
        """A copy converted to ``quantity`` (receptance, mobility or accelerance)."""
        H = convert_quantity(self.H, self.freq_hz, self.quantity, quantity)
        return FrfData(
            self.freq_hz.copy(),
            self.outputs,
            self.inputs,
            H,
            quantity,
            dict(self.operating_point),
            None if self.coherence is None else self.coherence.copy(),
            self.source,
        )
