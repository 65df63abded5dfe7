"""The model's FRF laid out like a measured data set (its channels, frequencies, quantity)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..data.measurement import FrfData
    from ..linear.affine import AffineModel
    from ..model.document import UrdfDocument


def model_frf(doc: UrdfDocument, ds: FrfData, affine: AffineModel | None = None) -> np.ndarray:
    """The model's FRF at ``ds``'s operating point and frequencies, in ``ds``'s layout.

    Args:
        doc: the model.
        ds: the data set (operating point, frequencies ``(n_freq,)`` Hz, channels, quantity).
        affine: the model's linearisation at ``ds.operating_point`` with ``ds.outputs``, when
            one is at hand (default: linearised here).

    Returns:
        complex ``(n_out, n_in, n_freq)`` in ``ds.quantity``, rows ``ds.outputs``, columns
        ``ds.inputs``.
    """
    if affine is None:
        from ..linear.affine import build_affine_model

        affine = build_affine_model(doc, ds.operating_point, outputs=ds.outputs)
    lm = affine.linear_model()
    H = lm.frf(ds.freq_hz, ds.quantity)
    return H[:, [lm.inputs.index(i) for i in ds.inputs], :]
