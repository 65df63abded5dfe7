"""Where the gap lies in the measured data (step 3 of :mod:`.pipeline`): :func:`where`."""

from __future__ import annotations

from typing import Any

from ..data.measurement import FrfData, channel_mask
from ..model.document import UrdfDocument
from .job import JobResult


def where(
    doc: UrdfDocument,
    full: list[FrfData],
    baseline: JobResult,
    channels: list[str],
    do_modes: bool,
) -> tuple[list[dict[str, Any]], list[list[dict[str, Any]]], list[dict[str, Any]], list, tuple]:
    """Modes (measured vs refitted model), anti-resonance shifts, automatic bands and the modes
    identified in each data set (a tuple of tuples of :class:`~bondid.modal.record.IdentifiedMode`;
    empty without ``do_modes``)."""
    from ..modal.antiresonance import antiresonance_shifts
    from ..modes.bands import Feature
    from .gap import gap_bands

    refit_doc = UrdfDocument.from_string(baseline.urdf, source="refit model")
    by_ds: list[list[dict[str, Any]]] = []
    anti: list[dict[str, Any]] = []
    feats: list[Feature] = []
    measured: list[tuple] = []
    for k, (d, H) in enumerate(zip(full, baseline.full_H, strict=True)):
        rows: list[dict[str, Any]] = []
        error: dict[str, Any] | None = None
        if do_modes:
            from ..modal.identify import identify_modes
            from ..modal.pairing import pair_modes

            try:
                meas = identify_modes(d)
            except Exception as exc:
                meas = []
                error = {"error": f"modal identification failed: {exc}"}
            measured.append(tuple(meas))
            mod = modes_on_channels(refit_doc, d, channels)
            rows = pair_modes(meas, mod, f_band=(float(d.freq_hz[0]), float(d.freq_hz[-1])))
            if error is not None:  # kept: the pairing must not hide why no mode was measured
                rows.insert(0, error)
            if k == 0:
                feats = [Feature(float(m.f_hz), float(m.zeta), "resonance") for m in meas]
        by_ds.append(rows)
        for row in antiresonance_shifts(d, H, channels=channels):
            anti.append({"dataset": k, **row})
    feats += [
        Feature(float(r["f_measured_hz"]), 0.0, "anti-resonance", r.get("channel"))
        for r in anti
        if r["dataset"] == 0 and r["f_measured_hz"]
    ]
    bands = gap_bands(full[0].freq_hz, feats)
    modes = by_ds[0] if by_ds else []
    return modes, by_ds, anti, bands, tuple(measured)


def modes_on_channels(doc: UrdfDocument, d: FrfData, channels: list[str]) -> list[Any]:
    """The modes of ``doc`` at ``d``'s operating point, their residues on ``d``'s outputs
    and inputs and ``channels`` (:func:`~bondid.modal.identify.model_modes`), as the measured
    modes of ``d`` are identified."""
    from ..linear.affine import build_affine_model
    from ..modal.identify import model_modes

    lm = build_affine_model(doc, d.operating_point, outputs=d.outputs)
    mask = channel_mask(lm.outputs, lm.inputs, channels)
    mod = model_modes(lm.linear_model(), freq_hz=d.freq_hz, channel_mask=mask)
    cols = [lm.inputs.index(i) for i in d.inputs]
    for m in mod:
        m.residues = m.residues[:, cols]
    return mod
