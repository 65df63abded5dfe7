"""A model's state space and FRD for python-control, at one operating point, in one call.

>>> from bondid.export import to_control
>>> sys, frd = to_control(doc, {"x": 0.0}, freq_hz)          # doc: a (fitted) UrdfDocument

``sys`` is a ``control.StateSpace`` with state ``x = [δq, δq̇]`` (``2·nv``), inputs the
model's inputs (transmitted joints and measurement points, in N or N·m, times their transducer
gains) and outputs its outputs (positions in m or rad, times their gains; ``quantity``
mobility / accelerance gives velocities / accelerations); ``frd`` is a ``control.FRD`` of the
same model at ``freq_hz`` (computed by bondid's FRF engine, not sampled from ``sys``).
python-control is an optional dependency, imported here only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .data.quantity import QUANTITIES
from .exceptions import DependencyError
from .linear.affine import build_affine_model
from .model.document import UrdfDocument


def _control() -> Any:
    try:
        import control
    except ImportError as exc:  # pragma: no cover - control is a test dependency
        raise DependencyError(
            "python-control is needed for bondid.export; install it with `pip install control`"
        ) from exc
    return control


def state_space(
    doc: UrdfDocument,
    operating_point: Mapping[str, float] | None = None,
    *,
    outputs: Sequence[str] | None = None,
    quantity: str = "receptance",
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(A (2nv, 2nv), B (2nv, n_in), C (n_out, 2nv), D (n_out, n_in))`` of ``doc``.

    Args:
        doc: the model (its points and gains included).
        operating_point: joint positions (m, rad) by name; others neutral.
        outputs: output names (joints or points); default the model's inputs.
        quantity: receptance (positions), mobility (velocities) or accelerance
            (accelerations; then ``D ≠ 0``).

    A structural loss factor (``<rayleigh_damping eta>``) has no state-space form; it enters
    as the viscous damping that dissipates as much at each mode's own frequency
    (:meth:`bondid.linear.linear_model.LinearModel.viscous`), so the state space matches the
    model's FRF at the resonances and departs from it between them.
    """
    from .exceptions import DataError

    if quantity not in QUANTITIES:
        raise DataError(f"unknown quantity {quantity!r}; valid: {', '.join(QUANTITIES)}")
    lm = build_affine_model(
        doc, operating_point, outputs=None if outputs is None else tuple(outputs)
    ).linear_model()
    A, B, C, D = lm.state_space()
    n = lm.nv
    if quantity == "mobility":
        C = np.hstack([np.zeros_like(lm.C), lm.C])
    elif quantity == "accelerance":
        C = lm.C @ A[n:, :]
        D = lm.C @ B[n:, :]
    return A, B, C, D


def to_control(
    doc: UrdfDocument,
    operating_point: Mapping[str, float] | None,
    freq_hz: np.ndarray,
    *,
    outputs: Sequence[str] | None = None,
    quantity: str = "receptance",
) -> tuple[Any, Any]:
    """``(control.StateSpace, control.FRD)`` of ``doc`` at ``operating_point``.

    Args:
        doc: the model (e.g. ``UrdfDocument.load("results/fitted.urdf")``).
        operating_point: joint positions (m, rad) by name; None = neutral.
        freq_hz: ``(n_freq,)`` frequencies in Hz (> 0) of the FRD.
        outputs: output names (joints or points); default the model's inputs.
        quantity: receptance, mobility or accelerance (of both results).

    Returns:
        The state space (named inputs/outputs, see the module docstring; a loss factor as in
        :func:`state_space`) and the FRD ``(n_out, n_in, n_freq)`` at ``ω = 2π·freq_hz``
        rad/s (exact, a loss factor included).
    """
    control = _control()
    f = np.asarray(freq_hz, dtype=float)
    outs = None if outputs is None else tuple(outputs)
    am = build_affine_model(doc, operating_point, outputs=outs)
    A, B, C, D = state_space(doc, operating_point, outputs=am.outputs, quantity=quantity)
    sys = control.ss(A, B, C, D, inputs=list(am.inputs), outputs=list(am.outputs))
    H = am.linear_model().frf(f, quantity)
    frd = control.frd(H, 2.0 * np.pi * f, inputs=list(am.inputs), outputs=list(am.outputs))
    return sys, frd
